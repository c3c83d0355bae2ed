"""Irradiance environment maps in 9 spherical-harmonic coefficients, filtered over microsurface slopes.

Ramamoorthi & Hanrahan 2001 ("An efficient representation for irradiance environment maps", eqs. 3,
7–9): project the distant radiance L(ω) on the real spherical harmonics of bands l <= 2,

    L_lm = ∫ L(ω) Y_lm(ω) dω,     E(n) = Σ_{l<=2} Σ_m Â_l L_lm Y_lm(n),   Â_0 = π, Â_1 = 2π/3, Â_2 = π/4,

where E(n) = ∫ L(ω) max(n·ω, 0) dω is the *irradiance* (W m⁻² for L in W m⁻² sr⁻¹) of a surface with
unit normal n, unshadowed. A Lambertian surface of albedo ρ reflects the radiance ρ E(n) / π. The SH9
E(n) is a quadratic polynomial in n; it is not clamped, and can dip slightly below 0 (by up to ~4 %
of the mean) facing away from a strong sun. Error: |E_SH9 − E| <= (3/32) ∫ L dω for any non-negative
map (the worst case of the SH9 clamped-cosine kernel, a light on the horizon: RH2001's "9 %"). RH2001
measured ~1 % mean error on sunless maps; on the shipped sunny maps the mean |error| is 3–6.5 %
(sky-low-sun) and 4–6.5 % (sky-high-sun) of the mean irradiance, per channel (tests/test_irradiance.py).

Heitz, Nowrouzezahrai, Poulin, Neyret 2014 §5.3: on a Lambertian microsurface whose micro-normals are
spread by the slope distribution, the filtered irradiance is the expectation of E over the (view-
dependent, visible) slope distribution, which is handed in here as a Gaussian N(mean, cov):

    Ē = E_s[E(n(s))],   n(s) = normalize(worldFromTangent · (−s_x, −s_y, 1)),

evaluated with the 3 x 3 tensor Gauss–Hermite rule through the Cholesky factor of cov (nodes 0, ±√3,
weights 2/3, 1/6 per axis: exact for polynomials up to degree 5 in each standardised variable).
Measured error vs a 40 x 40 rule, relative to max |Ē|, for slope standard deviations σ: 1e-6 (0.05),
6e-5 (0.1), 2e-3 (0.2), 1e-2 (0.3), 2e-2 (0.5), 0.13 (1.0): use it for σ <~ 0.3.

Conventions. Real SH of RH2001 eq. 3, without Condon–Shortley phase, in the order k = l² + l + m:
  k: 0 (0,0) 1 (1,−1) 2 (1,0) 3 (1,1) 4 (2,−2) 5 (2,−1) 6 (2,0) 7 (2,1) 8 (2,2)
  Y: 0.282095 | 0.488603 y, z, x | 1.092548 xy, yz; 0.315392 (3z² − 1); 1.092548 xz; 0.546274 (x² − y²)
Environment maps are equirectangular, linear RGB (H, W = 2H, 3): row i spans polar angle
θ ∈ [π i/H, π (i+1)/H] from the zenith (world +z up), column j spans longitude φ ∈ [2π j/W, 2π (j+1)/W],
φ = 0 at +x increasing towards +y; ω = (sin θ cos φ, sin θ sin φ, cos θ). The radiance is taken as
constant over each pixel, and the projection integrates Y_lm over each pixel exactly (closed forms in
cos θ and φ), so that the coefficients are exact for the piecewise-constant map.

Uniform layout (`sh_uniform`): float32 (9, 3), row k = coefficient L_k, columns RGB, for a GLSL
`uniform vec3 name[9]` passed to ms_irradianceSH / ms_filteredIrradianceSH / ms_filteredIrradianceMomentsSH
(irradiance.glsl).
Maps shipped in scenes/data/: sky-low-sun.exr, sky-high-sun.exr (procedural clear sky: Preetham sky,
sun, Lambertian ground, sun elevation 12° and 50°; 256 x 128, made by scripts/make-sky.py).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from prefilter import PrefilterError
from prefilter.images import read_image

GLSL = "microsurface/irradiance.glsl"

C0 = 0.5 / np.sqrt(np.pi)  # Y00 = 0.282095
C1 = np.sqrt(3.0 / (4.0 * np.pi))  # Y1m = 0.488603 (y, z, x)
C2 = np.sqrt(15.0 / (4.0 * np.pi))  # Y2,-2 Y2,-1 Y2,1 = 1.092548 (xy, yz, xz)
C20 = np.sqrt(5.0 / (16.0 * np.pi))  # Y20 = 0.315392 (3z² − 1)
C22 = np.sqrt(15.0 / (16.0 * np.pi))  # Y22 = 0.546274 (x² − y²)
A_HAT = np.array([np.pi] + [2.0 * np.pi / 3.0] * 3 + [np.pi / 4.0] * 5)  # Â_l per coefficient k
SH_LM = ((0, 0), (1, -1), (1, 0), (1, 1), (2, -2), (2, -1), (2, 0), (2, 1), (2, 2))

GH_NODES = np.array([-np.sqrt(3.0), 0.0, np.sqrt(3.0)])  # probabilists' Gauss–Hermite, 3 nodes
GH_WEIGHTS = np.array([1.0, 4.0, 1.0]) / 6.0


def read_environment(path: str | os.PathLike) -> np.ndarray:
    """An equirectangular map (.exr linear, or .png sRGB-decoded) as float64 (H, 2H, 3) radiance."""
    path = Path(path)
    rgb, _ = read_image(path)
    env = np.asarray(rgb, dtype=np.float64)
    h, w, _ = env.shape
    if w != 2 * h:
        raise PrefilterError(f"{path}: an equirectangular map must be twice as wide as high, got {w}x{h}")
    if not np.all(np.isfinite(env)) or env.min() < 0:
        raise PrefilterError(f"{path}: environment radiance must be finite and non-negative")
    return env


def _check_env(env: np.ndarray) -> np.ndarray:
    env = np.asarray(env, dtype=np.float64)
    if env.ndim != 3 or env.shape[2] != 3 or env.shape[1] != 2 * env.shape[0]:
        raise ValueError(f"expected an equirectangular (H, 2H, 3) map, got shape {env.shape}")
    return env


def pixel_solid_angles(h: int, w: int) -> np.ndarray:
    """Exact solid angle of each pixel row, (H,): (2π / W)(cos θ_i − cos θ_{i+1}); they sum to 4π."""
    edges = np.cos(np.pi * np.arange(h + 1) / h)
    return (2.0 * np.pi / w) * (edges[:-1] - edges[1:])


def pixel_directions(h: int, w: int) -> np.ndarray:
    """Unit directions (H, W, 3) at the pixel centres (θ, φ midpoints)."""
    theta = np.pi * (np.arange(h) + 0.5) / h
    phi = 2.0 * np.pi * (np.arange(w) + 0.5) / w
    st = np.sin(theta)[:, None]
    return np.stack(
        [st * np.cos(phi)[None], st * np.sin(phi)[None], np.broadcast_to(np.cos(theta)[:, None], (h, w))],
        axis=-1,
    )


def sh9_basis(n: np.ndarray) -> np.ndarray:
    """The 9 real SH Y_k(n) (RH2001 eq. 3) for unit vectors n (..., 3), as (..., 9)."""
    n = np.asarray(n, dtype=np.float64)
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    return np.stack(
        [
            np.full_like(x, C0),
            C1 * y,
            C1 * z,
            C1 * x,
            C2 * x * y,
            C2 * y * z,
            C20 * (3.0 * z * z - 1.0),
            C2 * x * z,
            C22 * (x * x - y * y),
        ],
        axis=-1,
    )


def sh9_pixel_integrals(h: int, w: int) -> np.ndarray:
    """∫_pixel Y_k(ω) dω for every pixel of an (h, w) equirect map, exactly: (9, h, w).

    With u = cos θ and s = sin θ = √(1 − u²), dω = du dφ and each Y_k is a product g(u) f(φ); the row
    factors ∫ g du and column factors ∫ f dφ have closed forms.
    """
    u = np.cos(np.pi * np.arange(h + 1) / h)  # row edges, decreasing from 1 to −1
    phi = 2.0 * np.pi * np.arange(w + 1) / w

    def rows(antiderivative) -> np.ndarray:  # ∫_{u_{i+1}}^{u_i} g(u) du
        f = antiderivative(u)
        return f[:-1] - f[1:]

    def cols(antiderivative) -> np.ndarray:  # ∫_{φ_j}^{φ_{j+1}} f(φ) dφ
        f = antiderivative(phi)
        return f[1:] - f[:-1]

    r_one = rows(lambda t: t)
    r_s = rows(
        lambda t: 0.5 * (t * np.sqrt(np.clip(1.0 - t * t, 0.0, None)) + np.arcsin(np.clip(t, -1.0, 1.0)))
    )
    r_u = rows(lambda t: 0.5 * t * t)
    r_ss = rows(lambda t: t - t**3 / 3.0)  # ∫ (1 − u²) du
    r_us = rows(lambda t: -(np.clip(1.0 - t * t, 0.0, None) ** 1.5) / 3.0)  # ∫ u √(1 − u²) du
    r_p2 = rows(lambda t: t**3 - t)  # ∫ (3u² − 1) du
    c_one = cols(lambda p: p)
    c_cos = cols(np.sin)
    c_sin = cols(lambda p: -np.cos(p))
    c_sincos = cols(lambda p: -0.25 * np.cos(2.0 * p))  # ∫ sin φ cos φ dφ
    c_cos2 = cols(lambda p: 0.5 * np.sin(2.0 * p))
    pairs = [
        (C0, r_one, c_one),
        (C1, r_s, c_sin),
        (C1, r_u, c_one),
        (C1, r_s, c_cos),
        (C2, r_ss, c_sincos),
        (C2, r_us, c_sin),
        (C20, r_p2, c_one),
        (C2, r_us, c_cos),
        (C22, r_ss, c_cos2),
    ]
    return np.stack([k * np.outer(r, c) for k, r, c in pairs])


def sh9_project(env: np.ndarray) -> np.ndarray:
    """SH9 coefficients L_k of an equirect radiance map (H, 2H, 3), piecewise constant per pixel: (9, 3)."""
    env = _check_env(env)
    h, w, _ = env.shape
    return np.einsum("kij,ijc->kc", sh9_pixel_integrals(h, w), env)


def irradiance_sh(coeffs: np.ndarray, n: np.ndarray) -> np.ndarray:
    """RH2001 irradiance E(n) = Σ Â_l L_k Y_k(n) for unit normals n (..., 3): (..., 3) RGB (not clamped)."""
    coeffs = np.asarray(coeffs, dtype=np.float64)
    return (sh9_basis(n) * A_HAT) @ coeffs


def irradiance_brute(env: np.ndarray, n: np.ndarray, supersample: int = 2, chunk: int = 64) -> np.ndarray:
    """Oracle: E(n) = ∫ L(ω) max(n·ω, 0) dω by quadrature over the map's pixels: (..., 3).

    Each pixel (radiance constant over it) is split into supersample² cells of equal Δθ, Δφ; the
    clamped cosine is evaluated at each cell's centre and weighted by the cell's exact solid angle.
    """
    env = _check_env(env)
    h, w, _ = env.shape
    s = int(supersample)
    dirs = pixel_directions(h * s, w * s).reshape(-1, 3)
    omega = np.repeat(pixel_solid_angles(h * s, w * s), w * s)
    radiance = np.repeat(np.repeat(env, s, axis=0), s, axis=1).reshape(-1, 3)
    weighted = radiance * omega[:, None]
    n = np.asarray(n, dtype=np.float64)
    flat = n.reshape(-1, 3)
    out = np.empty((len(flat), 3))
    for start in range(0, len(flat), chunk):
        cosine = np.maximum(flat[start : start + chunk] @ dirs.T, 0.0)
        out[start : start + chunk] = cosine @ weighted
    return out.reshape(n.shape[:-1] + (3,))


def _cov_cholesky(cov: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(l11, l21, l22) of cov given as (..., 2, 2) or (..., 3) = (xx, xy, yy); PSD-clamped like the GLSL."""
    cov = np.asarray(cov, dtype=np.float64)
    if cov.shape[-2:] == (2, 2):
        xx, xy, yy = cov[..., 0, 0], cov[..., 0, 1], cov[..., 1, 1]
    elif cov.shape[-1] == 3:
        xx, xy, yy = cov[..., 0], cov[..., 1], cov[..., 2]
    else:
        raise ValueError(f"cov must be (..., 2, 2) or (..., 3) = (xx, xy, yy), got shape {cov.shape}")
    l11 = np.sqrt(np.maximum(xx, 0.0))
    l21 = np.divide(xy, l11, out=np.zeros(np.broadcast(xy, l11).shape), where=l11 > 0)
    l22 = np.sqrt(np.maximum(yy - l21 * l21, 0.0))
    return l11, l21, l22


