"""Heitz et al. 2014 §8, Fig. 14: error of the Gaussian approximation of the visible-slope distribution.

Oracles: 1D quadrature of the analytic D_s(s) ∝ (cos θ − s sin θ)⁺ N(s; 0, σ²) of a Gaussian surface
(NumPy trapezoid on a fine grid, SciPy quad for the Gaussian inner product), the Bessel closed form
½ + ½ J0(2π k √2) of a sinusoid grating seen from above, the flat-floor area fraction 1 − π r² of the
bump grid, and the facet normal's projected area computed from explicit 3D vectors.
"""

import numpy as np
import pytest
from oracles import gaussian_density
from scipy.integrate import quad
from scipy.special import j0
from scipy.stats import kurtosis, norm

from prefilter.microsurface.error_analysis import (
    BUMP_RADIUS,
    DEFAULT_FREQUENCIES,
    SLOPE_STD,
    error_vs_frequency,
    filter_exact,
    gaussian_cosine,
    plot_error_vs_frequency,
    slope_moments,
    surface_slopes,
    view_weights,
)

SIZE = 256


def _analytic_ds(theta_deg: float, sigma: float = SLOPE_STD):
    """Grid, normalised density, mean and variance of the x-slope marginal of D_s for Gaussian slopes."""
    s = np.linspace(-10 * sigma, 10 * sigma, 200001)
    c, sn = np.cos(np.radians(theta_deg)), np.sin(np.radians(theta_deg))
    d = np.maximum(c - sn * s, 0.0) * norm.pdf(s, 0.0, sigma)
    d /= np.trapezoid(d, s)
    m = np.trapezoid(s * d, s)
    return s, d, m, np.trapezoid((s - m) ** 2 * d, s)


@pytest.mark.parametrize("surface", ["gaussian", "bumps", "gratings"])
@pytest.mark.parametrize("theta", [0.0, 60.0, 75.0])
def test_dc_and_linear_colour_maps_are_exact(surface, theta):
    r = error_vs_frequency(surface, theta, np.array([0.0, 0.5]), SIZE, seed=1)
    assert r["error"][0] <= 1e-6  # k = 0: both are 1
    assert r["error"][1] > 1e-5  # ... while k = 0.5 is not exact: the check can tell the two apart
    sx, sy = surface_slopes(surface, SIZE, seed=1)
    w = view_weights(sx, sy, theta)
    mean, cov = slope_moments(sx, sy, w)
    sd = np.sqrt(cov[0, 0])
    for colour in (lambda s: s, lambda s: 0.5 + s / (6 * SLOPE_STD)):  # C(s) = s_x and an affine map
        exact = filter_exact(colour(sx), w)
        gauss = quad(
            lambda s, c=colour: c(s) * gaussian_density(s, mean[0], sd), mean[0] - 12 * sd, mean[0] + 12 * sd
        )
        assert abs(exact - gauss[0]) <= 1e-6


def test_gaussian_inner_product_closed_form_matches_quadrature():
    for k, m, v in [(0.3, 0.1, 0.04), (1.7, -0.2, 0.01), (0.05, 0.0, 0.0625), (4.0, 0.3, 0.002)]:
        sd = np.sqrt(v)

        def integrand(s, k=k, m=m, sd=sd):
            return (0.5 + 0.5 * np.cos(2 * np.pi * k * s / 0.25)) * gaussian_density(s, m, sd)

        ref = quad(integrand, m - 12 * sd, m + 12 * sd, limit=400)[0]
        assert abs(gaussian_cosine(k, m, v, 0.25) - ref) <= 1e-9


def test_view_weight_is_projected_facet_area():
    rng = np.random.default_rng(3)
    sx, sy = rng.normal(0, 0.6, 1000), rng.normal(0, 0.6, 1000)
    for theta, phi in [(0.0, 0.0), (60.0, 0.0), (75.0, 130.0), (40.0, -70.0)]:
        t, p = np.radians(theta), np.radians(phi)
        o = np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
        n = np.stack([-sx, -sy, np.ones_like(sx)], axis=1)
        area = np.linalg.norm(n, axis=1)  # facet area over a unit of horizontal area
        projected = area * np.maximum(n @ o / area, 0.0)
        np.testing.assert_allclose(view_weights(sx, sy, theta, phi), projected, atol=1e-12)


def test_surfaces_have_the_intended_slope_statistics():
    sx, sy = surface_slopes("gaussian", 512, seed=0)
    assert np.std(sx) == pytest.approx(SLOPE_STD, rel=1e-12)
    assert np.std(sy) == pytest.approx(SLOPE_STD, rel=0.03)  # isotropic
    assert abs(kurtosis(sx.ravel())) < 0.05 and abs(kurtosis(sy.ravel())) < 0.05  # Gaussian slopes
    bx, by = surface_slopes("bumps", SIZE, seed=0)
    flat = np.mean((bx == 0) & (by == 0))
    assert flat == pytest.approx(1 - np.pi * BUMP_RADIUS**2, abs=0.01)  # the flat floor (an atom at 0)
    assert kurtosis(bx.ravel()) < -0.5 or kurtosis(bx.ravel()) > 1.0  # far from Gaussian


