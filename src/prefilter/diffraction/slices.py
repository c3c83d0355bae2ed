"""BRDF slices of a diffraction material: the shader's paths against a direct windowed reference.

The reference evaluates Stam's windowed transform directly, as a non-uniform DFT of e^{ikwh} with no
Taylor series and no DFT bins: a Riemann sum over the periodically tiled height field under the Gaussian
coherence window exp(−(x² + y²)/(2σ²)), normalised by its integral,

  P̃(α, β; k w) = Σ_{i,j} dx dy / (2π σ²) e^{−(x_j² + y_i²)/(2σ²)} e^{i k w h(x_j, y_i)} e^{−i(α x_j + β y_i)},

within ±WINDOW_SIGMAS σ. For height fields that vary across the grooves only (gratings, the CD: every
row equal) it separates into a 1D sum times e^{−σ² β² / 2}, cheap enough for 1 nm steps. For 2D fields
(the snakes) every direction and wavelength costs ~10⁵ exponentials, so slices use fewer directions and
coarser steps (SLICE_2D). Its only errors are the window's tail and aliases at α ± 2π/dx (≥ 125 rad/µm for
0.05 µm pixels, outside the visible range |α| ≤ 2k ≤ 33). The reflectance is Stam's, as stam.glsl's
df_geometry writes it: F (G / w²) 2 cos²θ_i Σ_λ |P̃(k u, k v; k w)|² weight(λ) → XYZ → linear sRGB.

Slices lie in the plane across the grooves: ω_i = (sin θ_i, 0, cos θ_i), ω_o = (sin θ_o, 0, cos θ_o).
"""

from __future__ import annotations

import math

import numpy as np

from prefilter import PrefilterError
from prefilter.diffraction.spectrum import spectral_weights, xyz_to_srgb

WINDOW_SIGMAS = 6.0  # e^{-18}: the window's weight beyond is below 1e-7 of its peak
SHADER_PATHS = {
    "point": "df_reflectance(wi, wo)",
    "fast": "df_fastReflectance(wi, wo)",
    "dhillon": "df_dhillonReflectance(wi, wo)",
    "naive": "df_analyticGrating(wi, wo, {period:.9g})",
}


def in_plane_slice(theta_i_deg: float, count: int = 357) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ω_i repeated, ω_o, θ_o in degrees) for θ_o over (−89°, 89°)."""
    theta_o = np.linspace(-89.0, 89.0, count)
    t = np.radians(theta_o)
    wo = np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], axis=1)
    ti = math.radians(theta_i_deg)
    wi = np.tile([math.sin(ti), 0.0, math.cos(ti)], (count, 1))
    return wi, wo, theta_o


def stam_geometry(wi: np.ndarray, wo: np.ndarray, f0: float) -> tuple[np.ndarray, np.ndarray]:
    """NumPy twin of df_geometry: (u, v, w) = k̂1 − k̂2 and the gain F (G / w²) 2 cos²θ_i."""
    k1, k2 = -wi, wo
    uvw = k1 - k2
    cos1, cos2 = np.maximum(wi[:, 2], 1e-4), np.maximum(wo[:, 2], 1e-4)
    g = (1.0 - np.sum(k1 * k2, axis=1)) / (cos1 * cos2)
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    fresnel = f0 + (1.0 - f0) * (1.0 - np.clip(np.sum(h * wo, axis=1), 0.0, 1.0)) ** 5
    return uvw, fresnel * g / np.maximum(uvw[:, 2] ** 2, 1e-8) * 2.0 * cos1**2


def grating_profile(heights: np.ndarray) -> np.ndarray:
    """The across-groove profile of a height field whose rows are all equal; PrefilterError otherwise."""
    heights = np.asarray(heights, np.float64)
    if not np.allclose(heights, heights[:1], atol=1e-9 * max(1.0, np.abs(heights).max())):
        raise PrefilterError("the direct slice reference needs a height field that varies along x only")
    return heights[0]


def direct_power(
    heights: np.ndarray, pixel, sigma: float, uvw: np.ndarray, step_nm: float = 1.0
) -> np.ndarray:
    """XYZ of Σ_λ |P̃(k u, k v; k w)|² x weight(λ) per (u, v, w) row, from the direct windowed transform;
    pixel = dx or (dx, dy) in µm."""
    dx, dy = (pixel, pixel) if np.isscalar(pixel) else pixel
    uvw = np.asarray(uvw, np.float64)
    try:
        profile = grating_profile(heights)
    except PrefilterError:
        return _direct_power_2d(np.asarray(heights, np.float64), dx, dy, sigma, uvw, step_nm)
    profile = profile - profile.mean()
    j, x, window = _window_axis(dx, sigma)
    h = profile[j % profile.size]
    xyz = np.zeros((len(uvw), 3))
    wavelengths, weights = spectral_weights(step_nm)
    for lam, weight in zip(wavelengths, weights, strict=True):
        k = 2.0 * math.pi / lam
        alpha, beta, kw = k * uvw[:, 0], k * uvw[:, 1], k * uvw[:, 2]
        phase = kw[:, None] * h[None, :] - alpha[:, None] * x[None, :]
        p = (window[None, :] * np.exp(1j * phase)).sum(axis=1) * np.exp(-0.5 * (sigma * beta) ** 2)
        xyz += (np.abs(p) ** 2)[:, None] * weight
    return xyz


def _window_axis(dx: float, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample indices j and positions x = j dx within ±WINDOW_SIGMAS σ, and the normalised 1D window there."""
    reach = int(math.ceil(WINDOW_SIGMAS * sigma / dx))
    j = np.arange(-reach, reach + 1)
    x = j * dx
    return j, x, dx / (math.sqrt(2.0 * math.pi) * sigma) * np.exp(-(x**2) / (2.0 * sigma**2))


