"""NumPy oracles shared by several test files (independent of the shaders they check)."""

import math

import numpy as np


def bilinear(h: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Periodic bilinear interpolation of texel-centre samples at (x, y) in texel widths."""
    rows, cols = h.shape
    gx, gy = x - 0.5, y - 0.5
    j0, i0 = np.floor(gx).astype(int), np.floor(gy).astype(int)
    fx, fy = gx - j0, gy - i0
    j1, i1 = (j0 + 1) % cols, (i0 + 1) % rows
    j0, i0 = j0 % cols, i0 % rows
    top = h[i0, j0] * (1 - fx) + h[i0, j1] * fx
    bottom = h[i1, j0] * (1 - fx) + h[i1, j1] * fx
    return top * (1 - fy) + bottom * fy


def gaussian_density(v: float, mu: float, sigma: float) -> float:
    """N(v; μ, σ²) of one scalar, for adaptive quadratures (scipy.stats' pdf costs ~20x per call)."""
    z = (v - mu) / sigma
    return math.exp(-0.5 * z * z) / (sigma * math.sqrt(2.0 * math.pi))
