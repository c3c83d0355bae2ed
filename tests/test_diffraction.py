"""Diffraction at run time: the GLSL transform and reflectance against the NumPy bake and closed forms."""

import dataclasses
import math

import moderngl
import numpy as np
import pytest

from prefilter.diffraction.nanostructure import Nanostructure, generate
from prefilter.diffraction.spectrum import spectral_weights, xyz_to_srgb
from prefilter.diffraction.transform import taylor_terms
from prefilter.gl.context import gl_context
from prefilter.gl.evaluate import glsl_eval
from prefilter.gl.render import Renderer
from prefilter.scene import SceneError, parse_scene

INCLUDES = ("diffraction/stam.glsl",)


def _textures(terms, step_nm=5.0):
    ctx = gl_context()
    c = terms.coefficients.astype(np.complex64)
    layers, h, w = c.shape
    data = np.ascontiguousarray(np.stack([c.real, c.imag], axis=-1).astype(np.float32))
    table = ctx.texture_array((w, h, layers), 2, data.tobytes(), dtype="f4")
    table.filter = (moderngl.NEAREST, moderngl.NEAREST)
    wavelengths, weights = spectral_weights(step_nm)
    spectrum = np.concatenate([weights, wavelengths[:, None]], axis=1).astype(np.float32)
    spectrum_tex = ctx.texture((len(wavelengths), 1), 4, spectrum.tobytes(), dtype="f4")
    spectrum_tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    dx, dy = terms.pixel
    uniforms = {
        "df_bins": (2 * math.pi / (w * dx), 2 * math.pi / (h * dy), float(w), float(h)),
        "df_sigma": float(terms.sigma),
        "df_order": int(terms.order),
        "df_wavelengths": len(wavelengths),
        "df_f0": 1.0,
    }
    return {"df_terms": table, "df_spectrum": spectrum_tex}, uniforms, (wavelengths, weights)


def test_glsl_taylor_transform_equals_the_bake():
    structure = generate("sinusoidal", period=1.6, amplitude=0.1, periods=8, pixel=0.05)
    terms = taylor_terms(structure.heights, structure.pixel, sigma=4.0)
    textures, uniforms, _ = _textures(terms)
    rng = np.random.default_rng(4)
    k = 2 * np.pi / rng.uniform(0.38, 0.78, 64)
    u, v, w = rng.uniform(-1.5, 1.5, 64), rng.uniform(-0.2, 0.2, 64), -rng.uniform(0.5, 2.0, 64)
    got = glsl_eval(
        "df_transform(a, b, kw)",
        {"a": k * u, "b": k * v, "kw": k * w},
        2,
        includes=INCLUDES,
        uniforms=uniforms,
        textures=textures,
    )
    expected = terms.evaluate(k * u, k * v, k * w, stencil=1)  # the shader reads the 2 x 2 nearest bins
    np.testing.assert_allclose(got[:, 0] + 1j * got[:, 1], expected, atol=2e-4)
    for t in textures.values():
        t.release()


def _flat_mirror(theta_deg, offset, sigma=65 / 4, defines=None, uniforms=None):
    """GLSL reflectance of a flat surface lit from θ_i: (in the mirror direction, `offset` rad away)."""
    flat = Nanostructure(np.zeros((32, 32)), (0.05, 0.05), "flat")
    textures, base, _ = _textures(taylor_terms(flat.heights, flat.pixel, sigma=sigma))
    theta = np.radians(theta_deg)
    wi = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], 1)
    mirror = wi * [-1, -1, 1]
    off = np.stack([-np.sin(theta + offset), np.zeros_like(theta), np.cos(theta + offset)], 1)
    try:
        got = glsl_eval(
            "df_reflectance(wi, wo)",
            {"wi": np.concatenate([wi, wi]), "wo": np.concatenate([mirror, off])},
            3,
            includes=INCLUDES,
            defines=defines,
            uniforms={**base, **(uniforms or {})},
            textures=textures,
        )
    finally:
        for t in textures.values():
            t.release()
    return got[: len(theta)], got[len(theta) :]


