"""Procedural clear-sky environment maps (sun + Preetham sky + Lambertian ground) for scenes/data/.

Usage:
    python scripts/make-sky.py                      # the two shipped maps, sky-low-sun.exr, sky-high-sun.exr
    python scripts/make-sky.py OUT.exr [--elevation 25 --azimuth 135 --turbidity 3 --albedo 0.2 ...]

Output: equirectangular float32 linear-RGB (Rec. 709 / sRGB primaries) EXR, 256 x 128 by default, in the
conventions of prefilter.microsurface.irradiance: world +z up, row i spans polar angle
θ ∈ [π i/H, π (i+1)/H] from the zenith (row 0 at the zenith, the horizon is the edge between rows H/2 − 1
and H/2), column j spans longitude φ ∈ [2π j/W, 2π (j+1)/W], φ = 0 at +x increasing towards +y,
ω = (sin θ cos φ, sin θ sin φ, cos θ). Units: kcd/m² (luminance, Preetham's zenith-luminance unit; each
channel is a radiance in those units), consistent with the sun's direct normal illuminance in klx. The
generator parameters and derived quantities are stored as JSON in the EXR header attribute `prefilter`
(prefilter.images.write_image). Fully deterministic (no random numbers).

Sun direction: s = (cos e cos a, cos e sin a, sin e) for elevation e and azimuth a (from +x towards +y).

Sky (upper hemisphere, θ < 90°): the Perez et al. 1993 all-weather distribution with the turbidity fits of
Preetham, Shirley & Smits 1999 ("A practical analytic model for daylight", appendix A.2), for the
luminance Y and the CIE chromaticities x, y alike:

    F(θ, γ) = (1 + A exp(B / cos θ)) (1 + C exp(D γ) + E cos² γ),
    Y(θ, γ) = Y_z F_Y(θ, γ) / F_Y(0, θ_s),   x = x_z F_x / F_x(0, θ_s),   y = y_z F_y / F_y(0, θ_s),

θ the view zenith angle, γ the angle between view and sun, θ_s = 90° − e the sun's zenith angle, T the
turbidity (haze: 2 very clear, 3 clear, 6 hazy, 10 thin fog; valid range 1.7–10 here):

         A                  B                  C                  D                  E
    Y:  0.1787T − 1.4630  −0.3554T + 0.4275  −0.0227T + 5.3251   0.1206T − 2.5771  −0.0670T + 0.3703
    x: −0.0193T − 0.2592  −0.0665T + 0.0008  −0.0004T + 0.2125  −0.0641T − 0.8989  −0.0033T + 0.0452
    y: −0.0167T − 0.2608  −0.0950T + 0.0092  −0.0079T + 0.2102  −0.0441T − 1.6537  −0.0109T + 0.0529

    Y_z = (4.0453T − 4.9710) tan χ − 0.2155T + 2.4192 [kcd/m²],   χ = (4/9 − T/120)(π − 2θ_s),
    x_z = [T² T 1] · M_x · [θ_s³ θ_s² θ_s 1]ᵀ,  y_z likewise (θ_s in radians), with
    M_x = [[0.00166, −0.00375, 0.00209, 0], [−0.02903, 0.06377, −0.03202, 0.00394],
           [0.11693, −0.21196, 0.06052, 0.25886]],
    M_y = [[0.00275, −0.00610, 0.00317, 0], [−0.04214, 0.08970, −0.04153, 0.00516],
           [0.15346, −0.26756, 0.06670, 0.26688]].

A < 0 and B < 0 make the sky brighten from zenith to horizon (factor 1 / (1 + A e^B) ≈ 2 at T = 3); the
C exp(Dγ) + E cos²γ term is the bright circumsolar aureole. (Y, x, y) → XYZ (X = xY/y, Z = (1 − x − y)Y/y)
→ linear sRGB (IEC 61966-2-1 matrix), clamped at 0. Each pixel is the solid-angle-weighted mean over
4 x 4 sub-cells of equal Δθ, Δφ.

Sun: direct normal illuminance per channel c, Beer–Lambert through the air mass of Kasten & Young 1989,

    E_c = E₀ exp(−m (τ_R(λ_c) + τ_a(λ_c))),   m = 1 / (cos θ_s + 0.50572 (96.07995 − θ_s[deg])^−1.6364),
    τ_R(λ) = 0.008569 λ⁻⁴ (1 + 0.0113 λ⁻² + 0.00013 λ⁻⁴)  (Rayleigh, sea level; λ in µm),
    τ_a(λ) = β λ^−1.3,  β = 0.04608T − 0.04586  (Ångström aerosol with Preetham's turbidity relation),

E₀ = 128 klx (extraterrestrial solar illuminance, taken white), λ_c = 0.61, 0.55, 0.465 µm (R, G, B);
ozone and water vapour absorption are ignored. The real disc (angular radius 0.27°, 6.9e-5 sr) is far
below a pixel (1.4°), so its power is spread over a disc of angular radius `spread` (default 1.5°, about
4 pixels): pixel p gets L_p = E_c f_p / Σ_q f_q Ω_q, f_p the fraction of the pixel's solid angle inside
that disc (16 x 16 sub-cells per pixel). Then Σ_p L_p Ω_p = E_c exactly: the sun's solid-angle-
integrated radiance (its power) is kept. The sun adds to the sky radiance below it.

Ground (lower hemisphere): a Lambertian plane of constant albedo ρ (default 0.2, grey) lit by the upper
half of the map: L_ground = ρ E_h / π, E_h = Σ_{upper pixels} L_p ∫_p cos θ dω (exact for the
piecewise-constant map; sky + sun). No horizon blur, no sky below the horizon.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from prefilter.images import write_image  # noqa: E402

DATA = ROOT / "src/prefilter/scenes/data"
PRESETS = {
    "sky-low-sun.exr": {"elevation": 12.0},
    "sky-high-sun.exr": {"elevation": 50.0},
}
DEFAULTS = {
    "elevation": 25.0,  # degrees above the horizon
    "azimuth": 135.0,  # degrees, from +x towards +y
    "turbidity": 3.0,
    "albedo": 0.2,
    "spread": 1.5,  # degrees, angular radius over which the sun's power is spread
    "height": 128,
}
SUN_RADIUS_DEG = 0.27
E0_KLX = 128.0
WAVELENGTHS_UM = np.array([0.61, 0.55, 0.465])
XYZ_TO_SRGB = np.array(
    [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ]
)
PEREZ = {  # (slope in T, intercept) for A..E
    "Y": [(0.1787, -1.4630), (-0.3554, 0.4275), (-0.0227, 5.3251), (0.1206, -2.5771), (-0.0670, 0.3703)],
    "x": [(-0.0193, -0.2592), (-0.0665, 0.0008), (-0.0004, 0.2125), (-0.0641, -0.8989), (-0.0033, 0.0452)],
    "y": [(-0.0167, -0.2608), (-0.0950, 0.0092), (-0.0079, 0.2102), (-0.0441, -1.6537), (-0.0109, 0.0529)],
}
ZENITH_X = np.array(
    [
        [0.00166, -0.00375, 0.00209, 0.0],
        [-0.02903, 0.06377, -0.03202, 0.00394],
        [0.11693, -0.21196, 0.06052, 0.25886],
    ]
)
ZENITH_Y = np.array(
    [
        [0.00275, -0.00610, 0.00317, 0.0],
        [-0.04214, 0.08970, -0.04153, 0.00516],
        [0.15346, -0.26756, 0.06670, 0.26688],
    ]
)


def perez(coeffs, cos_theta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    a, b, c, d, e = coeffs
    return (1.0 + a * np.exp(b / cos_theta)) * (1.0 + c * np.exp(d * gamma) + e * np.cos(gamma) ** 2)


def sky_xyz(dirs: np.ndarray, sun: np.ndarray, turbidity: float) -> np.ndarray:
    """Preetham sky as CIE XYZ (kcd/m²) for unit directions (..., 3) with z > 0."""
    t = turbidity
    theta_s = np.arccos(sun[2])
    cos_theta = dirs[..., 2]
    gamma = np.arccos(np.clip(dirs @ sun, -1.0, 1.0))
    chi = (4.0 / 9.0 - t / 120.0) * (np.pi - 2.0 * theta_s)
    zenith = {
        "Y": (4.0453 * t - 4.9710) * np.tan(chi) - 0.2155 * t + 2.4192,
        "x": np.array([t * t, t, 1.0]) @ ZENITH_X @ np.array([theta_s**3, theta_s**2, theta_s, 1.0]),
        "y": np.array([t * t, t, 1.0]) @ ZENITH_Y @ np.array([theta_s**3, theta_s**2, theta_s, 1.0]),
    }
    values = {}
    for key, table in PEREZ.items():
        coeffs = [slope * t + icpt for slope, icpt in table]
        values[key] = zenith[key] * perez(coeffs, cos_theta, gamma) / perez(coeffs, 1.0, theta_s)
    big_y, x, y = values["Y"], values["x"], values["y"]
    return np.stack([x * big_y / y, big_y, (1.0 - x - y) * big_y / y], axis=-1)


def air_mass(zenith_deg: float) -> float:
    """Kasten & Young 1989 relative optical air mass."""
    return 1.0 / (np.cos(np.radians(zenith_deg)) + 0.50572 * (96.07995 - zenith_deg) ** -1.6364)


def sun_illuminance(elevation: float, turbidity: float) -> np.ndarray:
    """Direct normal illuminance (klx) per RGB channel after Rayleigh and aerosol extinction."""
    lam = WAVELENGTHS_UM
    tau_r = 0.008569 * lam**-4 * (1.0 + 0.0113 * lam**-2 + 0.00013 * lam**-4)
    beta = 0.04608 * turbidity - 0.04586
    tau_a = beta * lam**-1.3
    return E0_KLX * np.exp(-air_mass(90.0 - elevation) * (tau_r + tau_a))


def cell_grid(h: int, w: int, rows: np.ndarray, s: int) -> tuple[np.ndarray, np.ndarray]:
    """Sub-cell directions (len(rows), s, w, s, 3) and solid angles (len(rows), s) of s x s sub-cells."""
    top = np.pi * rows / h
    theta_edges = top[:, None] + np.pi / h * np.arange(s + 1)[None] / s  # (r, s+1)
    theta = 0.5 * (theta_edges[:, :-1] + theta_edges[:, 1:])
    omega = (2.0 * np.pi / (w * s)) * (np.cos(theta_edges[:, :-1]) - np.cos(theta_edges[:, 1:]))
    phi = 2.0 * np.pi * (np.arange(w * s) + 0.5) / (w * s)
    st, ct = np.sin(theta)[:, :, None], np.cos(theta)[:, :, None]
    dirs = np.stack(np.broadcast_arrays(st * np.cos(phi), st * np.sin(phi), ct), axis=-1)  # (r, s, w*s, 3)
    return dirs.reshape(len(rows), s, w, s, 3), omega


def make_sky(elevation, azimuth, turbidity, albedo, spread, height) -> tuple[np.ndarray, dict]:
    if not 1.7 <= turbidity <= 10.0:
        raise ValueError("turbidity must lie in [1.7, 10] (Preetham's fits)")
    if not spread < elevation < 90.0 - spread:
        raise ValueError("the spread sun disc must lie above the horizon and off the zenith")
    h, w = int(height), 2 * int(height)
    if h % 2:
        raise ValueError("height must be even (the horizon is a row edge)")
    e, a = np.radians(elevation), np.radians(azimuth)
    sun = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    env = np.zeros((h, w, 3))
    upper = np.arange(h // 2)

    # Sky: pixel means over 4 x 4 sub-cells.
    s = 4
    dirs, omega = cell_grid(h, w, upper, s)
    rgb = np.clip(sky_xyz(dirs, sun, turbidity) @ XYZ_TO_SRGB.T, 0.0, None)
    env[: h // 2] = np.einsum("rawbc,ra->rwc", rgb, omega) / (omega.sum(axis=1)[:, None, None] * s)

    # Sun: its direct normal illuminance spread over a disc of angular radius `spread`.
    e_sun = sun_illuminance(elevation, turbidity)
    theta_s = np.pi / 2 - e
    reach = np.radians(spread) + np.pi / h
    rows = upper[(np.pi * (upper + 1) / h > theta_s - reach) & (np.pi * upper / h < theta_s + reach)]
    s = 16
    dirs, omega = cell_grid(h, w, rows, s)
    inside = (dirs @ sun) >= np.cos(np.radians(spread))
    covered = np.einsum("rawb,ra->rw", inside.astype(np.float64), omega)  # solid angle inside, per pixel
    sun_radiance = e_sun / covered.sum()
    env[rows] += covered[..., None] / (omega.sum(axis=1)[:, None, None] * s) * sun_radiance

    # Ground: Lambertian, lit by the upper hemisphere of the map itself.
    u = np.cos(np.pi * np.arange(h // 2 + 1) / h)
    cos_int = (2.0 * np.pi / w) * 0.5 * (u[:-1] ** 2 - u[1:] ** 2)  # ∫_pixel cos θ dω per upper row
    e_h = np.einsum("rwc,r->c", env[: h // 2], cos_int)
    env[h // 2 :] = albedo * e_h / np.pi

    row_omega = (2.0 * np.pi / w) * (
        np.cos(np.pi * np.arange(h) / h) - np.cos(np.pi * np.arange(1, h + 1) / h)
    )
    flux = np.einsum("rwc,r->c", env, row_omega)
    meta = {
        "generator": "scripts/make-sky.py",
        "model": "Preetham 1999 / Perez 1993 sky (XYZ -> linear sRGB), Kasten-Young air mass, Rayleigh + "
        "Angstrom extinction for the sun, Lambertian ground",
        "parameters": {
            "elevation_deg": elevation,
            "azimuth_deg": azimuth,
            "turbidity": turbidity,
            "ground_albedo": albedo,
            "sun_spread_deg": spread,
            "width": w,
            "height": h,
        },
        "units": "kcd/m^2 (sun: direct normal illuminance in klx spread over the disc)",
        "sun_direction": sun.round(9).tolist(),
        "sun_normal_illuminance_klx": e_sun.round(6).tolist(),
        "sun_physical_radiance": (e_sun / (2 * np.pi * (1 - np.cos(np.radians(SUN_RADIUS_DEG)))))
        .round(1)
        .tolist(),
        "horizontal_irradiance": e_h.round(6).tolist(),
        "sun_share_of_power": (e_sun / flux).round(6).tolist(),
        "convention": "equirect, row 0 zenith, world +z up, column j spans phi in 2 pi [j, j+1] / W, "
        "phi from +x towards +y",
    }
    return env, meta


def write(path: Path, **params) -> None:
    env, meta = make_sky(**{**DEFAULTS, **params})
    path = write_image(path, env.astype(np.float32), metadata=meta)
    lum = env @ np.array([0.2126, 0.7152, 0.0722])
    top = lum[: env.shape[0] // 2]
    print(
        f"{path}: {env.shape[1]}x{env.shape[0]}, sun {meta['sun_normal_illuminance_klx']} klx "
        f"(share of power {meta['sun_share_of_power']}), sky luminance zenith {top[0].mean():.2f} "
        f"horizon {top[-1].mean():.2f} kcd/m2, ground {lum[-1, 0]:.2f}, brightest pixel {lum.max():.0f}"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", nargs="?", type=Path, help="output .exr (default: write the shipped presets)")
    for key, value in DEFAULTS.items():
        parser.add_argument(f"--{key}", type=type(value), default=value)
    args = parser.parse_args(argv)
    if args.out is None:
        for name, preset in PRESETS.items():
            write(DATA / name, **preset)
    else:
        write(args.out, **{key: getattr(args, key) for key in DEFAULTS})


if __name__ == "__main__":
    main()
