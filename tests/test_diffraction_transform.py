"""Taylor/FFT diffraction transform (Single 2013, Stam 1999) against closed forms and brute-force sums."""

import math

import numpy as np
import pytest
from scipy.special import jv

from prefilter.diffraction.transform import (
    direct_transform,
    grating_peaks,
    order_powers,
    periodic_factor,
    periodic_factor_2d,
    periodic_sum,
    relative_power,
    taylor_direct,
    taylor_order,
    taylor_terms,
)


def _bound(x, n):
    return x ** (n + 1) / math.factorial(n + 1)


@pytest.mark.parametrize("x", [0.3, 1.0, 1.5 * math.pi, 12.0])
@pytest.mark.parametrize("eps", [1e-4, 1e-7, 1e-11])
def test_taylor_order_is_the_smallest_n_meeting_the_bound(x, eps):
    # x = (2π / λ_min) · w_max · h: choose h to give x with λ_min = 0.4, w_max = 2
    n = taylor_order(x * 0.4 / (2 * math.pi * 2), lambda_min_um=0.4, w_max=2.0, epsilon=eps)
    assert _bound(x, n) <= eps * (1 + 1e-12)
    assert n == 0 or _bound(x, n - 1) > eps


def test_taylor_order_for_singles_example():
    # Single §2.4.5: h = 0.15 µm, λ_min = 0.4 µm, |w| ≤ 2 -> x = 1.5π; without the e^x factor
    x = 1.5 * math.pi
    n = taylor_order(0.15, 0.4, 2.0, 1e-7)
    assert 1e-9 < _bound(x, n) <= 1e-7 < _bound(x, n - 1)
    assert 20 <= n <= 25  # the draft's e^x factor asks for 25; the corrected bound needs fewer
    # the draft's table (with its e^x factor) is reproduced: N = 20, 25, 30
    for order, printed in ((20, 2.9950e-4), (25, 8.8150e-8), (30, 1.0050e-11)):
        assert math.exp(x) * _bound(x, order) == pytest.approx(printed, rel=2e-3)
    assert taylor_order(0.0) == 0


def _sinusoid(a=0.1, d=1.6, periods=4, pixel=0.02, rows=4):
    n = round(d / pixel)
    x = np.arange(n * periods) * (d / n)
    return np.tile(a * np.sin(2 * np.pi * x / d), (rows, 1)), (d / n, d / n)


def test_sinusoidal_grating_orders_are_bessel_functions():
    h, pixel = _sinusoid()
    width = h.shape[1]
    for kw in (-2 * 2 * np.pi / 0.5, -7.0, 3.0):
        m = np.arange(-8, 9)
        got = order_powers(h, pixel, kw, m, period=1.6)
        np.testing.assert_allclose(got, jv(m, kw * 0.1) ** 2, atol=1e-4)
        everything = order_powers(h, pixel, kw, np.arange(width))  # every bin of the patch (period = width)
        assert abs(everything.sum() - 1.0) < 1e-6


def test_blazed_grating_efficiencies_are_sinc_squared_and_asymmetric():
    height, d, lam, pixel = 0.246, 2.5, 0.5, 0.02
    n = round(d / pixel)
    x = (np.arange(n * 4) + 0.5) * (d / n)
    h = np.tile(height * np.mod(x / d, 1.0), (2, 1))
    kw = -2 * 2 * np.pi / lam  # normal incidence: w = −2
    m = np.arange(-3, 4)
    got = order_powers(h, (d / n, d / n), kw, -m, period=d)  # grating order m is Fourier index −m
    np.testing.assert_allclose(got, np.sinc(2 * height / lam - m) ** 2, atol=2e-3)
    assert got[m == 1][0] > 0.99 and got[m == -1][0] < 0.05