def test_flat_mirror_is_white_in_the_specular_direction_and_dark_away_from_it():
    mirror, off = _flat_mirror([0.0, 20.0, 50.0, 70.0], 0.2, sigma=10.0)
    np.testing.assert_allclose(mirror, 1.0, atol=2e-3)  # D65 white through XYZ -> sRGB
    assert off.max() < 1e-6


def test_glsl_reflectance_of_a_grating_equals_stams_formula_summed_over_the_spectrum():
    """R = F (G / w²) 2 cos²θ1 Σ_λ |P̃|² weights(λ), with G from Stam's eq. (7), along the first order."""
    structure = generate("sinusoidal", period=1.6, amplitude=0.08, periods=8, pixel=0.05)
    terms = taylor_terms(structure.heights, structure.pixel, sigma=4.0)
    textures, uniforms, (wavelengths, weights) = _textures(terms, step_nm=10.0)
    theta_i = np.radians(30.0)
    wi = np.array([np.sin(theta_i), 0.0, np.cos(theta_i)])
    theta_o = np.radians(np.linspace(-80, 80, 41))
    wo = np.stack([np.sin(theta_o), np.zeros_like(theta_o), np.cos(theta_o)], 1)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    got = glsl_eval(
        "df_reflectance(wi, wo)",
        {"wi": np.tile(wi, (len(wo), 1)), "wo": wo},
        3,
        includes=INCLUDES,
        uniforms=uniforms,
        textures=textures,
    )
    k1, k2 = -wi, wo
    uvw = k1 - k2
    g = (1 - k2 @ k1) / (wi[2] * wo[:, 2])
    gain = g / uvw[:, 2] ** 2 * 2 * wi[2] ** 2
    xyz = np.zeros((len(wo), 3))
    for lam, wt in zip(wavelengths, weights, strict=True):
        k = 2 * np.pi / lam
        p = terms.evaluate(k * uvw[:, 0], k * uvw[:, 1], k * uvw[:, 2], stencil=1)
        xyz += np.abs(p)[:, None] ** 2 * wt
    expected = np.maximum(xyz_to_srgb(gain[:, None] * xyz), 0.0)
    assert expected.max() > 0.01
    np.testing.assert_allclose(got, expected, atol=2e-3 * expected.max() + 1e-6)
    for t in textures.values():
        t.release()


def _scene(material: str, light="direction = [0.3, 0.8, 0.2]\ndirection_end = [-0.3, 0.8, 0.2]"):
    text = f"""
size = [48, 32]
[camera]
eye = [0.0, 1.5, 1.5]
target = [0.0, 0.0, 0.0]
[[light]]
{light}
[[object]]
shape = "plane"
[object.material]
type = "diffraction"
{material}
"""
    return parse_scene(text, "test.toml", ".")


def test_scene_renders_every_mode_and_the_light_moves():
    scene = _scene('[object.material.generator]\nname = "sinusoidal"\nperiods = 4')
    assert np.allclose(
        scene.lights[0].at(1.0).direction, np.array([-0.3, 0.8, 0.2]) / np.linalg.norm([-0.3, 0.8, 0.2])
    )
    renderer = Renderer(scene)
    try:
        for mode in ("point", "naive", "blinn-phong"):
            image = renderer.render(mode)
            assert np.isfinite(image).all()
    finally:
        renderer.release()


@pytest.mark.parametrize(
    "material, message",
    [
        ("", "needs structure"),
        ('[object.material.generator]\nname = "opal"', "opal"),
        ('structure = "missing.npy"\npixel_um = 0.05', "structure: file not found"),
        ('grooves = "spiral"\n[object.material.generator]\nname = "blazed"', "grooves: expected one of"),
    ],
)
def test_bad_diffraction_materials_name_the_key(material, message):
    with pytest.raises(SceneError) as info:
        _scene(material)
    assert message in str(info.value) and "test.toml" in str(info.value)


def test_coarse_height_fields_are_rejected(tmp_path):
    np.save(tmp_path / "coarse.npy", np.zeros((16, 16)))
    text = f'structure = "{tmp_path / "coarse.npy"}"\npixel_um = 0.2'
    with pytest.raises(SceneError, match="too coarse"):
        _scene(text)


