"""Smith's masking for multi-octave fractal height fields: an effective slope variance, by ray casting.

Smith's Λ (Heitz et al. 2014 eq. 3) depends on the slope covariance Σ of the whole surface. On a Perlin
fBm whose octaves all carry similar slopes but ever smaller heights, Σ is dominated by the fine octaves,
and Smith then counts their many small up-crossings of a grazing ray as independent chances to block it.
They are not: a fine octave's bumps ride on the coarser hills and block a ray in clusters. Ray casting
the terrain presets' fractal (6 octaves, gain 0.5) gives a mean visible height of 0.999 σ_h at 3°
elevation and 0.386 σ_h at 10°, where Smith predicts 1.131 and 0.493; for one octave Smith is within
0.03 σ_h. On the rendered surfaces this bias was the largest error left: far terrain 9 % too bright under
ambient light, as too many of the white peaks were taken to be visible.

The model (beyond the paper): Λ is computed from an effective slope covariance

    Σ_eff = Σ_k g(log2(f_k / f_0)) Σ_k,

octave k's own slope covariance Σ_k weighted by G, a function of how many octaves (in factors of two
of frequency) it lies below the coarsest one. G was fitted by least squares to the effective Σ that makes
Smith's mean visible height equal the ray-cast one (`calibrate`): fractals of 1-6 octaves, lacunarity 2,
gains 0.35, 0.5 and 0.7, view elevations 3-20°. The ratio Σ_eff/Σ that matches each case does not
depend on the elevation (within the ray casts' noise), and one G fits all gains. Fine octaves keep
about 0.2 of their slopes. tests/test_microsurface.py checks the model against a fresh ray cast of a
fractal that was not fitted (gain 0.6, 5 octaves). The shader reads g(log2(f_k / f_0)) per octave
(`masking_uniform`, ms_octaveMasking in heightfield.glsl), G interpolated linearly between its entries.
Limits: measured for Perlin fBm with lacunarity 2 only, and for masking only; shadowing (Λ_i) uses the
same Σ_eff.

The visible slopes lean further towards the eye than D_s (visible_slopes.py) says. D_s is Smith's,
∝ (o·m)⁺ D(m): its masking does not depend on the facet. On the fBm a fine facet on the far side of a
coarse hill is masked by that hill more often than one on its near side. Ray cast (`visible_slope_mean`,
6000 rays), the terrain fractal's (6 octaves, gain 0.5) mean visible slope along the view is 0.733, 0.710,
0.656, 0.542 and 0.342 at 3°, 5°, 10°, 20° and 40° elevation, where D_s gives 0.665, 0.646, 0.599, 0.509
and 0.336: its shift is short by 10 % at grazing views and right at 40°. One octave is short by 3–7 %.
`slope_lean` scales the shift by 1 + 0.12 (1 − sin e / sin 40°)⁺, the least-squares fit to the 6-octave
ratios (the shader: MS_SLOPE_LEAN in microsurface.frag, the same constants); tests/test_microsurface.py
checks it against a fresh ray cast of a fractal it was not fitted to. The shader scales the extra lean by
the share of the height variance left to the statistics (the coarse hills' masking is rendered where they
are geometry). On the renders it took the far rows of the irradiance terrain, which were too bright by up
to 0.008, to within 0.004 of the reference (docs/microsurface-history.md).

`visible_height_mean` is the oracle: rays at a given elevation cross the macro plane at uniform points
(the projected-area weighting of pixels), are marched in steps of 0.12 of the finest lattice cell and
bisected to the first hit; the mean hit height over the heights' deviation is returned.

Run `python -m prefilter.microsurface.fractal_masking` to repeat the calibration (about three minutes).
"""

from __future__ import annotations

import sys

import numpy as np

from prefilter.microsurface.height_filtering import height_filtering_moments
from prefilter.microsurface.heightfield import MAX_OCTAVES, Fractal
from prefilter.microsurface.smith import lambda_smith
from prefilter.microsurface.visible_slopes import visible_slope_moments