def _direct_power_2d(heights, dx, dy, sigma, uvw, step_nm, chunk: int = 8) -> np.ndarray:
    """The 2D windowed sum, directions in chunks: e^{ikwh} over the window for each, then the separable
    window and Fourier factors on both sides, (w_y e^{−iβy})ᵀ E (w_x e^{−iαx})."""
    h = heights - heights.mean()
    rows, cols = h.shape
    jx, x, wx = _window_axis(dx, sigma)
    jy, y, wy = _window_axis(dy, sigma)
    patch = h[np.ix_(jy % rows, jx % cols)]  # the tiled field over the window, (Ny, Nx)
    xyz = np.zeros((len(uvw), 3))
    wavelengths, weights = spectral_weights(step_nm)
    for lam, weight in zip(wavelengths, weights, strict=True):
        k = 2.0 * math.pi / lam
        for start in range(0, len(uvw), chunk):
            alpha, beta, kw = (k * uvw[start : start + chunk, c] for c in range(3))
            field = np.exp(1j * kw[:, None, None] * patch[None])  # (D, Ny, Nx)
            ex = wx[None, :] * np.exp(-1j * alpha[:, None] * x[None, :])
            ey = wy[None, :] * np.exp(-1j * beta[:, None] * y[None, :])
            p = np.einsum("dy,dyx,dx->d", ey, field, ex, optimize=True)
            xyz[start : start + chunk] += (np.abs(p) ** 2)[:, None] * weight
    return xyz


def direct_reflectance(
    heights: np.ndarray,
    pixel,
    sigma: float,
    f0: float,
    wi: np.ndarray,
    wo: np.ndarray,
    step_nm: float = 1.0,
) -> np.ndarray:
    """Linear sRGB relative reflectance along the slice, from the direct windowed transform (header)."""
    uvw, gain = stam_geometry(wi, wo, f0)
    xyz = direct_power(heights, pixel, sigma, uvw, step_nm)
    return np.maximum(xyz_to_srgb(gain[:, None] * xyz), 0.0)


def shader_reflectances(
    material, wi: np.ndarray, wo: np.ndarray, modes: tuple[str, ...] = tuple(SHADER_PATHS)
) -> dict[str, np.ndarray]:
    """The material's GLSL paths along the slice (linear sRGB, before exposure), keyed by render mode."""
    from dataclasses import replace

    from prefilter.diffraction.material import dominant_period
    from prefilter.gl.context import gl_context
    from prefilter.gl.evaluate import glsl_eval

    if "fast" not in modes and "dhillon" not in modes:  # no need to bake the fast paths' tables
        material = replace(material, table_size=(2, 2, 2))
    resources = material.upload(gl_context(), None)
    try:
        period = dominant_period(material.structure)
        return {
            mode: glsl_eval(
                expr.format(period=period),
                {"wi": wi, "wo": wo},
                3,
                includes=("diffraction/stam.glsl",),
                defines=material.defines(None),
                uniforms=resources["uniforms"],
                textures=resources["textures"],
            )
            for mode, expr in SHADER_PATHS.items()
            if mode in modes
        }
    finally:
        material.release(resources)