@pytest.mark.parametrize("mode", ["fast", "dhillon"])
def test_fast_paths_agree_with_the_accurate_path_within_delta_e_1(mode):
    from prefilter.gl.render import composite, coverage_mask
    from prefilter.metrics import compare

    scene = _scene(
        "coherence_um = 3.0\nfast_table = [128, 128, 24]\n"
        '[object.material.generator]\nname = "blazed"\nperiods = 4',
        light="direction = [0.25, 0.55, -0.8]",
    )
    renderer = Renderer(scene)
    try:
        rgba = {m: renderer.render(m) for m in ("point", mode)}
    finally:
        renderer.release()
    mask = coverage_mask(rgba["point"])
    point, fast = (composite(rgba[m], scene.background) for m in ("point", mode))
    assert point.max() > 0.05  # the orders are in view
    scores = compare(fast, point, mask)
    assert scores["delta_e"] <= 1.0, scores


def test_glsl_periodic_factor_equals_the_brute_force_sum_including_its_singular_points():
    from prefilter.diffraction.transform import periodic_factor

    rng = np.random.default_rng(9)
    counts = rng.integers(1, 40, 300).astype(float)
    phase = np.concatenate(
        [rng.uniform(-30, 30, 200), 2 * np.pi * rng.integers(-4, 5, 100) + rng.normal(0, 1e-4, 100)]
    )
    got = glsl_eval(
        "df_periodicFactor(p, n)",
        {"p": phase, "n": counts},
        1,
        includes=INCLUDES,
        defines={"DF_TILING": True},
    ).ravel()
    brute = np.array(
        [
            abs(np.exp(-1j * p * np.arange(int(n))).sum()) ** 2 / n**2
            for p, n in zip(phase, counts, strict=True)
        ]
    )
    np.testing.assert_allclose(got, brute, atol=2e-4)
    bake = np.array([periodic_factor(p, 1.0, int(n)) / n**2 for p, n in zip(phase, counts, strict=True)])
    np.testing.assert_allclose(bake, brute, atol=1e-9)


def test_tiled_flat_mirror_is_white_in_the_specular_direction_and_dark_between_orders():
    tiled = {"defines": {"DF_TILING": True}, "uniforms": {"df_tiles": (40.0, 40.0)}}
    mirror, off = _flat_mirror([0.0, 30.0, 60.0], 0.05, **tiled)
    np.testing.assert_allclose(mirror, 1.0, atol=2e-3)
    assert off.max() < 0.05  # between the 40-slit orders


def test_tiles_are_read_from_the_scene(tmp_path):
    np.save(tmp_path / "flat.npy", np.zeros((16, 16)))
    scene = _scene(f'tiles = [40, 12]\nstructure = "{tmp_path / "flat.npy"}"\npixel_um = 0.05')
    assert scene.objects[0].material.tiles == (40, 12)
    with pytest.raises(SceneError, match="tiles"):
        _scene(f'tiles = [0, 12]\nstructure = "{tmp_path / "flat.npy"}"\npixel_um = 0.05')


# -- BRDF slices against the direct windowed reference (diffraction/slices.py) ------------------------


def _grating_material(sigma: float):
    import dataclasses

    from prefilter.scene import resolve_scene

    material = resolve_scene("diffraction-grating-plane").objects[0].material
    return dataclasses.replace(material, coherence=sigma)


def test_direct_slice_reference_equals_the_full_window_taylor_sum():
    """Two independent routes to the windowed transform: a Riemann sum of e^{ikwh} over the window, and
    the Taylor/FFT bake summed over every bin within the window (not the shader's 2 x 2)."""
    from prefilter.diffraction.slices import direct_reflectance, in_plane_slice, stam_geometry

    material = _grating_material(4.0)
    s = material.structure
    wi, wo, _ = in_plane_slice(30.0, 181)
    terms = taylor_terms(s.heights, s.pixel, sigma=material.coherence)
    uvw, gain = stam_geometry(wi, wo, material.f0)
    wavelengths, weights = spectral_weights(10.0)
    xyz = np.zeros((len(wi), 3))
    for lam, weight in zip(wavelengths, weights, strict=True):
        k = 2 * np.pi / lam
        p = terms.evaluate(k * uvw[:, 0], k * uvw[:, 1], k * uvw[:, 2], stencil=None)
        xyz += np.abs(p)[:, None] ** 2 * weight
    taylor = np.maximum(xyz_to_srgb(gain[:, None] * xyz), 0.0)
    direct = direct_reflectance(s.heights, s.pixel[0], material.coherence, material.f0, wi, wo, 10.0)
    assert direct.max() > 0.1
    np.testing.assert_allclose(taylor, direct, atol=1e-6 * direct.max())


