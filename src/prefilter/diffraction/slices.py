"""BRDF slices of a diffraction material: the shader's paths against a direct windowed reference.

The reference evaluates Stam's windowed transform directly, with no Taylor series and no DFT bins, for
height fields that vary across the grooves only (gratings: every row of the field equal). The Gaussian
coherence window exp(−(x² + y²)/(2σ²)), normalised by its integral, then separates:

    P̃(α, β; k w) = [Σ_j dx / (√(2π) σ) e^{−x_j²/(2σ²)} e^{i k w h(x_j)} e^{−i α x_j}] · e^{−σ² β² / 2},

a Riemann sum over the periodically tiled profile within ±WINDOW_SIGMAS σ. Its only errors are the
window's tail beyond that and aliases at α ± 2π/dx (≥ 125 rad/µm for 0.05 µm pixels, outside the
visible range |α| ≤ 2k ≤ 33). The reflectance is Stam's, as stam.glsl's df_geometry writes it:
F (G / w²) 2 cos²θ_i Σ_λ |P̃(k u, k v; k w)|² weight(λ) → XYZ → linear sRGB, at `step_nm` spectral steps.

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
    heights: np.ndarray, dx: float, sigma: float, uvw: np.ndarray, step_nm: float = 1.0
) -> np.ndarray:
    """XYZ of Σ_λ |P̃(k u, k v; k w)|² x weight(λ) per (u, v, w) row, from the direct windowed transform."""
    profile = grating_profile(heights)
    profile = profile - profile.mean()
    reach = int(math.ceil(WINDOW_SIGMAS * sigma / dx))
    j = np.arange(-reach, reach + 1)
    x = j * dx
    h = profile[j % profile.size]
    window = dx / (math.sqrt(2.0 * math.pi) * sigma) * np.exp(-(x**2) / (2.0 * sigma**2))
    uvw = np.asarray(uvw, np.float64)
    xyz = np.zeros((len(uvw), 3))
    wavelengths, weights = spectral_weights(step_nm)
    for lam, weight in zip(wavelengths, weights, strict=True):
        k = 2.0 * math.pi / lam
        alpha, beta, kw = k * uvw[:, 0], k * uvw[:, 1], k * uvw[:, 2]
        phase = kw[:, None] * h[None, :] - alpha[:, None] * x[None, :]
        p = (window[None, :] * np.exp(1j * phase)).sum(axis=1) * np.exp(-0.5 * (sigma * beta) ** 2)
        xyz += (np.abs(p) ** 2)[:, None] * weight
    return xyz


def direct_reflectance(
    heights: np.ndarray,
    dx: float,
    sigma: float,
    f0: float,
    wi: np.ndarray,
    wo: np.ndarray,
    step_nm: float = 1.0,
) -> np.ndarray:
    """Linear sRGB relative reflectance along the slice, from the direct windowed transform (header)."""
    uvw, gain = stam_geometry(wi, wo, f0)
    xyz = direct_power(heights, dx, sigma, uvw, step_nm)
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


def slice_study(material, angles=SLICE_ANGLES, step_nm: float = 1.0) -> dict | None:
    """Every shader path against the direct reference along in-plane slices; None for 2D structures.

    Errors per mode: the largest |difference| over the slice relative to the reference's peak, and the
    mean ΔE2000 over θ_o where the reference is brighter than 1 % of its peak (colours scaled by the peak).
    """
    from prefilter.metrics import delta_e2000_map

    s = material.structure
    try:
        grating_profile(s.heights)
    except PrefilterError:
        return None
    study: dict = {"angles": list(angles), "step_nm": step_nm, "slices": []}
    for theta_i in angles:
        wi, wo, theta_o = in_plane_slice(theta_i)
        reference = direct_reflectance(
            s.heights, s.pixel[0], material.coherence, material.f0, wi, wo, step_nm
        )
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
