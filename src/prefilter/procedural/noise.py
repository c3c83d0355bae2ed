"""Perlin's improved gradient noise in 3D, its analytic gradient, and the trilinear "linear noise" variant.

- `perlin_noise` is bit-for-bit the function of Perlin's reference Java `ImprovedNoise.noise(x, y, z)`
  (K. Perlin, "Improving Noise", SIGGRAPH 2002): his 256-entry permutation, the 12 edge gradients
  (padded to 16) chosen by `hash & 15`, the quintic fade 6t^5 - 15t^4 + 10t^3 and `lerp(t, a, b)`.
  The lattice repeats every 256 units along each axis; noise(3.14, 42, 7) = 0.13691995878400012.
- `perlin_noise_grad` adds the analytic gradient dn/dp, the function DNoise of Hart et al. 1999,
  "Antialiased parameterized solid texturing simplified for consumer-level hardware implementation",
  eq. (12) (Hart's filter width uses a_i |dn/ds T_i ds/dx|).
- `footprint_curvature(p, e1, e2)`: e1^T H e1 + e2^T H e2 of the noise's Hessian H, by central differences
  of `perlin_noise` along the unit directions (the quintic fade makes the noise C2, so they converge);
  over a box footprint spanned by e1, e2 the mean of n is n(p) + footprint_curvature / 24 to second
  order. The GLSL `nz_noiseGradCurv` computes it analytically and is tested against this.
- `linear_noise` / `linear_noise_grad`: the same corner contributions interpolated trilinearly (fade(t) = t),
  the reduced noise of Hart's "100,000-gate" implementation (§4.2, Fig. 11). It is only C0: its gradient
  jumps across lattice faces and the grid is visible.

Inputs are points of shape (..., 3) in lattice units, evaluated in float64 with vectorised NumPy.
The GLSL twin is `glsl/common/noise.glsl`: `nz_noise`, `nz_noiseGrad`, `nz_noiseGradCurv`,
`nz_linearNoise`, `nz_linearNoiseGrad`, `nz_linearNoiseGradCurv`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

# The largest lattice frequency (or amplitude) of a noise term that the shaders can evaluate: float32 lattice
# coordinates beyond it have lost their fraction, and a⁴f⁴-style sums overflow. Scene parsers refuse more.
MAX_NOISE_SCALE = 1e8

# Perlin's reference permutation of 0..255 (ImprovedNoise.java, 2002). The Java code doubles it to 512
# entries to avoid wrapping; here every index is reduced with `& 255` instead.
# fmt: off
PERMUTATION: tuple[int, ...] = (
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225,
    140, 36, 103, 30, 69, 142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148,
    247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219, 203, 117, 35, 11, 32,
    57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175,
    74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122,
    60, 211, 133, 230, 220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54,
    65, 25, 63, 161, 1, 216, 80, 73, 209, 76, 132, 187, 208, 89, 18, 169,
    200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173, 186, 3, 64,
    52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212,
    207, 206, 59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213,
    119, 248, 152, 2, 44, 154, 163, 70, 221, 153, 101, 155, 167, 43, 172, 9,
    129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232, 178, 185, 112, 104,
    218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162, 241,
    81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157,
    184, 84, 204, 176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93,
    222, 114, 67, 29, 24, 72, 243, 141, 128, 195, 78, 66, 215, 61, 156, 180,
)
# fmt: on

_PERM = np.array(PERMUTATION, dtype=np.int64)

# Gradient vectors of Perlin's grad(hash, x, y, z) for h = hash & 15: u = h<8 ? x : y,
# v = h<4 ? y : (h==12 || h==14 ? x : z), result = (h&1 ? -u : u) + (h&2 ? -v : v).
# The 12 cube-edge directions, with (1,1,0), (-1,1,0), (0,-1,1), (0,-1,-1) repeated for h = 12..15.
GRADIENTS = np.array(
    [
        [1, 1, 0], [-1, 1, 0], [1, -1, 0], [-1, -1, 0],
        [1, 0, 1], [-1, 0, 1], [1, 0, -1], [-1, 0, -1],
        [0, 1, 1], [0, -1, 1], [0, 1, -1], [0, -1, -1],
        [1, 1, 0], [0, -1, 1], [-1, 1, 0], [0, -1, -1],
    ],
    dtype=np.float64,
)  # fmt: skip
GRADIENTS.flags.writeable = False
_PERM.flags.writeable = False


def fade(t: np.ndarray) -> np.ndarray:
    """Perlin's quintic 6t^5 - 15t^4 + 10t^3, written as in ImprovedNoise.java."""
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def fade_derivative(t: np.ndarray) -> np.ndarray:
    """d fade / dt = 30 t^2 (t - 1)^2."""
    return 30.0 * t * t * (t * (t - 2.0) + 1.0)


def _identity(t: np.ndarray) -> np.ndarray:
    return t


def _one(t: np.ndarray) -> np.ndarray:
    return np.ones_like(t)