# g(k) for k = log2(f_k / f_0) = 0, 1, ..., 7 (fitted by `calibrate`; k >= 4 share one weight)
G = np.array([1.110, 0.935, 0.758, 0.470, 0.204, 0.204, 0.204, 0.204])
# The visible slopes' lean (slope_lean): the extra share of D_s's mean shift at a grazing view, fading
# linearly in sin(elevation) to none at SLOPE_LEAN_FADE_DEG (least squares on ray casts, module header).
SLOPE_LEAN = 0.12
SLOPE_LEAN_FADE_DEG = 40.0

CALIBRATION = [  # (gain, octaves, view elevations in degrees)
    (0.5, 1, (3.0, 10.0, 20.0)),
    (0.5, 2, (3.0, 10.0, 20.0)),
    (0.5, 3, (3.0, 10.0, 20.0)),
    (0.5, 4, (3.0, 10.0, 20.0)),
    (0.5, 5, (5.0, 15.0)),
    (0.5, 6, (3.0, 10.0, 20.0)),
    (0.35, 2, (5.0, 15.0)),
    (0.35, 3, (5.0, 15.0)),
    (0.35, 4, (5.0, 15.0)),
    (0.7, 2, (5.0, 15.0)),
    (0.7, 3, (5.0, 15.0)),
    (0.7, 4, (5.0, 15.0)),
    (0.7, 6, (5.0, 15.0)),
]


def masking_weights(fractal: Fractal, table: np.ndarray = G) -> np.ndarray:
    """g(log2(f_k / f_0)) for each octave of the fractal."""
    k = np.log2(fractal.frequencies / fractal.frequencies[0])
    return np.interp(k, np.arange(len(table)), table)


def masking_uniform(fractal: Fractal) -> np.ndarray:
    """ms_octaveMasking: the octaves' masking weights, padded with zeros to MAX_OCTAVES (float32)."""
    weights = np.zeros(MAX_OCTAVES, np.float32)
    weights[: fractal.octaves] = masking_weights(fractal)
    return weights


def effective_slope_variance(
    fractal: Fractal, weights: np.ndarray | None = None, table: np.ndarray = G
) -> float:
    """Per-axis Σ_eff of the octaves scaled by `weights` (all of them by default)."""
    w = np.ones(fractal.octaves) if weights is None else np.asarray(weights, float)
    return fractal.slope_variance(w * w * masking_weights(fractal, table))


def slope_lean(elevation_deg):
    """The factor on D_s's mean shift (visible_slopes.py) for the fBm's visible slopes (module header)."""
    fade = np.sin(np.radians(elevation_deg)) / np.sin(np.radians(SLOPE_LEAN_FADE_DEG))
    return 1.0 + SLOPE_LEAN * np.maximum(1.0 - fade, 0.0)


def visible_height_mean(fractal: Fractal, elevation_deg: float, rays: int = 6000, seed: int = 0) -> float:
    """Mean height, in units of σ_h, of the first hits of parallel rays at `elevation_deg` on the plane."""
    hits = first_hits(fractal, elevation_deg, rays, seed)
    return float(np.mean(fractal.value(hits)) / np.sqrt(fractal.variance()))


def visible_slope_mean(fractal: Fractal, elevation_deg: float, rays: int = 6000, seed: int = 0) -> float:
    """Mean slope along the view (rising away from the eye: facing it) of those first hits."""
    return float(np.mean(fractal.gradient(first_hits(fractal, elevation_deg, rays, seed))[:, 0]))


def smith_visible_slope_mean(fractal: Fractal, elevation_deg: float, lean: float = 1.0) -> float:
    """D_s's mean slope along the view for the fractal's slope covariance, its shift times `lean`."""
    e = np.radians(elevation_deg)
    variance = fractal.slope_variance()
    wo = np.array([-np.cos(e), 0.0, np.sin(e)])  # towards the eye, in the tangent frame (x, z, y up)
    mean, _ = visible_slope_moments(wo, np.zeros(2), np.array([variance, 0.0, variance]))
    return float(lean * mean[0])