@pytest.mark.parametrize("theta", [0.0, 60.0, 75.0])
def test_exact_filter_on_gaussian_surface_matches_analytic_ds(theta):
    s, d, m, v = _analytic_ds(theta)
    freqs = np.array([0.1, 0.25, 0.4, 0.7, 1.5])
    r = error_vs_frequency("gaussian", theta, freqs, 512, seed=2)
    assert r["mean"][0] == pytest.approx(m, abs=0.02 * SLOPE_STD)
    assert r["covariance"][0, 0] == pytest.approx(v, rel=0.03)
    ref = [np.trapezoid((0.5 + 0.5 * np.cos(2 * np.pi * k * s / SLOPE_STD)) * d, s) for k in freqs]
    np.testing.assert_allclose(r["exact"], ref, atol=0.01)  # Monte Carlo over 512² correlated facets


def test_gaussian_surface_error_below_one_percent():
    for theta in (0.0, 60.0):
        # the limit of an infinite surface, by quadrature: the (o_z − s·o_xy)⁺ weight skews D_s a little
        s, d, m, v = _analytic_ds(theta)
        for k in DEFAULT_FREQUENCIES:
            exact = np.trapezoid((0.5 + 0.5 * np.cos(2 * np.pi * k * s / SLOPE_STD)) * d, s)
            assert abs(exact - gaussian_cosine(k, m, v, SLOPE_STD)) < 0.01
        for seed in (0, 1):  # sampled surfaces (their own moments)
            r = error_vs_frequency("gaussian", theta, DEFAULT_FREQUENCIES, 512, seed)
            assert r["error"].max() < 0.01, (theta, seed, r["error"].max())
    # the criterion discriminates: at 75° the skew of D_s alone is several per cent
    s, d, m, v = _analytic_ds(75.0)
    k = 0.35
    exact = np.trapezoid((0.5 + 0.5 * np.cos(2 * np.pi * k * s / SLOPE_STD)) * d, s)
    assert abs(exact - gaussian_cosine(k, m, v, SLOPE_STD)) > 0.02


@pytest.mark.parametrize("theta", [0.0, 60.0, 75.0])
def test_non_gaussian_surface_error_grows_with_frequency(theta):
    r = error_vs_frequency("bumps", theta, DEFAULT_FREQUENCIES, SIZE, seed=0)
    lowest, highest = r["error"][1], r["error"][-1]  # k = 1/16 and k = 8
    assert lowest < 0.002  # negligible for a colour map much smoother than the slope spread
    assert highest > 0.05
    assert highest > 50 * lowest


def test_bump_grid_high_frequency_limit_is_half_the_flat_atom():
    # at high k only the atom at s = 0 survives the average: C̄ → ½ + ½ (1 − π r²), the Gaussian → ½
    freqs = np.linspace(4.0, 8.0, 17)
    r = error_vs_frequency("bumps", 0.0, freqs, SIZE, seed=0)
    assert r["exact"].mean() == pytest.approx(0.5 + 0.5 * (1 - np.pi * BUMP_RADIUS**2), abs=0.01)
    np.testing.assert_allclose(r["gaussian"], 0.5, atol=1e-12)


def test_gratings_seen_from_above_match_bessel_closed_form():
    freqs = np.array([0.05, 0.2, 0.5, 1.0, 2.0])
    r = error_vs_frequency("gratings", 0.0, freqs, SIZE, seed=4)
    np.testing.assert_allclose(r["exact"], 0.5 + 0.5 * j0(2 * np.pi * freqs * np.sqrt(2)), atol=1e-6)


def test_deterministic_with_the_seed():
    for surface in ("gaussian", "bumps"):
        a = error_vs_frequency(surface, 60.0, DEFAULT_FREQUENCIES, SIZE, seed=5)
        b = error_vs_frequency(surface, 60.0, DEFAULT_FREQUENCIES, SIZE, seed=5)
        c = error_vs_frequency(surface, 60.0, DEFAULT_FREQUENCIES, SIZE, seed=6)
        for key in ("exact", "gaussian", "error", "mean", "covariance"):
            assert np.array_equal(a[key], b[key])
        assert not np.array_equal(a["exact"], c["exact"])


def test_unknown_surface_is_rejected():
    with pytest.raises(ValueError, match="unknown surface"):
        error_vs_frequency("fractal", 0.0, np.array([0.0]), 16)


def test_plot_is_written_atomically(tmp_path):
    path = tmp_path / "fig14.png"
    results = plot_error_vs_frequency(path, DEFAULT_FREQUENCIES[::4], angles=(0.0, 60.0), size=64)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig14.png"]  # no temporary left behind
    assert set(results) == {("gaussian", 0.0), ("gaussian", 60.0), ("bumps", 0.0), ("bumps", 60.0)}