def slope_normals(frame: np.ndarray, slopes: np.ndarray) -> np.ndarray:
    """World unit normals normalize(frame @ (−s_x, −s_y, 1)) of slopes (..., 2); frame (..., 3, 3)."""
    slopes = np.asarray(slopes, dtype=np.float64)
    t = np.concatenate([-slopes, np.ones(slopes.shape[:-1] + (1,))], axis=-1)
    m = np.einsum("...ij,...j->...i", np.asarray(frame, dtype=np.float64), t)
    return m / np.linalg.norm(m, axis=-1, keepdims=True)


def filtered_irradiance(
    coeffs: np.ndarray, frame: np.ndarray, mean: np.ndarray, cov: np.ndarray
) -> np.ndarray:
    """E_s[E(n(s))] for slopes s ~ N(mean, cov) by 3x3 Gauss–Hermite cubature: (..., 3) RGB.

    coeffs (9, 3); frame (..., 3, 3) world-from-tangent (columns: tangent, bitangent, normal in world);
    mean (..., 2) slopes; cov (..., 2, 2) or (..., 3) = (xx, xy, yy) (slope², dimensionless).
    """
    return filtered_irradiance_moments(coeffs, frame, mean, cov, np.zeros(2))[0]


def filtered_irradiance_moments(
    coeffs: np.ndarray, frame: np.ndarray, mean: np.ndarray, cov: np.ndarray, direction: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(E_s[E(n(s))], Cov(s·d, E(n(s)))) for slopes s ~ N(mean, cov) and a slope direction d (2,), both
    (..., 3) RGB, from the same 3x3 Gauss–Hermite nodes (twin of ms_filteredIrradianceMomentsSH). The
    covariance is what a colour tied to the slope along d adds where it correlates with the irradiance."""
    mean = np.asarray(mean, dtype=np.float64)
    direction = np.asarray(direction, dtype=np.float64)
    l11, l21, l22 = _cov_cholesky(cov)
    frame = np.asarray(frame, dtype=np.float64)
    total, covariance = 0.0, 0.0
    for xi, wi in zip(GH_NODES, GH_WEIGHTS, strict=True):
        for xj, wj in zip(GH_NODES, GH_WEIGHTS, strict=True):
            offset = np.stack(np.broadcast_arrays(l11 * xi, l21 * xi + l22 * xj), axis=-1)
            e = wi * wj * irradiance_sh(coeffs, slope_normals(frame, mean + offset))
            total = total + e
            covariance = covariance + (offset @ direction)[..., None] * e
    return np.asarray(total), np.asarray(covariance)


def sh_uniform(coeffs: np.ndarray) -> np.ndarray:
    """Coefficients as float32 (9, 3), C-contiguous, for `uniform vec3 name[9]` (set_uniforms writes it)."""
    coeffs = np.asarray(coeffs)
    if coeffs.shape != (9, 3):
        raise ValueError(f"expected SH9 RGB coefficients of shape (9, 3), got {coeffs.shape}")
    return np.ascontiguousarray(coeffs, dtype=np.float32)
