"""The wavelength-preintegrated fast path: XYZ(u, v, w) = Σ_λ |P̃(k u, k v; k w)|² x (D65 x CIE 1931).

Dhillon et al. 2014 take the wavelength loop out of the pixel shader by integrating the |Σ|² cross terms
of the Taylor series over 380-780 nm into 2N + 1 tables over (u, v), combined per pixel by powers of w
(mode `dhillon`, diffraction/dhillon.py). This module preintegrates the same quantity one step later: the
spectrally integrated power itself, a function of (u, v, w) alone, tabulated on a 3D grid — u, v in
[-2, 2], w in [-2, 0], texel centres on the grid points, odd counts so that the specular direction u = v = 0
is a node — and read with one trilinear lookup instead of Dhillon's 2N + 1 (mode `fast`). The wavelength-
independent gain (Fresnel, G / w², 2 cos²θ1) is applied per pixel (stam.glsl `df_fastReflectance`).

The bake needs no Taylor series: for each wavelength and w-slice, k w is one number, so the Fourier-series
coefficients of exp(i k w h) over the patch are one FFT, C = fft2(exp(i k w h_c)) / (H W) (the sum of
Single's terms, without their truncation). The windowed transform on the table's (u, v) grid is then
separable Gaussian gridding, P̃ = G_v C G_u^T with G[a, l] = exp(−σ² (k u_a − α_l)² / 2) over the bins
within reach of the visible range: every bin of the window, not the shader's stencil. With tiles
(Single §2.7) the power is the nearest bin's |C|² times the periodic factor, as in stam.glsl.

Its resolution bounds the narrowest lobe it can hold (so does Dhillon's, on the same u, v grid): lobes are
about 1 / (k σ) wide in u and v, so σ up to a few µm (the presets) needs 257 samples per axis; σ = 16 µm
would need thousands, and the accurate path is then the one to use.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft

from prefilter.diffraction.spectrum import spectral_weights
from prefilter.diffraction.transform import WINDOW_RADIUS, periodic_factor

DEFAULT_SIZE = (257, 257, 33)  # u, v, w samples: odd, so u = 0, v = 0 and w = -1 are grid points


def window_gridding(k: float, sigma: float, alpha_bins, beta_bins, u, v):
    """The coherence window carried from the DFT bins to a (u, v) grid at wavenumber k: the bins in reach of
    the visible range (|α|, |β| ≤ 2k + WINDOW_RADIUS / σ) and the separable Gaussian weights, so that the
    windowed transform of coefficients C on the grid is G_v C[sy, sx] G_uᵀ. Returns (sx, sy, G_u, G_v)."""
    reach = 2.0 * k + WINDOW_RADIUS / sigma
    sx = np.nonzero(np.abs(alpha_bins) <= reach)[0]
    sy = np.nonzero(np.abs(beta_bins) <= reach)[0]
    gu = np.exp(-0.5 * (sigma * (k * np.asarray(u)[:, None] - alpha_bins[sx])) ** 2)
    gv = np.exp(-0.5 * (sigma * (k * np.asarray(v)[:, None] - beta_bins[sy])) ** 2)
    # weights below 1e-30 are 0: in float32 the smallest are subnormal, and products over subnormal
    # operands ran 10x slower (on the snake the fast table's second gridding product took 5.2 ms a slice
    # with them, 0.4 ms without; dropping them moves an amplitude by under 1e-25, 283² bins of at most 1e-30)
    gu[gu < 1e-30] = 0.0
    gv[gv < 1e-30] = 0.0
    return sx, sy, gu, gv


def _phasor_slices(k: float, w: np.ndarray, h: np.ndarray):
    """exp(i k w_j h) for the evenly spaced w_j, complex64, each slice from the last by one complex product
    in float64 (32 products lose under 1e-14; float32 cosines and sines of every slice took a fifth of the
    bake, and NumPy's complex exp ten times that)."""

    def unit(phase: np.ndarray) -> np.ndarray:
        out = np.empty(phase.shape, np.complex128)
        out.real, out.imag = np.cos(phase), np.sin(phase)
        return out

    phasor = unit(k * float(w[0]) * h)
    turn = unit(k * float(w[1] - w[0]) * h) if len(w) > 1 else None
    for _ in w:
        yield phasor.astype(np.complex64)
        if turn is not None:
            phasor *= turn


def bake_fast_table(
    heights: np.ndarray,
    pixel: tuple[float, float],
    sigma: float,
    step_nm: float,
    size=DEFAULT_SIZE,
    tiles: tuple[int, int] | None = None,
) -> np.ndarray:
    """(w samples, v samples, u samples, 4) float32: XYZ (and 1) of the spectrally integrated power.

    Per (wavelength, w) the DFT runs along the rows first and along the columns only at the bins in reach,
    and the window's real weights grid the coefficients' real and imaginary parts as two real products
    (a complex product with real weights did twice the work); each slice's power is added to X, Y and Z in
    place. With the weights' subnormals flushed (window_gridding) the snake's table bakes in 17 s instead
    of 42, the same to 1.2e-7 of its peak (float32 rounding); with each slice's phasors from the last
    slice's (_phasor_slices) in 0.86 of that time (24.2 -> 20.9 s on a busier machine), the same to 1.1e-7."""
    nu, nv, nw = size
    h = np.asarray(heights, np.float64)
    h = h - h.mean()
    if tiles is None and np.all(h == h[:1]):  # a grating (rows all equal): one row gives the same
        h = h[:1]  # coefficients (those at β ≠ 0 are zero); the tiling factor needs the patch's height
    rows, cols = h.shape
    dx, dy = pixel
    alpha_bins = 2.0 * math.pi * np.fft.fftfreq(cols, dx)
    beta_bins = 2.0 * math.pi * np.fft.fftfreq(rows, dy)
    u, v, w = np.linspace(-2.0, 2.0, nu), np.linspace(-2.0, 2.0, nv), np.linspace(-2.0, 0.0, nw)
    out = np.zeros((3, nw, nv, nu))
    wavelengths, weights = spectral_weights(step_nm)
    for lam, weight in zip(wavelengths, weights, strict=True):
        k = 2.0 * math.pi / lam
        alpha, beta = k * u, k * v
        if tiles is None:
            sx, sy, gu, gv = window_gridding(k, sigma, alpha_bins, beta_bins, u, v)
            gu, gv = gu.astype(np.float32), gv.astype(np.float32)
        else:
            lx = np.floor(alpha / (2.0 * math.pi / (cols * dx)) + 0.5).astype(np.int64) % cols
            ly = np.floor(beta / (2.0 * math.pi / (rows * dy)) + 0.5).astype(np.int64) % rows
            factor = np.outer(  # normalised by N² per axis: a flat mirror stays 1
                periodic_factor(beta, rows * dy, tiles[1]) / tiles[1] ** 2,
                periodic_factor(alpha, cols * dx, tiles[0]) / tiles[0] ** 2,
            )
            sx, sy = lx, ly
        for j, phasor in enumerate(_phasor_slices(k, w, h)):
            c = scipy.fft.fft(phasor, axis=1, workers=-1)[:, sx]
            c = scipy.fft.fft(c, axis=0, workers=-1)[sy] / (rows * cols)
            if tiles is None:
                parts = gv @ np.concatenate([c.real, c.imag], axis=1)  # (v, 2 bins): real, imaginary
                re, im = parts[:, : len(sx)] @ gu.T, parts[:, len(sx) :] @ gu.T
                power = re * re + im * im
            else:
                power = (c.real * c.real + c.imag * c.imag) * factor
            for channel in range(3):
                out[channel, j] += weight[channel] * power
    xyz1 = np.concatenate([out, np.ones((1,) + out.shape[1:])])
    return np.ascontiguousarray(np.moveaxis(xyz1, 0, -1), dtype=np.float32)
