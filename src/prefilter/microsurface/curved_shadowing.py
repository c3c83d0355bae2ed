"""Smith's shadowing of micro relief on a sphere: the light's elevation as the curving surface raises it.

Heitz et al. 2014 eq. 2 take the shadowing of a plane: a ray that leaves a point at height h with slope μ
over the macro surface keeps that slope, and G1 = P_h(h)^Λ(μ) vanishes at and below the horizon. Over a
sphere of radius R the macro surface falls away beneath the ray: its altitude is h + μt + t²/2R and its
slope relative to the surface grows as μ + t/R. Relief of height deviation σ shadows a ray over the first
stretch that it climbs by about σ, so the slope that counts is raised there. Solving μ_e = μ + σ k / (R μ_e)
for that slope gives (beyond the paper)

    μ_e = (μ⁺ + sqrt(μ⁺² + 4kσ/R)) / 2,

which is μ far above the horizon and sqrt(kσ/R) at it. Below the horizon (μ < 0) the ray first dives by
μ²R/2 under its start before it climbs, and the relief must clear that dive too: the visibility at μ = 0
is multiplied by exp(−μ²R / 2bσ). Λ(μ_e) then enters V̄ (eq. 12) and D_h's moments as Λ(ω_i) did.

k and b were fitted by least squares (`calibrate`) to a ray-cast oracle (`lit_fraction`): shadow rays from
random points of a Perlin fBm, lifted by t²/2R as they go, their lit fraction weighted by each point's
cosine to the light. Plane Smith and the ray cast differ even on the plane (Smith's lit fraction is 7–16 %
too high at 2–17° on these fractals: Σ_eff, fractal_masking.py, was fitted to the visible heights, not to
shadows), so the model is fitted through the plane ray cast's ratio to Smith on each fractal (its `bias`),
and only curvature is modelled here. Over four fractals (σ_h 0.00125–0.0037, R 0.4 and 1, μ from −0.08 to
0.15) the oracle's RMS difference from the model is 0.026, from plane Smith 0.112.
tests/test_microsurface_stats.py checks the model against a fresh ray cast of a fractal that was not
fitted; microsurface.frag (`ms_curvedLight`) uses it for Gaussian reliefs on spheres, where it brought the
height sphere's terminator closer to the reference's far away (FLIP 0.0596 → 0.0552 at 24 units, 0.0549 →
0.0527 at 10; docs/microsurface.md).

Run `python -m prefilter.microsurface.curved_shadowing` to repeat the calibration (about a minute).
"""

from __future__ import annotations

import sys

import numpy as np

from prefilter.microsurface.fractal_masking import effective_slope_variance
from prefilter.microsurface.heightfield import Fractal
from prefilter.microsurface.smith import average_visibility, lambda_smith

CURVED_ELEVATION = 0.45  # k
CURVED_DESCENT = 0.22  # b
# (octaves, amplitude, frequency, radius) of the fractals the constants were fitted to (gain 0.5)
CALIBRATION = ((5, 0.008, 40.0, 1.0), (4, 0.012, 24.0, 1.0), (5, 0.008, 40.0, 0.4), (6, 0.004, 60.0, 1.0))
CALIBRATION_SLOPES = (-0.08, -0.05, -0.03, -0.015, 0.0, 0.02, 0.04, 0.08, 0.15)


def curved_elevation(mu, sigma: float, radius: float, k: float = CURVED_ELEVATION):
    """μ_e: the slope of a ray over relief of height deviation sigma on a sphere of this radius (μ⁺ used)."""
    m = np.maximum(np.asarray(mu, float), 0.0)
    return 0.5 * (m + np.sqrt(m * m + 4.0 * k * sigma / radius))


def descent_factor(mu, sigma: float, radius: float, b: float = CURVED_DESCENT):
    """The share of the light that clears a ray's dive below the horizon (1 at and above it)."""
    m = np.minimum(np.asarray(mu, float), 0.0)
    return np.exp(-m * m * radius / (2.0 * b * sigma))


def smith_lit_fraction(mu, slope_variance: float) -> np.ndarray:
    """Plane Smith: V̄ = 1 / (1 + Λ(μ)), isotropic slopes (eq. 12, Λ_o = 0; 0 at and below the horizon)."""
    mu = np.atleast_1d(np.asarray(mu, float))
    e = np.arctan(np.maximum(mu, 0.0))
    w = np.stack([np.cos(e), np.zeros_like(e), np.sin(e)], axis=-1)
    lam = lambda_smith(w, np.array([slope_variance, 0.0, slope_variance]))
    return np.where(mu > 0.0, average_visibility(0.0, lam), 0.0)


