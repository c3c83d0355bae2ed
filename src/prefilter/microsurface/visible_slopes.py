"""View-dependent slope filtering distribution of a Gaussian microsurface: Heitz, Nowrouzezahrai, Poulin,
Neyret 2014 §5.2, eq. (18), and a 9-node Gauss–Hermite cubature to integrate slope colour maps over it.

The paper's derivation of D_s is in its supplemental document, which we do not have; this one is ours.
Slopes s = ∇h are N(s̄, Σ) in the tangent frame of the coarse surface (normal = +z); the facet of slope s
has the unnormalised normal (−s_x, −s_y, 1), so the area it shows towards ω_o per unit macro area is
(−s, 1)·ω_o = o_z − s·o_xy, clamped at 0 (back-facing). Masking is independent of slope under Smith's
assumption (it depends on height only, eq. 2), so it cancels from eq. (18)'s normalised D_s:

    D_s(s) ∝ (o_z − s·o_xy)⁺ N(s; s̄, Σ).

It depends on s only through u = o_xy·(s − s̄) ~ N(0, σ_u²), σ_u² = o_xyᵀ Σ o_xy. With z = u/σ_u ~ N(0, 1)
and a = (o_z − o_xy·s̄)/σ_u the weight is σ_u (a − z)⁺ φ(z), whose moments ∫ z^k (a − z)⁺ φ(z) dz are

    M0 = a Φ(a) + φ(a),   M1 = −Φ(a),   M2 = a Φ(a) + 2 φ(a)

(from ∫_{−∞}^a φ = Φ(a), ∫_{−∞}^a zφ = −φ(a), ∫_{−∞}^a z²φ = Φ(a) − aφ(a), ∫_{−∞}^a z³φ = −(a² + 2)φ(a));
z̄ = M1/M0, var_z = M2/M0 − z̄². Since the weight depends on z only, s given z keeps its Gaussian
conditional law, E[s | z] = s̄ + Σ o_xy z/σ_u and Cov[s | z] = Σ − Σ o_xy o_xyᵀ Σ/σ_u², hence (total
mean and covariance)

    mean_vis = s̄ + Σ o_xy z̄/σ_u,    cov_vis = Σ − (1 − var_z) Σ o_xy o_xyᵀ Σ/σ_u²,
    projected_area = E[(o_z − s·o_xy)⁺] = σ_u M0 = c Φ(a) + σ_u φ(a),  c = o_z − o_xy·s̄

(the brief's derivation checked step by step: no error found). D_s is not Gaussian (it is a Gaussian
times a ramp along one direction); these are its exact first two moments, the Gaussian the paper uses.
Numerics: for a < 0 the moments cancel (M0 ~ φ(a)/a²), so they are taken in t = a − z >= 0, with
weight t exp(−xt − t²/2), x = −a: t̄ = 2ρ₂(x), var_t = 2ρ₂(3ρ₃ − 2ρ₂) (ρ_k from smith.mills_rho), z̄ = a − t̄,
var_z = var_t. a is clamped to [−1e4, 1e4] (beyond, the visible fraction underflows and the moments are
meaningless, or the shift is below 1e-4 σ_u). σ_u = 0 (normal view, or Σ o_xy = 0) gives D_s = p_s
(mean_vis = s̄, cov_vis = Σ) and projected_area = c⁺. The cov_vis = Σ limit is continuous: |Σ o_xy| <=
√λ_max(Σ) σ_u and 1 − var_z → 0 as a → ∞.

Gauss–Hermite cubature (`gauss_hermite_2d`; GLSL ms_lambertMoments writes its nine nodes out): the
tensor product of the probabilists' rule (order 3: nodes 0, ±√3, weights 2/3, 1/6) mapped through the
Cholesky factor of Σ (lower triangular, robust for semidefinite Σ); node k = order·i + j takes
z = (z_i, z_j). Exact for polynomials of degree <= 2·order − 1 in each variable (degree 5 for order 3).

Lambert under the slope distribution (`lambert_moments`, GLSL ms_lambertMoments): E[L] and Cov(s, L) of
L(s) = max((−s, 1)·ω_i/|(−s, 1)|, 0), the cosine at the facet of slope s, by the same 9-node cubature. The
covariance says how the light falls on the slopes: main() weights the slope colour with it (Stein's lemma,
microsurface.frag).

Parameters: wo (..., 3) unit view direction, mean (..., 2) mean slope s̄, cov (..., 2, 2) or packed
(..., 3) = (Σxx, Σxy, Σyy) (GLSL vec3); slopes are dimensionless (rise over run).
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial.hermite_e import hermegauss
from scipy.special import ndtr

from prefilter.microsurface.smith import cov_parts, mills_rho, normal_loss_scaled, normal_pdf

A_CLAMP = 1e4


def _prepare(wo, mean, cov):
    wo = np.asarray(wo, np.float64)
    mean = np.asarray(mean, np.float64)
    sxx, sxy, syy = cov_parts(cov)
    vx, vy, oz = wo[..., 0], wo[..., 1], wo[..., 2]
    svx = sxx * vx + sxy * vy  # Σ o_xy
    svy = sxy * vx + syy * vy
    su2 = vx * svx + vy * svy
    c = oz - (vx * mean[..., 0] + vy * mean[..., 1])
    ok = su2 > 0.0
    su = np.sqrt(np.where(ok, su2, 1.0))
    a = np.clip(np.where(ok, c / su, 0.0), -A_CLAMP, A_CLAMP)
    return mean, (sxx, sxy, syy), (svx, svy), su2, su, c, a, ok


def visible_slope_moments_1d(a) -> tuple[np.ndarray, np.ndarray]:
    """(z̄, var_z) of the density ∝ (a − z)⁺ φ(z), any real a (float64, no cancellation)."""
    a = np.asarray(a, np.float64)
    ap = np.maximum(a, 0.0)
    cdf, pdf = ndtr(ap), normal_pdf(ap)
    m0 = ap * cdf + pdf
    z_pos = -cdf / m0
    var_pos = (ap * cdf + 2.0 * pdf) / m0 - z_pos**2
    _, r2, r3 = mills_rho(np.maximum(-a, 0.0))
    z_neg = a - 2.0 * r2
    var_neg = 2.0 * r2 * (3.0 * r3 - 2.0 * r2)
    return np.where(a >= 0.0, z_pos, z_neg), np.where(a >= 0.0, var_pos, var_neg)


def visible_slope_moments(wo, mean, cov) -> tuple[np.ndarray, np.ndarray]:
    """Mean (..., 2) and covariance (..., 2, 2) of D_s(s) ∝ (o_z − s·o_xy)⁺ N(s; s̄, Σ) (module header)."""
    mean, (sxx, sxy, syy), (svx, svy), su2, su, _, a, ok = _prepare(wo, mean, cov)
    zbar, var_z = visible_slope_moments_1d(a)
    shift = np.where(ok, zbar / su, 0.0)
    vis_mean = mean + np.stack([svx * shift, svy * shift], axis=-1)
    k = np.where(ok, (1.0 - var_z) / np.where(ok, su2, 1.0), 0.0)
    vis_cov = np.stack(
        [
            np.stack([sxx - k * svx * svx, sxy - k * svx * svy], axis=-1),
            np.stack([sxy - k * svx * svy, syy - k * svy * svy], axis=-1),
        ],
        axis=-2,
    )
    return vis_mean, vis_cov


def projected_area(wo, mean, cov) -> np.ndarray:
    """E[(o_z − s·o_xy)⁺] = ∫ max(cos θ_o, 0) dA per unit macro area (= σ_u M0; c⁺ when σ_u = 0)."""
    _, _, _, _, su, c, a, ok = _prepare(wo, mean, cov)
    front = c * ndtr(np.maximum(a, 0.0)) + su * normal_pdf(np.maximum(a, 0.0))
    back = su * normal_pdf(a) * normal_loss_scaled(np.maximum(-a, 0.0))
    return np.where(ok, np.where(a >= 0.0, front, back), np.maximum(c, 0.0))


def cholesky_2x2(cov) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(L11, L21, L22) of the lower Cholesky factor, robust for positive semidefinite Σ."""
    sxx, sxy, syy = cov_parts(cov)
    l11 = np.sqrt(np.maximum(sxx, 0.0))
    l21 = np.where(l11 > 0.0, sxy / np.where(l11 > 0.0, l11, 1.0), 0.0)
    l22 = np.sqrt(np.maximum(syy - l21 * l21, 0.0))
    return l11, l21, l22