def first_hits(fractal: Fractal, elevation_deg: float, rays: int = 6000, seed: int = 0) -> np.ndarray:
    """First hits (rays, 3) of parallel rays at `elevation_deg` along +x that cross the plane uniformly."""
    rng = np.random.default_rng(seed)
    bound = float(np.sum(fractal.amplitudes))
    step = 0.12 / fractal.frequencies[-1]
    elevation = np.radians(elevation_deg)
    d = np.array([np.cos(elevation), -np.sin(elevation)])  # along x, down

    def height(x, z):
        return fractal.value(np.stack([x, np.zeros_like(x), z], axis=-1))

    x0 = rng.uniform(0.0, 40.0, rays) - bound / np.tan(elevation)  # cross y = 0 uniformly over [0, 40]
    z = rng.uniform(0.0, 40.0, rays)
    t = np.zeros(rays)
    hit = np.full(rays, np.nan)
    alive = np.ones(rays, bool)
    while alive.any():
        idx = np.nonzero(alive)[0]
        t[idx] += step
        y = bound + t[idx] * d[1]
        below = y < height(x0[idx] + t[idx] * d[0], z[idx])
        hit[idx[below]] = t[idx[below]]
        alive[idx[below | (y < -bound)]] = False
    lo, hi = hit - step, hit.copy()
    for _ in range(16):
        mid = 0.5 * (lo + hi)
        below = bound + mid * d[1] < height(x0 + mid * d[0], z)
        hi, lo = np.where(below, mid, hi), np.where(below, lo, mid)
    return np.stack([x0 + hi * d[0], np.zeros_like(z), z], axis=-1)


def smith_visible_height_mean(fractal: Fractal, elevation_deg: float, slope_variance: float) -> float:
    """Smith's mean visible height (μ_d of D_h, Λ_o only) in units of σ_h for a per-axis slope variance."""
    e = np.radians(elevation_deg)
    lam = lambda_smith(np.array([np.cos(e), 0.0, np.sin(e)]), np.array([slope_variance, 0.0, slope_variance]))
    return float(height_filtering_moments(np.asarray(lam))[0])


def calibrate(rays: int = 6000) -> np.ndarray:
    """Ray-cast every CALIBRATION case, invert Smith for the Σ_eff/Σ that matches it and fit G."""
    from scipy.optimize import brentq, least_squares

    cases = []
    for gain, octaves, elevations in CALIBRATION:
        fractal = Fractal(octaves=octaves, amplitude=0.16, frequency=2.0, gain=gain)
        total = fractal.slope_variance()
        for elevation in elevations:
            real = visible_height_mean(fractal, elevation, rays)
            smith = smith_visible_height_mean(fractal, elevation, total)
            if real <= smith_visible_height_mean(fractal, elevation, 1e-4 * total):
                print(f"gain {gain} octaves {octaves} elevation {elevation:4.1f}°: {real:.3f} σ_h, noise")
                continue
            ratio = brentq(
                lambda r, f=fractal, e=elevation, s=total, v=real: smith_visible_height_mean(f, e, r * s) - v,
                1e-4,
                50.0,
            )
            print(
                f"gain {gain} octaves {octaves} elevation {elevation:4.1f}°: ray cast {real:.3f} σ_h, "
                f"Smith {smith:.3f}; Σ_eff/Σ {ratio:.3f}",
                flush=True,
            )
            cases.append((fractal, real, ratio))

    def table(x):
        return np.concatenate([x[:4], np.full(len(G) - 4, x[4])])

    def residual(x):  # weighted by the size of the shift: small shifts pin the ratio down poorly
        return [
            (effective_slope_variance(f, table=table(x)) / f.slope_variance() - ratio) * real / 0.02
            for f, real, ratio in cases
        ]

    return table(least_squares(residual, np.ones(5), bounds=(0.0, 2.0)).x)


def main() -> int:
    fitted = calibrate()
    print("G =", np.array2string(fitted, precision=3, separator=", "))
    return 0


if __name__ == "__main__":
    sys.exit(main())