def test_accurate_path_matches_the_direct_slice_reference_at_the_default_window():
    """σ = 65/4 µm: the window is narrow in frequency next to the 0.25 rad/µm bins, so 2 x 2 bins suffice."""
    from prefilter.diffraction.slices import direct_reflectance, in_plane_slice, shader_reflectances

    material = _grating_material(65.0 / 4.0)
    s = material.structure
    for theta_i in (0.0, 60.0):
        wi, wo, _ = in_plane_slice(theta_i, 357)
        shader = shader_reflectances(material, wi, wo, ("point",))["point"]
        direct = direct_reflectance(s.heights, s.pixel[0], material.coherence, material.f0, wi, wo, 5.0)
        assert np.abs(shader - direct).max() <= 1e-3 * direct.max(), theta_i


@pytest.mark.parametrize("sigma", [4.0, 2.5])
def test_accurate_path_matches_the_direct_slice_reference_at_the_presets_windows(sigma):
    """σ = 4 and 2.5 µm (the presets' windows): the window's neighbours one bin away weigh 0.6 and more, so
    the shader's stencil grows with 1 / (σ Δ); the 2 x 2 nearest bins alone were 15 % and 36 % off."""
    from prefilter.diffraction.slices import direct_reflectance, in_plane_slice, shader_reflectances

    material = _grating_material(sigma)
    assert material.stencil() > 1
    s = material.structure
    wi, wo, _ = in_plane_slice(30.0, 713)
    shader = shader_reflectances(material, wi, wo, ("point",))["point"]
    direct = direct_reflectance(s.heights, s.pixel[0], material.coherence, material.f0, wi, wo, 5.0)
    assert np.abs(shader - direct).max() <= 1e-2 * direct.max()


def test_direct_reference_of_a_2d_field_equals_the_full_window_taylor_sum_and_the_shader():
    """Snake ridges (a 2D field): the direct non-uniform DFT of e^{ikwh} under the window against the
    Taylor/FFT bake over every bin of the window, and the shader's 12 x 12 stencil against both."""
    from prefilter.diffraction.slices import direct_power, in_plane_slice, shader_reflectances, stam_geometry
    from prefilter.scene import resolve_scene

    material = resolve_scene("diffraction-snake-cylinder").objects[0].material
    s = material.structure
    wi, wo, _ = in_plane_slice(30.0, 13)
    uvw, gain = stam_geometry(wi, wo, material.f0)
    direct = direct_power(s.heights, s.pixel, material.coherence, uvw, 20.0)
    terms = taylor_terms(s.heights, s.pixel, sigma=material.coherence)
    wavelengths, weights = spectral_weights(20.0)
    xyz = np.zeros((len(wi), 3))
    for lam, weight in zip(wavelengths, weights, strict=True):
        k = 2 * np.pi / lam
        xyz += np.abs(terms.evaluate(k * uvw[:, 0], k * uvw[:, 1], k * uvw[:, 2]))[:, None] ** 2 * weight
    assert direct.max() > 0.05
    np.testing.assert_allclose(xyz, direct, atol=1e-6 * direct.max())
    reflectance = np.maximum(xyz_to_srgb(gain[:, None] * direct), 0.0)
    shader = shader_reflectances(dataclasses.replace(material, spectral_step=20.0), wi, wo, ("point",))
    assert np.abs(shader["point"] - reflectance).max() <= 5e-3 * reflectance.max()


