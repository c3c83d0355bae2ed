"""Dhillon et al. 2014's wavelength-preintegrated tables: the |Σ|² cross terms of the Taylor series,
integrated over 380-780 nm, as 2N + 1 XYZ tables over (u, v) combined per pixel by powers of w.

Expand about w₀ (Dhillon's own expansion is w₀ = 0):
    exp(i k w h) = exp(i k w₀ h) Σ_n (k (w − w₀))ⁿ (i h)ⁿ / n!,
so the windowed transform is P̃(w) = Σ_n (w − w₀)ⁿ a_n, a_n(u, v; λ) = kⁿ P̃[exp(i k w₀ h)(i h)ⁿ / n!](k u, k v)
(mean-subtracted h; the Gaussian window as in transform.py). Its power is a polynomial of degree 2N in w:

    |P̃|² = Σ_j (w − w₀)^j Σ_{n+m=j} a_n conj(a_m),     T_j(u, v) = Σ_λ weight(λ) Σ_{n+m=j} Re(a_n conj(a_m)),

T_j in XYZ (weight = D65 x CIE 1931, spectrum.py). The pixel then needs no wavelength loop: one Horner sum
Σ_j (w − w₀)^j T_j(u, v) over 2N + 1 bilinear lookups (stam.glsl `df_dhillonReflectance`).

The catch is precision. The terms of that sum are bounded by exp(2 k_max |w − w₀| max|h|) (the Taylor
terms' own bound, squared) and cancel down to |P̃|² ≤ 1, while the tables and the shader's sum are float32.
The bound (~2e7 for the snake ridges at w₀ = 0) is pessimistic: with each T_j accurate to its own size, the
sum's terms on the snakes reach ~2e3 at w₀ = 0 (6.5e-4 of the peak off against the 3D table) and ~10 at
w₀ = −1, the middle of the w range (3e-6 off), which also cuts N from 33 to 21 (docs/diffraction.md).

The bake: Single's terms, one FFT each for all wavelengths, re-expanded about w₀ per wavelength; the window
gridded onto the tables' (u, v) grid over every bin in reach (separable Gaussians, as in fast_table.py, as
real products on the real and imaginary parts); the cross terms summed product by product in float64 by a
compiled loop (_cross_terms), row by row, and added to X, Y and Z in place. 27 -> 13 s for the snake's
tables, the same bit for bit as the complex-gridded bake (snake and xenopeltis); most of what is left is
the gridding's matrix products.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import scipy.fft
import scipy.special
from scipy.linalg.blas import daxpy as axpy

from prefilter.diffraction.fast_table import window_gridding
from prefilter.diffraction.spectrum import spectral_weights
from prefilter.diffraction.transform import _order_for

W_RANGE = (-2.0, 0.0)  # w = −(cos θ1 + cos θ2) on the upper hemisphere


def dhillon_order(height_range_um: float, w0: float, epsilon: float, lambda_min_um: float = 0.38) -> int:
    """N for the expansion about w₀: truncation ≤ ε for |w − w₀| up to the farther end of W_RANGE."""
    reach = max(abs(W_RANGE[0] - w0), abs(W_RANGE[1] - w0))
    return _order_for(2.0 * math.pi / lambda_min_um * reach * height_range_um, epsilon)


@numba.njit(cache=True)
def _cross_terms(re: np.ndarray, im: np.ndarray, cross: np.ndarray) -> None:
    """cross[j] += Σ_{n+m=j} Re(a_n conj(a_m)) for a_n = re[n] + i im[n], (N + 1, nv, nu) each: product by
    product in float64, row by row of v (a row's N + 1 terms stay in cache), the inner loop along u."""
    terms, rows, cols = re.shape
    for v in range(rows):
        for n in range(terms):
            for m in range(n, terms):
                twice = 1.0 if m == n else 2.0  # (n, m) and (m, n)
                for u in range(cols):
                    cross[n + m, v, u] += twice * (re[n, v, u] * re[m, v, u] + im[n, v, u] * im[m, v, u])


def bake_dhillon_tables(
    heights: np.ndarray,
    pixel: tuple[float, float],
    sigma: float,
    step_nm: float,
    size: tuple[int, int] = (257, 257),
    w0: float = -1.0,
    epsilon: float = 1e-7,
) -> np.ndarray:
    """(2N + 1, v samples, u samples, 4) float32: T_j in XYZ (A = 0), u and v on linspace(−2, 2, size)."""
    nu, nv = size
    h = np.asarray(heights, np.float64)
    h = h - h.mean()
    if np.all(h == h[:1]):  # a grating (rows all equal): one row has the same coefficients, |β| > 0 empty
        h = h[:1]
    rows, cols = h.shape
    order = dhillon_order(float(np.abs(h).max()), w0, epsilon)
    dx, dy = pixel
    alpha_bins = 2.0 * math.pi * np.fft.fftfreq(cols, dx)
    beta_bins = 2.0 * math.pi * np.fft.fftfreq(rows, dy)
    u, v = np.linspace(-2.0, 2.0, nu), np.linspace(-2.0, 2.0, nv)
    length = 2 * order + 1
    tables = np.zeros((3, length, nv, nu))  # X, Y, Z, each accumulated in place (daxpy)
    # Single's terms c_p = F{(i h)^p / p!} for |w| ≤ 2 (p ≤ N₀), one FFT each for every wavelength; the
    # expansion about w₀ re-expands their polynomial: P̃ = Σ_p (k w)^p c_p = Σ_n (w − w₀)^n a_n with
    # a_n = Σ_{p≥n} C(p, n) k^p w₀^{p−n} c_p (in float64 its terms stay below e^{k |w₀| max|h|} ~ 10²)
    full = max(order, dhillon_order(float(np.abs(h).max()), 0.0, epsilon))
    powers = np.empty((full + 1, rows, cols), np.complex128)  # (i h)^p / p!
    powers[0] = 1.0
    for p in range(1, full + 1):
        powers[p] = powers[p - 1] * (1j * h) / p
    coefficients = scipy.fft.fft2(powers, axes=(1, 2), workers=-1) / (rows * cols)
    del powers
    kept, term = np.arange(order + 1)[:, None], np.arange(full + 1)[None, :]  # n, p
    binomial = scipy.special.comb(term, kept) * (term >= kept)  # (N + 1, N₀ + 1)
    wavelengths, weights = spectral_weights(step_nm)
    for lam, weight in zip(wavelengths, weights, strict=True):
        k = 2.0 * math.pi / lam
        sx, sy, gu, gv = window_gridding(k, sigma, alpha_bins, beta_bins, u, v)
        shift = binomial * k**term * float(w0) ** np.maximum(term - kept, 0)
        window = np.tensordot(shift, coefficients[:, sy[:, None], sx], axes=(1, 0))  # (N + 1, Sy, Sx)
        # the windowed transform of each term, (N + 1, nv, nu): the weights are real, so the real and
        # imaginary parts are gridded as real products (a complex product with them did twice the work)
        re = gv @ np.ascontiguousarray(window.real) @ gu.T
        im = gv @ np.ascontiguousarray(window.imag) @ gu.T
        # Σ_{n+m=j} Re(a_n conj(a_m)) for j = 0..2N, product by product: each T_j keeps its own relative
        # accuracy (an FFT product would leave a floor of 1e-16 max|a|² that (w − w₀)^2N multiplies)
        # (compiled, _cross_terms; numpy's passes over blocks of rows took 4 s of the snake's bake)
        cross = np.zeros((length, nv, nu))
        _cross_terms(re, im, cross)
        for channel in range(3):
            axpy(cross.ravel(), tables[channel].ravel(), a=weight[channel])
    out = np.zeros((length, nv, nu, 4), np.float32)
    out[..., :3] = np.moveaxis(tables, 0, -1)
    return out
