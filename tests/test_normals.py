"""Fournier 1992 pyramids at run time: interpolation, visibility, Fig. 2, horizons per peak, Dask bakes."""

import numpy as np
import pytest

from prefilter import PrefilterError
from prefilter.gl.context import gl_context
from prefilter.gl.evaluate import glsl_eval
from prefilter.gl.render import Renderer
from prefilter.normals import peak_texels
from prefilter.normals.horizon import horizon_slopes, visible
from prefilter.normals.material import NormalsMaterial, pack_atlas
from prefilter.normals.normal_maps import SurfaceMap, generate, write_normal_map
from prefilter.normals.peaks import lobe
from prefilter.normals.pyramid import PyramidOptions, build_pyramid, level_sizes
from prefilter.scene import SceneError, parse_scene

INCLUDES = ("normals/phong_peaks.glsl", "normals/normal_pyramid.glsl")


def _scene(material: str, light=(0.866, 0.5, 0.0), size=(48, 48), uv=(64.0, 64.0), base_dir="."):
    """An orthographic view straight down at a plane (tangent +x, bitangent -z, normal +y)."""
    text = f"""
size = [{size[0]}, {size[1]}]
ambient = 0.0
[camera]
eye = [0.0, 3.0, 0.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 0.0, -1.0]
projection = "orthographic"
height = 1.6
[[light]]
direction = [{light[0]}, {light[1]}, {light[2]}]
[[object]]
shape = "plane"
params = {{ size = 2.0 }}
[object.material]
uv_scale = [{uv[0]}, {uv[1]}]
{material}
"""
    return parse_scene(text, "test.toml", base_dir)


def _render(scene, modes, spp=0):
    renderer = Renderer(scene)
    try:
        images = {m: renderer.render(m)[..., :3] for m in modes}
        if spp:
            images["reference"] = renderer.reference(spp)[..., :3]
        return images
    finally:
        renderer.release()


def test_level_sizes_any_shape():
    assert level_sizes(48, 20) == [(48, 20), (24, 10), (12, 5), (6, 3), (3, 2), (2, 1), (1, 1)]
    assert level_sizes(1, 1) == [(1, 1)]


def test_interpolation_weights_are_bilinear_and_trilinear_and_sum_to_one():
    rng = np.random.default_rng(3)
    uv = rng.uniform(-3, 3, size=(200, 2))
    lod = rng.uniform(0, 6.5, size=200)
    sizes = level_sizes(48, 20)
    level = np.zeros((16, 4), np.float32)
    level[: len(sizes), 2:] = sizes
    prelude = """
vec4 weights(vec2 uv, float lod) {
    int l0; vec2 w; nd_levelWeights(lod, l0, w);
    ivec2 t0; vec2 f; nd_bilinear(uv, l0, t0, f);
    float total = 0.0;
    for (int k = 0; k < 2; ++k) {
        nd_bilinear(uv, l0 + k, t0, f);
        for (int c = 0; c < 4; ++c) total += w[k] * nd_bilinearWeight(f, c);
    }
    nd_bilinear(uv, l0, t0, f);
    return vec4(total, float(l0), w.y, nd_bilinearWeight(f, 3));
}"""
    got = glsl_eval(
        "weights(uv, lod)",
        {"uv": uv, "lod": lod},
        4,
        includes=INCLUDES,
        prelude=prelude,
        uniforms={"nd_level": level, "nd_levelCount": len(sizes)},
    )
    np.testing.assert_allclose(got[:, 0], 1.0, atol=1e-5)
    l0 = np.floor(lod).astype(int)
    np.testing.assert_array_equal(got[:, 1], l0)
    np.testing.assert_allclose(got[:, 2], np.where(l0 + 1 < len(sizes), lod - l0, 0.0), atol=1e-5)
    w = np.array([sizes[k][0] for k in l0])
    h = np.array([sizes[k][1] for k in l0])
    p = uv * np.stack([w, h], 1) - 0.5
    f = p - np.floor(p)
    np.testing.assert_allclose(got[:, 3], f[:, 0] * f[:, 1], atol=2e-4)


