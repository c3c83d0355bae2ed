"""Smith masking for Gaussian microsurfaces: Heitz, Nowrouzezahrai, Poulin, Neyret 2014 §3, eqs. (2), (3),
(12) (with the DESIGN.md errata), and the float-accurate erfc that the GLSL twin (smith.glsl) needs.

Conventions: directions w are unit vectors in the tangent frame of the coarse surface (normal = +z);
slopes s = ∇h of z = h(x, y) are N(s̄, Σ), Σ a 2x2 covariance given either as (..., 2, 2) matrices or
packed (..., 3) = (Σxx, Σxy, Σyy) as in GLSL; heights are N(0, σ_h²) (σ_h in length units).

    Λ(ω) = σ_s / (μ √(2π)) exp(−μ² / (2σ_s²)) − ½ erfc(μ / (√2 σ_s))          (eq. under (2))
         = G(ν) / ν,   ν = μ/σ_s = w_z / √(w_xyᵀ Σ w_xy),  G(ν) = φ(ν) − ν Q(ν)

with μ = cot θ = w_z/|w_xy|, σ_s² = d̂ᵀΣd̂ the slope variance along d̂ = w_xy/|w_xy|, φ, Φ, Q = 1 − Φ the
standard normal density, CDF and tail. G is the normal loss function E[(Z − ν)⁺]; for ν >= 3 (GLSL: 1.5)
it is evaluated as φ(ν) J₁(ν) with J₁ = G/φ from Laplace's continued fraction of the Mills ratio, which
avoids the cancellation in φ(ν)/ν − Q(ν) and keeps full relative precision as σ_s → 0 (Λ → 0, no NaN).
Limits: Λ = 0 at normal incidence (w_xy = 0) and for Σ = 0; at grazing incidence ν is clamped to
NU_MIN = 1e-4 (w_z <= 0 included), so Λ <= φ(0)/NU_MIN − ½ ≈ 3989 stays finite (and Λ_o + Λ_i stays
below the L_max = 1e4 of the height filtering table).

    P_h(h) = ½ erfc(−h / (√2 σ_h)),   V(h, ω) = P_h(h)^Λ(ω)                       (eq. 2)
    V̄(ω_o, ω_i) = ∫ P_h^(Λo+Λi) p_h dh / ∫ P_h^Λo p_h dh = (1 + Λo) / (1 + Λo + Λi)   (eq. 12, errata)

erfc for GLSL (ms_erfc / ms_erfcx): erfcx(x) = exp(x²) erfc(x) ≈ t exp(P(t)), t = 1 / (1 + x/2), x >= 0,
P a degree-9 polynomial (ERFCX_COEFFS, the form of Numerical Recipes' erfcc) refitted here by
`fit_erfcx_coefficients`: Lawson-weighted Chebyshev least squares on log(erfcx(x)/t) over t in (0, 1]
(near-minimax). Max relative error of the fit (float64, all x >= 0): 9.8e-8. erfc(x) = erfcx(x) exp(−x²)
(x >= 0; exp(−x²) with x split so that the large part of x² is exact in float32), 2 − erfc(−x) (x < 0).
Measured in float32 on llvmpipe (tests/test_microsurface_stats.py): relative error <= 6.7e-7 for
x in [−6, 9.1] against scipy.special.erfc at the same float32 inputs (a plain exp(−x²) costs up to 7e-6:
llvmpipe's exp loses ~|arg| ulp); 0 for x > 9.3, where erfc is below the normal float32 range.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev, polynomial
from scipy.special import erfcx, ndtr

NU_MIN = 1e-4  # grazing clamp of ν = cot θ / σ_s
INV_SQRT_2PI = 1.0 / np.sqrt(2.0 * np.pi)
SQRT_HALF_PI = np.sqrt(0.5 * np.pi)

# log(erfcx(x) / t) ≈ Σ_k c_k t^k, t = 1 / (1 + x/2): fit_erfcx_coefficients(9), rounded to 9 digits
ERFCX_COEFFS = (
    -1.26551222,
    1.00002266,
    0.37412486,
    0.09638966,
    -0.18397321,
    0.2713703,
    -1.12112952,
    1.4732828,
    -0.8133392,
    0.16876379,
)

# Mills-ratio continued fraction: switch point and depth (float64 here; smith.glsl uses 2 and 16)
CF_SWITCH = 3.0
CF_DEPTH = 40


def fit_erfcx_coefficients(degree: int = 9, nodes: int = 4000, iterations: int = 60) -> np.ndarray:
    """Refit ERFCX_COEFFS (monomial coefficients in t, lowest first) by Lawson's iteration."""
    k = np.arange(nodes)
    t = 0.5 * (1.0 + np.cos(np.pi * (k + 0.5) / nodes))
    t = t[t > 1e-6]
    y = np.log(erfcx(2.0 * (1.0 / t - 1.0)) / t)
    weights = np.ones_like(t)
    for _ in range(iterations):
        c = chebyshev.chebfit(2.0 * t - 1.0, y, degree, w=np.sqrt(weights))
        weights = weights * np.abs(chebyshev.chebval(2.0 * t - 1.0, c) - y)
        weights /= weights.sum()
    in_s = chebyshev.cheb2poly(c)  # polynomial in s = 2t − 1: compose with s(t)
    out = np.zeros(1)
    for coef in in_s[::-1]:
        out = polynomial.polyadd(polynomial.polymul(out, [-1.0, 2.0]), [coef])
    return out


def erfcx_approx(x: np.ndarray) -> np.ndarray:
    """NumPy twin of ms_erfcx (float64 arithmetic): the fitted erfcx for x >= 0 (x < 0 taken as 0)."""
    x = np.maximum(np.asarray(x, np.float64), 0.0)
    t = 1.0 / (1.0 + 0.5 * x)
    return t * np.exp(polynomial.polyval(t, ERFCX_COEFFS))