def curved_lit_fraction(
    mu, fractal: Fractal, radius: float, k: float = CURVED_ELEVATION, b: float = CURVED_DESCENT
) -> np.ndarray:
    """The model: plane Smith at μ_e, times the descent factor (Σ_eff as the shader's Λ uses)."""
    sigma = float(np.sqrt(fractal.variance()))
    plane = smith_lit_fraction(curved_elevation(mu, sigma, radius, k), effective_slope_variance(fractal))
    return plane * descent_factor(mu, sigma, radius, b)


def lit_fraction(fractal: Fractal, radius: float, mu: float, points: int = 3000, seed: int = 0) -> float:
    """The oracle: shadow rays at slope mu along +x from random points of the fractal on the plane y = 0,
    their altitude lifted by t²/2R (radius = inf: the plane), marched in steps of 0.12 of the finest
    lattice cell until they clear the relief's bound; the lit share weighted by each point's cos⁺ to the
    light (what a Lambertian facet shows)."""
    rng = np.random.default_rng(seed)
    bound = float(np.sum(fractal.amplitudes))
    step = 0.12 / fractal.frequencies[-1]
    x, z = rng.uniform(0.0, 40.0, points), rng.uniform(0.0, 40.0, points)

    def height(xs, zs):
        return fractal.value(np.stack([xs, np.zeros_like(xs), zs], axis=-1))

    start = height(x, z)
    curvature = 0.0 if np.isinf(radius) else 1.0 / (2.0 * radius)
    lit = np.ones(points, bool)
    alive = np.ones(points, bool)
    t = np.zeros(points)
    while alive.any():
        i = np.nonzero(alive)[0]
        t[i] += step
        altitude = start[i] + 1e-6 + mu * t[i] + curvature * t[i] ** 2
        blocked = altitude < height(x[i] + t[i], z[i])
        lit[i[blocked]] = False
        alive[i[blocked | (altitude > bound)]] = False
    gradient = fractal.gradient(np.stack([x, np.zeros_like(x), z], axis=-1))
    normal = np.stack([-gradient[:, 0], np.ones(points), -gradient[:, 2]], axis=-1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    e = np.arctan(mu)
    cosine = np.maximum(normal @ np.array([np.cos(e), np.sin(e), 0.0]), 0.0)
    return float((cosine * lit).sum() / max(cosine.sum(), 1e-30))


def plane_bias(fractal: Fractal, slopes=(0.02, 0.04, 0.08, 0.15), points: int = 3000) -> float:
    """The plane ray cast's lit fraction over plane Smith's, averaged over slopes above the horizon."""
    cast = np.array([lit_fraction(fractal, np.inf, m, points) for m in slopes])
    return float(np.mean(cast / smith_lit_fraction(slopes, effective_slope_variance(fractal))))


def calibrate(points: int = 3000) -> tuple[float, float, float, float]:
    """Fit (k, b) over CALIBRATION; returns (k, b, RMS of the model, RMS of plane Smith), both with bias."""
    from scipy.optimize import least_squares

    cases, casts = [], []
    for octaves, amplitude, frequency, radius in CALIBRATION:
        fractal = Fractal(octaves=octaves, amplitude=amplitude, frequency=frequency, gain=0.5)
        bias = plane_bias(fractal, points=points)
        for mu in CALIBRATION_SLOPES:
            cases.append((fractal, radius, mu, bias))
            casts.append(lit_fraction(fractal, radius, mu, points))

    def residuals(p):
        return [bias * curved_lit_fraction(mu, f, r, *p)[0] for f, r, mu, bias in cases] - np.array(casts)

    fit = least_squares(residuals, [0.3, 0.3], bounds=([1e-3, 1e-3], [10.0, 10.0]))
    plane = [bias * smith_lit_fraction(mu, effective_slope_variance(f))[0] for f, _, mu, bias in cases]
    rms, rms_plane = np.sqrt(np.mean(fit.fun**2)), np.sqrt(np.mean((np.array(plane) - casts) ** 2))
    return float(fit.x[0]), float(fit.x[1]), float(rms), float(rms_plane)


def main() -> int:
    k, b, rms, plane = calibrate()
    print(f"k = {k:.3f}, b = {b:.3f}: RMS {rms:.4f} against the ray cast (plane Smith {plane:.4f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