def test_glsl_lobe_and_visibility_match_the_numpy_oracles():
    rng = np.random.default_rng(5)
    c = rng.uniform(-0.2, 1.0, 300)
    n = rng.uniform(0.0, 300.0, 300)
    got = glsl_eval("nd_lobe(c, n)", {"c": c, "n": n}, 1, includes=INCLUDES).ravel()
    np.testing.assert_allclose(got, lobe(c, n), rtol=2e-4, atol=1e-5)

    w = rng.normal(size=(400, 3))
    w[:, 2] = np.abs(w[:, 2]) * rng.choice([1, -1], 400, p=[0.9, 0.1])
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    horizon = rng.uniform(-0.5, 1.5, size=(400, 4))
    hard = glsl_eval("nd_visibility(w, h, vec4(0.0))", {"w": w, "h": horizon}, 1, includes=INCLUDES).ravel()
    expected = np.array([visible(horizon[i], w[i]) for i in range(len(w))], float)
    assert np.mean(hard == expected) > 0.995  # float32 ties only

    # soft: 0 below mean - std, 1 above mean + std, linear between, along one axis
    slope = np.linspace(-1, 2, 61)
    dirs = np.stack([np.ones_like(slope), np.zeros_like(slope), slope], 1)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    dirs[:, 2] = np.maximum(dirs[:, 2], 1e-4)
    soft = glsl_eval(
        "nd_visibility(w, vec4(0.5, 9.0, 9.0, 9.0), vec4(0.25, 0.0, 0.0, 0.0))",
        {"w": dirs},
        1,
        includes=INCLUDES,
    ).ravel()
    s = dirs[:, 2] / dirs[:, 0]
    np.testing.assert_allclose(soft, np.clip((s - 0.25) / 0.5, 0, 1), atol=1e-4)


def test_packed_peak_texels_keep_every_field_within_its_step_in_numpy_and_glsl():
    """Oracle: the peaks that went in. Every packed word is a normal float (it must survive float32
    textures and EXR files), and what the shader unpacks is each input within half its code step."""
    rng = np.random.default_rng(7)
    n = 500
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:3] = [(0, 0, 1), (1, 0, 0), (0, -1, 0)]
    amplitude = rng.uniform(0, 1.5, n)
    amplitude[:2] = (0.0, 1.5)
    exponent = np.concatenate([[0.0, 1.0, 150.0, 255.0], np.exp(rng.uniform(0, np.log(2e4), n - 4))])
    horizon = np.concatenate([rng.uniform(-0.7, 3.0, (n, 4)), rng.uniform(0, 0.8, (n, 4))], axis=1)
    scales = peak_texels.scales_for(amplitude, horizon)
    texels = peak_texels.encode(d[:, :2], amplitude, exponent, horizon, scales)
    float_exponent = (texels.view(np.uint32) >> 23) & 255
    assert np.isfinite(texels).all() and float_exponent.min() >= 64 and float_exponent.max() <= 127

    fields = {}
    for which in range(4):
        fields[which] = glsl_eval(
            f"fieldOf(t, {which})",
            {"t": texels},
            4,
            includes=INCLUDES,
            defines={"ND_SHADOWING": True},
            uniforms=scales.uniforms(),
            prelude="""
            vec4 fieldOf(vec4 t, int which) {
                NdPeak p = nd_unpackPeak(t);
                if (which == 0) return vec4(p.direction, p.amplitude);
                if (which == 1) return vec4(p.exponent, 0.0, 0.0, 0.0);
                if (which == 2) return p.mean;
                return p.deviation;
            }""",
        )
    numpy = peak_texels.decode(texels, scales)
    shader = {
        "direction": fields[0][:, :3],
        "amplitude": fields[0][:, 3],
        "exponent": fields[1][:, 0],
        "mean": fields[2],
        "deviation": fields[3],
    }
    for got in (shader, numpy):
        np.testing.assert_allclose(got["direction"][:, :2], d[:, :2], atol=0.5 / 1023 + 1e-6)
        np.testing.assert_allclose(got["direction"][:3], d[:3], atol=1e-6)  # the pole and the horizon
        np.testing.assert_allclose(got["amplitude"], amplitude, atol=scales.amplitude_step / 2 + 1e-6)
        np.testing.assert_allclose(got["exponent"][:4], exponent[:4], rtol=1e-6)  # integers up to 256
        np.testing.assert_allclose(1 + got["exponent"], 1 + exponent, rtol=2.0**-8 + 1e-6)
        np.testing.assert_allclose(got["mean"], horizon[:, :4], atol=scales.mean_step / 2 + 1e-6)
        np.testing.assert_allclose(got["deviation"], horizon[:, 4:], atol=scales.std_step / 2 + 1e-6)