def erfc_approx(x: np.ndarray) -> np.ndarray:
    """NumPy twin of ms_erfc (float64 arithmetic)."""
    x = np.asarray(x, np.float64)
    ax = np.abs(x)
    e = erfcx_approx(ax) * np.exp(-ax * ax)
    return np.where(x >= 0.0, e, 2.0 - e)


def cov_parts(cov) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Σxx, Σxy, Σyy) from (..., 2, 2) matrices or packed (..., 3) vectors."""
    cov = np.asarray(cov, np.float64)
    if cov.shape[-2:] == (2, 2):
        return cov[..., 0, 0], 0.5 * (cov[..., 0, 1] + cov[..., 1, 0]), cov[..., 1, 1]
    if cov.shape[-1] == 3:
        return cov[..., 0], cov[..., 1], cov[..., 2]
    raise ValueError(f"covariance must have shape (..., 2, 2) or (..., 3), got {cov.shape}")


def mills_rho(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ρ₁, ρ₂, ρ₃)(x), x >= 0, with J_k(x) = ∫₀^∞ t^k exp(−xt − t²/2) dt and ρ_k = J_k / (k J_{k−1}).

    J₀ = R (the Mills ratio Q/φ), J₁ = 1 − xR = G/φ, and J_k = k! R ρ₁ ⋯ ρ_k. Small x: forward recurrence
    J_{k+1} = k J_{k−1} − x J_k from R = √(π/2) erfcx(x/√2); large x (where the recurrence cancels):
    Laplace's continued fraction ρ_k = 1 / (x + (k+1) ρ_{k+1}), started from its fixed point at depth
    CF_DEPTH. Both are accurate to ~1e-13 relative in float64.
    """
    x = np.maximum(np.asarray(x, np.float64), 0.0)
    small = x < CF_SWITCH
    xs = np.where(small, x, 0.0)
    j0 = SQRT_HALF_PI * erfcx(xs / np.sqrt(2.0))
    j1 = 1.0 - xs * j0
    j2 = j0 - xs * j1
    j3 = 2.0 * j1 - xs * j2
    xl = np.where(small, CF_SWITCH, x)
    r = 2.0 / (xl + np.sqrt(xl * xl + 4.0 * (CF_DEPTH + 2)))
    for j in range(CF_DEPTH, 2, -1):
        r = 1.0 / (xl + (j + 1) * r)
    r2 = 1.0 / (xl + 3.0 * r)
    r1 = 1.0 / (xl + 2.0 * r2)
    return (
        np.where(small, j1 / j0, r1),
        np.where(small, j2 / (2.0 * j1), r2),
        np.where(small, j3 / (3.0 * j2), r),
    )


def normal_loss_scaled(x: np.ndarray) -> np.ndarray:
    """J₁(x) = G(x)/φ(x) = 1 − x Q(x)/φ(x) for x >= 0, without cancellation."""
    r1, _, _ = mills_rho(x)
    x = np.maximum(np.asarray(x, np.float64), 0.0)
    return r1 / (x + r1)  # R = 1 / (x + ρ₁) and J₁ = R ρ₁


def normal_pdf(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, np.float64)
    return INV_SQRT_2PI * np.exp(-0.5 * x * x)


def lambda_smith(w, cov) -> np.ndarray:
    """Smith's Λ(ω) for Gaussian slopes N(·, Σ); w (..., 3) unit vectors, cov (..., 2, 2) or (..., 3)."""
    w = np.asarray(w, np.float64)
    sxx, sxy, syy = cov_parts(cov)
    q = w[..., 0] ** 2 * sxx + 2.0 * w[..., 0] * w[..., 1] * sxy + w[..., 1] ** 2 * syy  # (σ_s |w_xy|)²
    q, wz = np.broadcast_arrays(q, w[..., 2])
    ok = q > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        nu = np.where(ok, wz / np.sqrt(np.where(ok, q, 1.0)), 1.0)
    nu = np.maximum(nu, NU_MIN)
    lam = normal_pdf(nu) * normal_loss_scaled(nu) / nu
    return np.where(ok, lam, 0.0)


def height_cdf(h, sigma_h) -> np.ndarray:
    """P_h(h) = ½ erfc(−h / (√2 σ_h)), heights N(0, σ_h²)."""
    return ndtr(np.asarray(h, np.float64) / np.asarray(sigma_h, np.float64))


def visibility(h, sigma_h, lam) -> np.ndarray:
    """V(h, ω) = P_h(h)^Λ(ω) (eq. 2); 1 for Λ = 0."""
    p = height_cdf(h, sigma_h)
    lam = np.asarray(lam, np.float64)
    with np.errstate(divide="ignore"):
        return np.where(lam > 0.0, np.exp(lam * np.log(p)), 1.0)


def average_visibility(lam_o, lam_i) -> np.ndarray:
    """V̄ = (1 + Λ_o) / (1 + Λ_o + Λ_i), the closed form of eq. (12) (errata: p_h in the denominator)."""
    lam_o = np.asarray(lam_o, np.float64)
    return (1.0 + lam_o) / (1.0 + lam_o + np.asarray(lam_i, np.float64))


__all__ = [
    "ERFCX_COEFFS",
    "NU_MIN",
    "average_visibility",
    "cov_parts",
    "erfc_approx",
    "erfcx_approx",
    "fit_erfcx_coefficients",
    "height_cdf",
    "lambda_smith",
    "mills_rho",
    "normal_loss_scaled",
    "normal_pdf",
    "visibility",
]
