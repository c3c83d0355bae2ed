"""Tabulated drivers (Heitz et al. §4.2): MIP moments give the variance of the covered texels."""

from dataclasses import replace

import imageio.v3 as iio
import numpy as np
import pytest
from oracles import bilinear

from prefilter import PrefilterError
from prefilter.colormap.tabulated import moment_pyramid, read_driver
from prefilter.gl.context import gl_context
from prefilter.gl.evaluate import glsl_eval
from prefilter.gl.render import Renderer
from prefilter.image_data import write_exr
from prefilter.scene import SceneError, load_scene, resolve_scene


def test_moment_pyramid_variance_is_the_variance_of_the_covered_texels():
    f = np.random.default_rng(2).gamma(2.0, 0.2, size=(64, 32))  # skewed, not Gaussian
    levels = moment_pyramid(f)
    assert len(levels) == 7 and levels[-1].shape == (1, 1, 2)
    for data in levels:
        by, bx = f.shape[0] // data.shape[0], f.shape[1] // data.shape[1]
        blocks = f.reshape(data.shape[0], by, data.shape[1], bx)
        np.testing.assert_allclose(data[..., 0], blocks.mean(axis=(1, 3)), atol=1e-12)
        np.testing.assert_allclose(data[..., 1] - data[..., 0] ** 2, blocks.var(axis=(1, 3)), atol=1e-12)


def test_gpu_moment_texture_holds_the_pyramid():
    scene = resolve_scene("terrain-data")
    material = scene.objects[0].material
    resources = material.upload(gl_context(), mesh=None)
    try:
        levels = moment_pyramid(material.driver)
        texture = resources.driver
        for level in (0, 3, 6):
            h, w = levels[level].shape[:2]
            ij = np.random.default_rng(level).integers(0, [w, h], size=(50, 2))
            got = glsl_eval(
                f"texelFetch(driver, ivec2(ij), {level}).xy",
                {"ij": ij},
                2,
                prelude="uniform sampler2D driver;",
                textures={"driver": texture},
            )
            want = levels[level][ij[:, 1], ij[:, 0]]
            np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-7)
            variance = got[:, 1] - got[:, 0] ** 2
            np.testing.assert_allclose(variance, want[:, 1] - want[:, 0] ** 2, atol=1e-5)
    finally:
        resources.release()


@pytest.mark.parametrize("target", ["gl330", "es300"])
def test_point_read_is_the_base_level_not_the_anisotropic_filter(target):
    """Each reference pass must see f itself. Random neighbouring uvs give the fragments huge
    derivatives, under which the driver's 16x anisotropic sampler blurs (llvmpipe does so even for
    textureLod at level 0); the texelFetch read must still equal bilinear reconstruction of level 0."""
    scene = resolve_scene("terrain-data")
    material = scene.objects[0].material
    resources = material.upload(gl_context(), mesh=None)
    try:
        uv = np.random.default_rng(7).uniform(-3.0, 3.0, size=(4096, 2))
        got = glsl_eval(
            "tb_driverAtBase(driver, uv)",
            {"uv": uv},
            1,
            includes=("colormap/tabulated.glsl",),
            target=target,
            prelude="uniform sampler2D driver;",
            textures={"driver": resources.driver},
        ).ravel()
    finally:
        resources.release()
    h, w = material.driver.shape
    want = bilinear(material.driver, uv[:, 0] * w, uv[:, 1] * h)
    np.testing.assert_allclose(got, want, atol=2e-5)


def test_read_driver_errors(tmp_path):
    odd = tmp_path / "odd.png"
    iio.imwrite(odd, np.zeros((30, 32), np.uint8))
    with pytest.raises(PrefilterError, match="powers of two"):
        read_driver(odd)
    garbage = tmp_path / "bad.png"
    garbage.write_bytes(b"not an image")
    with pytest.raises(PrefilterError, match="not a PNG file"):
        read_driver(garbage)
    garbage = tmp_path / "bad.tif"
    garbage.write_bytes(b"not an image")
    with pytest.raises(PrefilterError, match="cannot read driver image"):
        read_driver(garbage)
    # non-finite values had gone into the moment pyramid and rendered as whatever the table clamps them to
    holes = np.ones((4, 8), np.float32)
    holes[1, 5] = np.nan
    holes[2, 0] = np.inf
    write_exr(tmp_path / "holes.exr", "Y", holes)
    with pytest.raises(PrefilterError, match=r"2 driver values are not finite \(the first at x 5, y 1\)"):
        read_driver(tmp_path / "holes.exr")
    ok = tmp_path / "ok.png"
    iio.imwrite(ok, np.full((8, 16), 65535, np.uint16))
    np.testing.assert_array_equal(read_driver(ok), np.ones((8, 16)))


@pytest.mark.parametrize(
    ("material", "message"),
    [
        ('image = "nowhere.png"', r"object\[0\]\.material\.image: file not found"),
        ('image = "f.png"\nprobes = 17', r"object\[0\]\.material\.probes: expected an integer in \[0, 16\]"),
    ],
)
def test_scene_errors_name_the_key(tmp_path, material, message):
    iio.imwrite(tmp_path / "f.png", np.zeros((8, 8), np.uint8))
    scene = tmp_path / "s.toml"
    scene.write_text(
        '[camera]\neye = [0.0, 1.0, 3.0]\ntarget = [0.0, 0.0, 0.0]\n[[object]]\nshape = "plane"\n'
        f'[object.material]\ntype = "tabulated"\n{material}\n'
        '[object.material.colour_table]\nstops = [[0.0, "#000000"], [1.0, "#ffffff"]]\n'
    )
    with pytest.raises(SceneError, match=message):
        load_scene(scene)