def test_exact_texels_collect_their_own_horizons():
    surface = generate("hemispheres", size=(16, 16), count=(2, 2))
    pyramid = build_pyramid(surface, PyramidOptions(tile=8), scheduler="synchronous")
    horizons = horizon_slopes(surface.heights)
    # level 1 texels hold <= 4 distinct normals: each peak's statistics are those of its own texels
    peaks, stats = pyramid.peaks[1], pyramid.horizon[1]
    for j, i in [(0, 0), (3, 5), (7, 7), (2, 6)]:
        block = surface.normals[2 * j : 2 * j + 2, 2 * i : 2 * i + 2].reshape(-1, 3)
        hblock = horizons[2 * j : 2 * j + 2, 2 * i : 2 * i + 2].reshape(-1, 4)
        for k in range(int((peaks[j, i, :, 3] > 0).sum())):
            members = np.linalg.norm(block - peaks[j, i, k, :3], axis=1) < 1e-5
            assert members.any()
            np.testing.assert_allclose(peaks[j, i, k, 3], members.mean(), atol=1e-6)
            np.testing.assert_allclose(stats[j, i, k, :4], hblock[members].mean(0), atol=1e-5)
            np.testing.assert_allclose(stats[j, i, k, 4:], hblock[members].std(0), atol=1e-4)