def _lerp(t: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a + t * (b - a)


def _noise(
    p: np.ndarray,
    weight: Callable[[np.ndarray], np.ndarray],
    weight_derivative: Callable[[np.ndarray], np.ndarray] | None,
) -> tuple[np.ndarray, np.ndarray | None]:
    p = np.asarray(p, dtype=np.float64)
    if p.ndim == 0 or p.shape[-1] != 3:
        raise ValueError(f"noise expects points of shape (..., 3), got shape {p.shape}")
    cell = np.floor(p)
    f = p - cell  # fractional position in the cell, in [0, 1)
    lattice = cell.astype(np.int64) & 255  # two's complement & 255, as (int)Math.floor(x) & 255 in Java
    X, Y, Z = lattice[..., 0], lattice[..., 1], lattice[..., 2]
    x, y, z = f[..., 0], f[..., 1], f[..., 2]

    # Perlin's hash chain: h(i, j, k) = P[P[P[X + i] + Y + j] + Z + k], every index taken mod 256.
    A = _PERM[X] + Y
    B = _PERM[(X + 1) & 255] + Y
    AA, AB = _PERM[A & 255] + Z, _PERM[(A + 1) & 255] + Z
    BA, BB = _PERM[B & 255] + Z, _PERM[(B + 1) & 255] + Z

    def corner(h: np.ndarray, dx: np.ndarray, dy: np.ndarray, dz: np.ndarray):
        g = GRADIENTS[_PERM[h & 255] & 15]
        # (gx*dx + gy*dy) + gz*dz adds the same two non-zero terms as Java's grad(), so it is exact
        return g, g[..., 0] * dx + g[..., 1] * dy + g[..., 2] * dz

    x1, y1, z1 = x - 1.0, y - 1.0, z - 1.0
    g000, c000 = corner(AA, x, y, z)
    g100, c100 = corner(BA, x1, y, z)
    g010, c010 = corner(AB, x, y1, z)
    g110, c110 = corner(BB, x1, y1, z)
    g001, c001 = corner(AA + 1, x, y, z1)
    g101, c101 = corner(BA + 1, x1, y, z1)
    g011, c011 = corner(AB + 1, x, y1, z1)
    g111, c111 = corner(BB + 1, x1, y1, z1)

    u, v, w = weight(x), weight(y), weight(z)
    a00, a10 = _lerp(u, c000, c100), _lerp(u, c010, c110)
    a01, a11 = _lerp(u, c001, c101), _lerp(u, c011, c111)
    b0, b1 = _lerp(v, a00, a10), _lerp(v, a01, a11)
    value = _lerp(w, b0, b1)
    if weight_derivative is None:
        return value, None

    # n = sum_ijk W_ijk (g_ijk . (f - ijk)), W a tensor product of fades, so
    # dn/dp = sum W_ijk g_ijk (trilinear blend of the gradients) + sum dW_ijk c_ijk (fade slopes).
    u3, v3, w3 = u[..., None], v[..., None], w[..., None]
    blended = _lerp(
        w3,
        _lerp(v3, _lerp(u3, g000, g100), _lerp(u3, g010, g110)),
        _lerp(v3, _lerp(u3, g001, g101), _lerp(u3, g011, g111)),
    )
    ddx = _lerp(w, _lerp(v, c100 - c000, c110 - c010), _lerp(v, c101 - c001, c111 - c011))
    gradient = blended + np.stack(
        [
            weight_derivative(x) * ddx,
            weight_derivative(y) * _lerp(w, a10 - a00, a11 - a01),
            weight_derivative(z) * (b1 - b0),
        ],
        axis=-1,
    )
    return value, gradient


def perlin_noise(p: np.ndarray) -> np.ndarray:
    """Perlin's improved noise at points p (..., 3) -> (...); equal to ImprovedNoise.noise in float64."""
    return _noise(p, fade, None)[0]


def perlin_noise_grad(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(noise (...), analytic gradient dn/dp (..., 3)) of `perlin_noise` at points p (..., 3)."""
    value, gradient = _noise(p, fade, fade_derivative)
    return value, gradient


def footprint_curvature(p: np.ndarray, e1: np.ndarray, e2: np.ndarray, step: float = 1e-4) -> np.ndarray:
    """e1^T H e1 + e2^T H e2 (...) of `perlin_noise` at p (..., 3), e1 and e2 (..., 3) in lattice units."""
    centre = perlin_noise(p)
    total = np.zeros(centre.shape)
    for e in (e1, e2):
        length = np.linalg.norm(e, axis=-1, keepdims=True)
        unit = e / np.maximum(length, 1e-300)
        second = perlin_noise(p + step * unit) - 2.0 * centre + perlin_noise(p - step * unit)
        total = total + length[..., 0] ** 2 * second / step**2
    return total


def linear_noise(p: np.ndarray) -> np.ndarray:
    """`perlin_noise` with the fade replaced by t: trilinear blend of the corner contributions."""
    return _noise(p, _identity, None)[0]


def linear_noise_grad(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(linear noise (...), its gradient (..., 3)); one-sided at lattice faces, where it jumps."""
    value, gradient = _noise(p, _identity, _one)
    return value, gradient