def test_compare_adds_brdf_slices_against_the_direct_reference_for_gratings(tmp_path):
    from prefilter.compare import compare_scene, write_comparison

    scene = _scene(
        'coherence_um = 3.0\nfast_table = [64, 64, 16]\n[object.material.generator]\nname = "blazed"\n'
        "pixel = 0.1"  # the coarsest pixel that resolves the visible: half the direct reference's window sum
    )
    out = write_comparison(compare_scene(scene, spp=4, frames=1), tmp_path / "cmp")
    report = (out / "report.md").read_text()
    assert (out / "brdf-slices.png").stat().st_size > 10_000
    assert "## BRDF slices against the direct reference" in report
    rows = [line for line in report.splitlines() if line.startswith("| 30° | point |")]
    assert len(rows) == 1 and float(rows[0].split("|")[3]) > 0.0


# -- Dhillon et al. 2014's 2N + 1 tables (diffraction/dhillon.py) ---------------------------------------


def _in_plane(u: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ω_i, ω_o) in the plane across the grooves with k̂1 − k̂2 = (u, 0, w): −u = 2 sin s cos d and
    −w = 2 cos s cos d, θ_i = s + d, θ_o = s − d."""
    s = np.arctan2(-u, -w)
    d = np.arccos(np.hypot(u, w) / 2.0)  # |(u, w)| < 2
    ti, to = s + d, s - d
    zeros = np.zeros_like(u)
    wi = np.stack([np.sin(ti), zeros, np.cos(ti)], axis=1)
    wo = np.stack([np.sin(to), zeros, np.cos(to)], axis=1)
    return wi, wo


@pytest.mark.parametrize("w0", [0.0, -1.0])
def test_dhillon_tables_equal_the_direct_windowed_power_at_their_grid_points(w0):
    """Σ_j (w − w₀)^j T_j at the tables' (u, v = 0) nodes against the direct Riemann sum of e^{ikwh} under the
    window (slices.direct_power: no Taylor series, no DFT bins), at w from grazing to normal incidence."""
    from prefilter.diffraction.dhillon import bake_dhillon_tables
    from prefilter.diffraction.slices import direct_power

    material = _grating_material(4.0)
    s = material.structure
    tables = bake_dhillon_tables(s.heights, s.pixel, 4.0, 10.0, (65, 65), w0=w0)[..., :3].astype(np.float64)
    u_nodes = np.linspace(-2.0, 2.0, 65)
    columns = np.nonzero(np.abs(u_nodes) <= 1.2)[0]
    for w in (-1.9, -1.5, -1.0, -0.6):
        x = w - w0
        horner = np.zeros((len(columns), 3))
        for j in range(tables.shape[0] - 1, -1, -1):
            horner = horner * x + tables[j, 32, columns]
        uvw = np.stack([u_nodes[columns], np.zeros(len(columns)), np.full(len(columns), w)], axis=1)
        direct = direct_power(s.heights, s.pixel[0], 4.0, uvw, 10.0)
        assert direct.max() > 0.05
        np.testing.assert_allclose(horner, direct, atol=2e-5 * direct.max(), err_msg=f"w = {w}")


def test_glsl_dhillon_path_equals_its_tables_and_the_direct_reflectance():
    """The shader's Horner sum over hardware-bilinear lookups equals the same sum over NumPy-interpolated
    tables in float64 (the float32 cancellation stays small), and at the grid nodes the direct reference."""
    import dataclasses

    from prefilter.diffraction.slices import direct_reflectance

    material = dataclasses.replace(_grating_material(4.0), table_size=(65, 65, 9))
    s = material.structure
    resources = material.upload(gl_context(), None)
    try:
        rng = np.random.default_rng(3)
        w = rng.uniform(-1.95, -0.5, 400)
        u = rng.uniform(-1.0, 1.0, 400) * np.sqrt(3.9 - w**2)
        wi, wo = _in_plane(u, w)
        keep = (wi[:, 2] > 0.1) & (wo[:, 2] > 0.1)  # both above the surface, not grazing
        u, w = u[keep][:40], w[keep][:40]
        u = np.concatenate([np.linspace(-2.0, 2.0, 65)[13:52:3], u])  # 13 nodes, then 40 between them
        w = np.concatenate([np.full(13, -1.5), w])
        wi, wo = _in_plane(u, w)
        wo[13:, 1] = rng.uniform(-0.05, 0.05, len(u) - 13)  # off the plane: v between the nodes
        wo /= np.linalg.norm(wo, axis=1, keepdims=True)
        shader = glsl_eval(
            "df_dhillonReflectance(wi, wo)",
            {"wi": wi, "wo": wo},
            3,
            includes=INCLUDES,
            defines=material.defines(None),
            uniforms=resources["uniforms"],
            textures=resources["textures"],
        )
    finally:
        material.release(resources)
    from prefilter.diffraction.dhillon import bake_dhillon_tables
    from prefilter.diffraction.slices import stam_geometry

    tables = bake_dhillon_tables(s.heights, s.pixel, 4.0, material.spectral_step, (65, 65))[..., :3]
    uvw, gain = stam_geometry(wi, wo, material.f0)
    fx, fy = (uvw[:, 0] + 2.0) / 4.0 * 64, (uvw[:, 1] + 2.0) / 4.0 * 64
    x0, y0 = np.floor(fx).astype(int), np.floor(fy).astype(int)
    ax, ay = (fx - x0)[:, None], (fy - y0)[:, None]
    xyz = np.zeros((len(u), 3))
    for j in range(tables.shape[0] - 1, -1, -1):
        t = tables[j].astype(np.float64)
        lerp = (1 - ay) * ((1 - ax) * t[y0, x0] + ax * t[y0, x0 + 1]) + ay * (
            (1 - ax) * t[y0 + 1, x0] + ax * t[y0 + 1, x0 + 1]
        )
        xyz = xyz * (uvw[:, 2] - material.dhillon_w0)[:, None] + lerp
    numpy = np.maximum(xyz_to_srgb(gain[:, None] * xyz), 0.0)
    peak = numpy.max()
    assert peak > 0.1
    np.testing.assert_allclose(shader, numpy, atol=2e-3 * peak)
    direct = direct_reflectance(s.heights, s.pixel[0], 4.0, material.f0, wi[:13], wo[:13], 5.0)
    np.testing.assert_allclose(shader[:13], direct, atol=1e-3 * direct.max())


def test_fast_and_dhillon_bakes_of_a_2d_field_equal_the_direct_windowed_power():
    """Snake ridges (a 2D field, not a grating's one row): the fast 3D table and Dhillon's 2N + 1 tables at
    their grid nodes against the direct non-uniform transform of e^{ikwh} under the window (slices.
    direct_power: no DFT bins, no gridding), at three w and nine u through the specular lobe, to 1e-6 of
    the peak (measured 9.5e-8 and 2.4e-8; with the gridding weights flushed below 1e-4 instead of 1e-30,
    5.9e-6 for both, below 1e-2, 3.5e-4)."""
    from prefilter.diffraction.dhillon import bake_dhillon_tables
    from prefilter.diffraction.fast_table import bake_fast_table
    from prefilter.diffraction.slices import direct_power
    from prefilter.scene import resolve_scene

    material = resolve_scene("diffraction-snake-cylinder").objects[0].material
    s, sigma, w0 = material.structure, material.coherence, material.dhillon_w0
    fast = bake_fast_table(s.heights, s.pixel, sigma, 20.0, (33, 33, 5))[..., :3].astype(np.float64)
    tables = bake_dhillon_tables(s.heights, s.pixel, sigma, 20.0, (33, 33), w0=w0)[..., :3].astype(np.float64)
    nodes, w_nodes = np.linspace(-2.0, 2.0, 33), np.linspace(-2.0, 0.0, 5)
    columns = np.arange(12, 21)  # u in [-0.5, 0.5], v = 0 (row 16)
    uvw, from_fast, from_dhillon = [], [], []
    for wi in (1, 2, 3):
        for c in columns:
            uvw.append((nodes[c], 0.0, w_nodes[wi]))
            from_fast.append(fast[wi, 16, c])
            horner = np.zeros(3)
            for j in range(tables.shape[0] - 1, -1, -1):
                horner = horner * (w_nodes[wi] - w0) + tables[j, 16, c]
            from_dhillon.append(horner)
    direct = direct_power(s.heights, s.pixel, sigma, np.array(uvw), 20.0)
    assert direct.max() > 0.05 and np.median(direct) > 1e-3 * direct.max()  # the lobe, not its dark tails
    np.testing.assert_allclose(from_fast, direct, atol=1e-6 * direct.max())
    np.testing.assert_allclose(from_dhillon, direct, atol=1e-6 * direct.max())