def test_fitted_peaks_collect_horizon_statistics_of_their_normals():
    """Two populations of normals (tilted +-30 deg about y) with different horizons: each fitted peak
    carries the horizon statistics of its own population."""
    rng = np.random.default_rng(7)
    n = 32
    sign = np.where((np.arange(n)[:, None] // 8 + np.arange(n)[None, :] // 8) % 2 == 0, 1.0, -1.0)
    angle = np.radians(30.0) * sign + rng.normal(0, np.radians(0.5), (n, n))
    normals = np.stack([np.sin(angle), rng.normal(0, 0.005, (n, n)), np.cos(angle)], -1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    heights = np.where(sign > 0, 0.0, 2.0) + rng.normal(0, 0.1, (n, n))
    pyramid = build_pyramid(
        SurfaceMap(normals, heights, "two"), PyramidOptions(exponent=100, tile=8), "synchronous"
    )
    top, stats = pyramid.peaks[-1][0, 0], pyramid.horizon[-1][0, 0]
    # the two largest peaks are the populations (smaller ones fit the bilinear transitions between them)
    assert top[0, 3] > 0.3 and top[1, 3] > 0.3 and top[0, 0] * top[1, 0] < 0
    horizons = horizon_slopes(heights)
    for k in (0, 1):
        population = sign > 0 if top[k, 0] > 0 else sign < 0
        np.testing.assert_allclose(np.degrees(np.arcsin(abs(top[k, 0]))), 30.0, atol=1.0)
        np.testing.assert_allclose(stats[k, :4], horizons[population].mean(0), atol=0.05)
        np.testing.assert_allclose(stats[k, 4:], horizons[population].std(0), atol=0.05)


def test_fig2_two_symmetric_populations_highlight_matches_reference_and_averaged_normal_does_not(tmp_path):
    """Fournier's Fig. 2: half the normals tilted +30 deg, half -30 deg about y. Lit so that the +30 deg
    population mirrors the light into the eye, far away (many texels per pixel)."""
    rng = np.random.default_rng(2)
    n = 64
    sign = np.where((np.arange(n)[:, None] // 4 + np.arange(n)[None, :] // 4) % 2 == 0, 1.0, -1.0)
    angle = np.radians(30.0) * sign + rng.normal(0, np.radians(0.3), (n, n))  # > 7 distinct: real fits
    normals = np.stack([np.sin(angle), np.zeros((n, n)), np.cos(angle)], -1)
    write_normal_map(tmp_path / "two.exr", normals)
    material = (
        'type = "normal-map"\nnormal_map = "two.exr"\nalbedo = "#202020"\nspecular = 0.2\nexponent = 200'
    )
    scene = _scene(material, base_dir=tmp_path)
    images = _render(scene, ["naive", "multilobe"], spp=64)
    ref = images["reference"].mean()
    assert ref > 0.1  # a strong highlight in the reference
    # measured: multilobe 0.232, reference 0.260, naive 0.007 (the fit's 5 % tolerance and the 2 x 2
    # points per texel that stand for the bilinear field account for the gap)
    assert abs(images["multilobe"].mean() - ref) < 0.15 * ref
    assert images["naive"].mean() < 0.1 * ref


def test_constant_map_every_level_and_footprint_gives_the_point_image(tmp_path):
    """Interpolation weights sum to 1 everywhere: a map of one normal renders the same in all modes."""
    normals = np.zeros((20, 48, 3))
    normals[...] = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    write_normal_map(tmp_path / "flat.exr", normals)
    for aniso in (1, 4):
        material = 'type = "normal-map"\nnormal_map = "flat.exr"\nspecular = 0.3\nexponent = 60\n'
        material += f"anisotropy = {aniso}"
        scene = _scene(material, light=(0.2, 0.9, 0.3), uv=(3.0, 40.0), base_dir=tmp_path)
        images = _render(scene, ["point", "multilobe", "naive", "toksvig"])
        for mode in ("multilobe", "naive", "toksvig"):
            np.testing.assert_allclose(images[mode], images["point"], atol=2e-3, err_msg=mode)


def test_lod_bias_moves_multilobe_between_the_base_level_and_the_pyramid():
    """lod_bias shifts multilobe's level: far below 0 every pixel is magnified, so multilobe is the
    base level, the `point` image; at 0 the pyramid's levels filter the map and it is not."""
    material = (
        'type = "normal-map"\nspecular = 0.5\nexponent = 80\nanisotropy = 2\nlod_bias = {bias}\n'
        '[object.material.generator]\nname = "hemispheres"\nsize = [32, 32]\ncount = 4'
    )
    images = {}
    for bias in (0.0, -8.0):
        images[bias] = _render(_scene(material.format(bias=bias), uv=(24.0, 24.0)), ["point", "multilobe"])
    np.testing.assert_allclose(images[-8.0]["multilobe"], images[-8.0]["point"], atol=1e-6)
    assert np.abs(images[0.0]["multilobe"] - images[0.0]["point"]).mean() > 0.01


def test_multiple_surface_is_its_peaks_and_drops_those_below_the_surface():
    velvet = _scene('type = "multiple-surface"\npreset = "velvet"').objects[0].material
    assert isinstance(velvet, NormalsMaterial)
    peaks = velvet.pyramid().peaks[0][0, 0]
    assert (peaks[:, 3] > 0).sum() == 5  # two of the paper's seven point below the surface
    scene = _scene('type = "multiple-surface"\npreset = "three-normal"', light=(0.6, 0.8, 0.0))
    images = _render(scene, ["point", "multilobe"])
    np.testing.assert_array_equal(images["point"], images["multilobe"])
    assert images["point"].max() > 0.05


def test_pyramid_tiles_are_cached_and_dask_cluster_bake_gives_identical_bytes(tmp_path, monkeypatch):
    distributed = pytest.importorskip("distributed")
    surface = generate("twill", size=(48, 40), threads=8)
    options = PyramidOptions(tile=16, exponent=60)
    monkeypatch.setenv("PREFILTER_CACHE", str(tmp_path / "a"))
    local = build_pyramid(surface, options, scheduler="synchronous")
    again = build_pyramid(surface, options, scheduler="synchronous")
    assert again.report.tiles_from_cache == again.report.tiles == local.report.tiles == 9
    monkeypatch.setenv("PREFILTER_CACHE", str(tmp_path / "b"))
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as c:
        cluster = build_pyramid(surface, options, scheduler=c.scheduler_address)
    assert cluster.report.tiles_from_cache == 0 and cluster.report.scheduler.startswith("distributed")
    for a, b in zip(local.peaks + local.horizon, cluster.peaks + cluster.horizon, strict=True):
        assert a.tobytes() == b.tobytes()


def test_npot_map_bakes_packs_and_renders(tmp_path):
    surface = generate("stochastic", size=(48, 20), rms_slope=0.4)
    pyramid = build_pyramid(surface, PyramidOptions(tile=8), scheduler="synchronous")
    assert [p.shape[:2] for p in pyramid.peaks] == [(h, w) for w, h in level_sizes(48, 20)]
    for level in pyramid.peaks:
        np.testing.assert_allclose(level[..., 3].sum(-1), 1.0, atol=0.1)
    atlas, boxes, scales = pack_atlas(pyramid, shadowing=True)
    assert atlas.shape[:2] == (22, 72) and len(boxes) == 7  # levels >= 1 stack to 10+5+3+2+1+1 rows
    amplitudes = peak_texels.decode(atlas, scales)["amplitude"]
    for (x, y, w, h), level in zip(boxes.astype(int), pyramid.peaks, strict=True):
        block = amplitudes[y : y + h, x : x + w]
        np.testing.assert_allclose(block, level[..., 3], atol=scales.amplitude_step / 2)
    material = (
        'type = "normal-map"\nshadowing = true\n[object.material.generator]\n'
        'name = "stochastic"\nsize = [48, 20]\nrms_slope = 0.4'
    )
    images = _render(_scene(material, uv=(2.0, 5.0)), ["point", "multilobe"])
    assert np.isfinite(images["multilobe"]).all() and images["multilobe"].max() > 0.01
    gl_context()


@pytest.mark.parametrize(
    "material, message",
    [
        ('type = "normal-map"', "needs normal_map, height_map or a [generator]"),
        ('type = "normal-map"\nnormal_map = "missing.png"', "normal_map: file not found"),
        ('type = "normal-map"\n[object.material.generator]\nname = "waves"', "waves"),
        (
            'type = "normal-map"\nshadowing = true\nnormal_map = "n.exr"',
            "shadowing: needs heights",
        ),
        ('type = "multiple-surface"\npreset = "satin"', "preset: expected one of"),
        (
            'type = "multiple-surface"\n[[object.material.peak]]\namplitude = 1.0\n'
            "direction = [0, 0, -1]\nexponent = 5",
            "below the surface",
        ),
        ('type = "normal-map"\nnormal_map = "n.exr"\n[object.material.pyramid]\ntile = 12', "power of two"),
        ('type = "normal-map"\nnormal_map = "n.exr"\nlod_bias = "finer"', "lod_bias: expected a number"),
        ('type = "normal-map"\nheight_map = "n.exr"\nheight_scale = -1', "height_scale: expected a number"),
    ],
)
def test_bad_materials_name_the_key(tmp_path, material, message):
    write_normal_map(tmp_path / "n.exr", np.dstack([np.zeros((4, 4, 2)), np.ones((4, 4))]))
    with pytest.raises((SceneError, PrefilterError)) as info:
        _scene(material, base_dir=tmp_path)
    assert message in str(info.value)
    assert str(info.value).count("test.toml") == 1  # once: not re-raised under an enclosing key


def test_levels_of_a_tiling_map_are_alike_and_shaded_once_with_the_same_result():
    """Hemispheres repeat every 16 texels: from level 4 up every texel holds the same peaks, and shading
    such a level once per pixel gives the image that shading all its texels gives."""
    periodic = build_pyramid(generate("hemispheres", size=(64, 64), count=(4, 4)), PyramidOptions(tile=16))
    assert periodic.alike == [False] * 4 + [True] * 3
    for level in range(4, 7):
        assert (periodic.peaks[level] == periodic.peaks[level][0, 0]).all()
    random = build_pyramid(generate("stochastic", size=(32, 32)), PyramidOptions(tile=16))
    assert random.alike == [False] * 5 + [True]

    material = (
        'type = "normal-map"\nspecular = 0.3\nexponent = 60\nanisotropy = 4\n'
        '[object.material.generator]\nname = "hemispheres"\nsize = [64, 64]\ncount = [4, 4]'
    )
    scene = _scene(material, light=(0.3, 0.8, -0.4), uv=(6.0, 300.0))  # lod 0 .. 6 across the image
    shaded_once = _render(scene, ["multilobe"])["multilobe"]
    scene.objects[0].material.pyramid().alike = [False] * 7
    every_texel = _render(scene, ["multilobe"])["multilobe"]
    assert shaded_once.max() > 0.05
    np.testing.assert_allclose(shaded_once, every_texel, atol=1e-4)