@pytest.mark.parametrize("d", [0.9, 1.6, 2.5])
@pytest.mark.parametrize("theta_i", [0.0, 75.0])
def test_peaks_follow_the_grating_equation(d, theta_i):
    lam, a = 0.55, 0.15
    h, pixel = _sinusoid(a=a, d=d, periods=8, pixel=0.05, rows=2)
    terms = taylor_terms(h, pixel)
    angles, powers = grating_peaks(terms, lam, theta_i)
    s_i = math.sin(math.radians(theta_i))
    k = 2 * math.pi / lam
    # predicted orders: visible, away from grazing, with enough power J_m(k w a)²
    found_orders = []
    for angle in angles:
        m = round((math.sin(math.radians(angle)) + s_i) * d / lam)
        expected = math.degrees(math.asin(m * lam / d - s_i))
        assert abs(angle - expected) < 0.5, (angle, expected, m)
        found_orders.append(m)
    assert len(set(found_orders)) == len(found_orders)
    for m in range(-10, 11):
        s = m * lam / d - s_i
        if abs(s) > math.sin(math.radians(87)):
            continue
        theta_r = math.asin(s)
        kw = -k * (math.cos(math.radians(theta_i)) + math.cos(theta_r))
        if jv(m, kw * a) ** 2 > 1e-4:
            assert m in found_orders, (m, found_orders)
    # the period from the peak positions (least squares of sin θ_r + sin θ_i = m λ / d through 0)
    ms = np.array(found_orders, float)
    s = np.sin(np.radians(angles)) + s_i
    assert np.count_nonzero(ms) >= 1
    d_fit = lam * np.sum(ms * ms) / np.sum(ms * s)
    assert abs(d_fit / d - 1) < 5e-3
    # the specular order is the mirror direction θ_r = −θ_i
    assert np.min(np.abs(angles + theta_i)) < 0.05 or theta_i > 85


def test_taylor_sum_equals_the_direct_transform():
    rng = np.random.default_rng(7)
    size, pixel = 64, 0.05
    noise = rng.standard_normal((size, size))
    f = np.fft.fftfreq(size, pixel)
    smooth = np.fft.ifft2(
        np.fft.fft2(noise) * np.exp(-(f[:, None] ** 2 + f[None, :] ** 2) / (2 * 1.5**2))
    ).real
    h = 0.2 * smooth / np.abs(smooth - smooth.mean()).max()
    terms = taylor_terms(h, pixel, epsilon=1e-9)
    assert terms.order == taylor_order(np.abs(h - h.mean()).max(), epsilon=1e-9)
    kmax = 2 * 2 * np.pi / 0.38
    alpha, beta = rng.uniform(-kmax, kmax, (2, 50))
    kw = rng.uniform(-kmax, kmax, 50)
    kw[:3] = [-kmax, kmax, 0.0]
    reference = direct_transform(h, pixel, alpha, beta, kw)
    assert np.abs(reference).max() > 1e-3
    assert np.abs(taylor_direct(terms, alpha, beta, kw) - reference).max() <= 1e-6
    got = taylor_direct(h, alpha[:5], beta[:5], kw[:5], pixel=(pixel, pixel), epsilon=1e-9)
    assert np.abs(got - reference[:5]).max() <= 1e-6
    # at the DFT bins the windowed sum tends to the same series as σ -> ∞ (only the bin itself survives)
    wide = taylor_terms(h, pixel, sigma=1e4, epsilon=1e-9)
    a0, b0 = wide.freq_x[3], wide.freq_y[-5]
    np.testing.assert_allclose(
        wide.evaluate(a0, b0, 20.0), direct_transform(h, pixel, a0, b0, 20.0), atol=1e-9
    )


def test_flat_surface_is_one_at_the_origin_and_a_gaussian_elsewhere():
    sigma = 65 / 4
    terms = taylor_terms(np.zeros((16, 16)), 0.05, sigma=sigma)
    assert relative_power(terms, 0.0, 0.0, -20.0) == 1.0
    assert relative_power(terms, 0.0, 0.0, 0.0) == 1.0
    rng = np.random.default_rng(1)
    r = rng.uniform(0, 5 / sigma, 200)
    t = rng.uniform(0, 2 * np.pi, 200)
    a, b = r * np.cos(t), r * np.sin(t)
    got = relative_power(terms, a, b, rng.uniform(-30, 0, 200))
    np.testing.assert_allclose(got, np.exp(-(sigma**2) * (a * a + b * b)), rtol=1e-12, atol=1e-300)
    # along one axis, with the other at 0: exp(−σ² α²)
    alpha = np.linspace(-4 / sigma, 4 / sigma, 81)
    np.testing.assert_allclose(
        relative_power(terms, alpha, 0.0, -5.0), np.exp(-(sigma**2) * alpha**2), rtol=1e-12
    )