def gauss_hermite_2d(mean, cov, order: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (..., order², 2) and weights (order²,) integrating against N(mean, cov) (module header)."""
    z, w = hermegauss(order)
    w = w / w.sum()
    zi, zj = (g.ravel() for g in np.meshgrid(z, z, indexing="ij"))
    weights = np.outer(w, w).ravel()
    mean = np.asarray(mean, np.float64)
    l11, l21, l22 = (np.asarray(v)[..., None] for v in cholesky_2x2(cov))
    nodes = np.stack([l11 * zi, l21 * zi + l22 * zj], axis=-1) + mean[..., None, :]
    return nodes, weights


def lambert_moments(mean, cov, wi) -> tuple[np.ndarray, np.ndarray]:
    """(E[L], Cov(s, L)) of Lambert's cosine L(s) = max(n(s)·ω_i, 0), n(s) = (−s, 1)/|(−s, 1)|, for slopes
    s ~ N(mean, cov), by the 3 x 3 Gauss–Hermite cubature (module header)."""
    nodes, weights = gauss_hermite_2d(mean, cov)
    normals = np.concatenate([-nodes, np.ones(nodes.shape[:-1] + (1,))], axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    cosine = np.maximum(np.sum(normals * np.asarray(wi, np.float64)[..., None, :], axis=-1), 0.0)
    mean_l = np.sum(weights * cosine, axis=-1)
    cov_sl = np.sum(
        (weights * cosine)[..., None] * (nodes - np.asarray(mean, np.float64)[..., None, :]), axis=-2
    )
    return mean_l, cov_sl