def _footprint_moments_by_brute_force(f, uv, dx, dy, k=24):
    """Mean and standard deviation of bilinear f over each parallelogram uv + a dx + b dy, a, b in
    [-1/2, 1/2] (a box pixel filter), from a k x k grid of points."""
    h, w = f.shape
    s = (np.arange(k) + 0.5) / k - 0.5
    a, b = (g.ravel() for g in np.meshgrid(s, s))
    x = (uv[:, None, 0] + a * dx[:, None, 0] + b * dy[:, None, 0]) * w
    y = (uv[:, None, 1] + a * dx[:, None, 1] + b * dy[:, None, 1]) * h
    values = bilinear(f, x, y)
    return values.mean(axis=1), values.std(axis=1)


def _ridged_field(shape=(64, 256), seed=3):
    """A non-square periodic test image: smooth random waves with sharp ridges (|sin|), in [0, 2]."""
    h, w = shape
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w] + 0.5
    field = np.zeros(shape)
    for _ in range(12):
        kx, ky = rng.integers(1, 9), rng.integers(-4, 5)
        field += np.abs(np.sin(np.pi * (kx * x / w + ky * y / h) + rng.uniform(0, np.pi))) / 6.0
    return field


@pytest.mark.parametrize("target", ["gl330", "es300"])
@pytest.mark.parametrize("driver", ["terrain-data", "ridged 256x64"])
def test_footprint_probes_give_the_moments_of_the_covered_texels(target, driver):
    """tb_footprintMoments against brute-force moments under 400 random footprints, on the real data and
    on a non-square synthetic image: 1-64 texels long, up to 12:1, any orientation, either derivative the
    longer. Four probes along the longer axis must come within 0.15 (mean) and 0.17 (σ) of the
    footprints' mean σ, RMS, and halve the error of one isotropic read (TB_PROBES = 1)."""
    material = resolve_scene("terrain-data").objects[0].material
    if driver != "terrain-data":
        material = replace(material, driver=_ridged_field())
    h, w = material.driver.shape
    rng = np.random.default_rng(5)
    n = 400
    uv = rng.uniform(0.0, 1.0, (n, 2))
    longer = np.exp(rng.uniform(0.0, np.log(64.0), n))
    shorter = longer / np.exp(rng.uniform(0.0, np.log(12.0), n))
    angle = rng.uniform(0.0, np.pi, n)
    along = np.stack([np.cos(angle), np.sin(angle)], 1) * longer[:, None]
    across = np.stack([-np.sin(angle), np.cos(angle)], 1) * shorter[:, None]
    swap = rng.random(n)[:, None] < 0.5
    texel = np.array([w, h], float)
    dx, dy = np.where(swap, across, along) / texel, np.where(swap, along, across) / texel
    mean, sd = _footprint_moments_by_brute_force(material.driver, uv, dx, dy)
    scale = sd.mean()
    errors = {}
    for probes in (1, 4):
        resources = replace(material, probes=probes).upload(gl_context(), mesh=None)
        try:
            got = glsl_eval(
                "tb_footprintMoments(driver, uv, dx, dy)",
                {"uv": uv, "dx": dx, "dy": dy},
                2,
                includes=("colormap/tabulated.glsl",),
                target=target,
                defines={"TB_PROBES": probes},
                prelude="uniform sampler2D driver;",
                textures={"driver": resources.driver},
            )
        finally:
            resources.release()
        got_sd = np.sqrt(np.maximum(got[:, 1] - got[:, 0] ** 2, 0.0))
        errors[probes] = (
            np.sqrt(np.mean((got[:, 0] - mean) ** 2)) / scale,
            np.sqrt(np.mean((got_sd - sd) ** 2)) / scale,
        )
    assert errors[4][0] < 0.15 and errors[4][1] < 0.17, errors
    assert errors[4][0] < 0.5 * errors[1][0] and errors[4][1] < 0.5 * errors[1][1], errors


def test_the_gl_anisotropic_filter_remains_an_option():
    """probes = 0 reads the moments through the GL's 16x anisotropic filter: it must render, and on the
    terrain both reads must give nearly the same picture (the probes differ from it most at the horizon)."""
    scene = resolve_scene("terrain-data")
    images = {}
    for probes in (0, 4):
        material = replace(scene.objects[0].material, probes=probes)
        variant = replace(scene, objects=[replace(scene.objects[0], material=material)])
        renderer = Renderer(variant, (128, 96))
        try:
            images[probes] = renderer.render("gaussian")
        finally:
            renderer.release()
    covered = images[4][..., 3] > 0
    assert np.isfinite(images[0]).all() and covered.mean() > 0.5
    difference = np.abs(images[0] - images[4])[covered][:, :3]
    assert 0.0 < difference.mean() < 0.05, difference.mean()