def test_windowed_transform_of_a_grating_peaks_at_the_orders_with_bessel_power():
    h, pixel = _sinusoid(a=0.1, d=1.6, periods=8, pixel=0.05, rows=2)
    terms = taylor_terms(h, pixel)
    kw = -15.0
    m = np.arange(-3, 4)
    got = relative_power(terms, 2 * np.pi * m / 1.6, 0.0, kw)
    np.testing.assert_allclose(got, jv(m, kw * 0.1) ** 2, atol=1e-6)


def _brute(alpha, period, count):
    n = np.arange(count)
    return np.abs(np.exp(-1j * np.multiply.outer(alpha, n * period)).sum(-1)) ** 2


def test_periodic_factor_equals_the_brute_force_sum():
    period, count = 1.3, 7
    rng = np.random.default_rng(3)
    alpha = rng.uniform(-30, 30, 500)
    singular = 2 * np.pi * np.arange(-4, 5) / period
    near = np.concatenate([singular, singular + 1e-9, singular - 1e-6, singular + 1e-3, singular + 0.1])
    for a in (alpha, near):
        np.testing.assert_allclose(
            periodic_factor(a, period, count), _brute(a, period, count), rtol=1e-9, atol=1e-9
        )
    assert np.all(periodic_factor(singular, period, count) == pytest.approx(count**2, rel=1e-12))
    assert periodic_factor(0.0, period, 1) == 1.0
    sums = periodic_sum(alpha, period, count)
    expected = np.exp(-1j * np.multiply.outer(alpha, np.arange(count) * period)).sum(-1)
    np.testing.assert_allclose(sums, expected, atol=1e-9)


def test_periodic_factor_2d_uses_the_corrected_complex_product():
    tx, ty, nx, ny = 1.1, 0.7, 5, 3
    rng = np.random.default_rng(5)
    a, b = rng.uniform(-20, 20, (2, 300))
    a[:3] = 2 * np.pi * np.array([0, 1, -2]) / tx
    b[:3] = 2 * np.pi * np.array([0, 3, 1]) / ty + np.array([0, 1e-8, 0])
    n1, n2 = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    phase = np.multiply.outer(a, (n1 * tx).ravel()) + np.multiply.outer(b, (n2 * ty).ravel())
    brute = np.abs(np.exp(-1j * phase).sum(-1)) ** 2
    got = periodic_factor_2d(a, b, tx, ty, nx, ny)
    np.testing.assert_allclose(got, brute, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got, periodic_factor(a, tx, nx) * periodic_factor(b, ty, ny), rtol=1e-12)
    # the draft's imaginary part p1 p2 + q1 q2 would not give the brute-force sum
    s1, s2 = periodic_sum(a, tx, nx), periodic_sum(b, ty, ny)
    wrong = (s1.real * s2.real - s1.imag * s2.imag) ** 2 + (s1.real * s2.real + s1.imag * s2.imag) ** 2
    assert np.abs(wrong - brute).max() > 1.0


def test_nearest_bins_match_a_hand_sum_and_the_full_window_when_it_is_narrow():
    rng = np.random.default_rng(9)
    h = 0.1 * rng.standard_normal((8, 12))
    terms = taylor_terms(h, (0.05, 0.08), sigma=4.0)
    da, db = terms.spacing
    alpha, beta, kw = 3.3 * da + 0.2, -1.6 * db, -17.0
    total = 0
    for m in (-2, -1):
        for lx in (3, 4):
            c = sum(kw**n * terms.coefficients[n, m % 8, lx] for n in range(terms.order + 1))
            total += c * np.exp(-0.5 * 16 * ((alpha - lx * da) ** 2 + (beta - m * db) ** 2))
    assert terms.evaluate(alpha, beta, kw, stencil=1) == pytest.approx(total, abs=1e-13)
    wide = taylor_terms(h, (0.05, 0.08), sigma=100.0)  # σ Δ ≫ 6: the 2 x 2 bins carry the whole window
    a, b = rng.uniform(-30, 30, (2, 100))
    np.testing.assert_allclose(wide.evaluate(a, b, kw, stencil=1), wide.evaluate(a, b, kw), atol=1e-12)