SLICE_ANGLES = (0.0, 30.0, 60.0)  # θ_i of the slices that `prefilter compare` draws


SLICE_2D = (61, 10.0)  # directions per slice and spectral step (nm) of the reference for 2D height fields


def slice_study(material, angles=SLICE_ANGLES, step_nm: float = 1.0) -> dict | None:
    """Every shader path against the direct reference along in-plane slices (None for tiled patches,
    whose shader has no coherence window).

    Errors per mode: the largest |difference| over the slice relative to the reference's peak, and the
    mean ΔE2000 over θ_o where the reference is brighter than 1 % of its peak (colours scaled by the peak).
    Gratings get 357 directions at `step_nm`; 2D height fields SLICE_2D's fewer directions and coarser steps.
    """
    from prefilter.metrics import delta_e2000_map

    s = material.structure
    if material.tiles is not None:
        return None
    count = 357
    try:
        grating_profile(s.heights)
    except PrefilterError:
        count, step_nm = SLICE_2D
    study: dict = {"angles": list(angles), "step_nm": step_nm, "slices": []}
    for theta_i in angles:
        wi, wo, theta_o = in_plane_slice(theta_i, count)
        reference = direct_reflectance(s.heights, s.pixel, material.coherence, material.f0, wi, wo, step_nm)
        peak = float(reference.max())
        bright = reference @ np.array([0.2126, 0.7152, 0.0722]) > 0.01 * peak
        entry = {"theta_i": theta_i, "theta_o": theta_o, "reference": reference, "modes": {}, "errors": {}}
        for mode, value in shader_reflectances(material, wi, wo).items():
            delta_e = delta_e2000_map((value / peak)[None], (reference / peak)[None])[0]
            entry["modes"][mode] = value
            entry["errors"][mode] = {
                "max_relative": float(np.abs(value - reference).max() / peak),
                "mean_delta_e": float(delta_e[bright].mean()) if bright.any() else 0.0,
            }
        study["slices"].append(entry)
    return study


def write_slice_figure(study: dict, path) -> None:
    """Luminance along each slice (log scale), the reference in black, and each path's colours in a strip."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from prefilter.images import linear_to_srgb

    luminance = np.array([0.2126, 0.7152, 0.0722])
    slices = study["slices"]
    fig, axes = plt.subplots(
        2, len(slices), figsize=(5.2 * len(slices), 6.2), height_ratios=[3, 1], squeeze=False
    )
    for column, entry in enumerate(slices):
        ax, strip = axes[0, column], axes[1, column]
        theta_o, reference = entry["theta_o"], entry["reference"]
        peak = reference.max()
        ax.semilogy(
            theta_o,
            np.maximum(reference @ luminance, 1e-6),
            "k",
            lw=2.2,
            label=f"direct ({study['step_nm']:g} nm)",
        )
        for mode, value in entry["modes"].items():
            err = entry["errors"][mode]
            label = f"{mode}: max {err['max_relative']:.3f}, ΔE {err['mean_delta_e']:.1f}"
            ax.semilogy(theta_o, np.maximum(value @ luminance, 1e-6), lw=1.1, label=label)
        ax.set_ylim(max(float((reference @ luminance).max()) * 1e-4, 1e-7), None)
        ax.set_title(f"θ_i = {entry['theta_i']:g}°")
        ax.set_xlabel("θ_o (degrees, across the grooves)")
        ax.legend(fontsize=7)
        rows = [reference] + list(entry["modes"].values())
        image = np.stack([np.repeat(r[None] / peak, 8, axis=0) for r in rows]).reshape(-1, len(theta_o), 3)
        strip.imshow(
            linear_to_srgb(np.clip(image, 0, 1)),
            aspect="auto",
            extent=(theta_o[0], theta_o[-1], len(rows), 0),
        )
        strip.set_yticks(np.arange(len(rows)) + 0.5, ["direct", *entry["modes"]])
    axes[0, 0].set_ylabel("relative reflectance (luminance)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
