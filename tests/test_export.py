"""Export bundles: an engine-like loader that reads only the bundle's files (JSON, EXR, .bin, GLSL) draws
every material type in a fresh GL context, from the 330 core and the 300 es shaders, and must match
`prefilter render` within FLIP 0.01; tables round-trip; the README names the uniforms; bad output
directories are refused without writing."""

import json
from pathlib import Path

import moderngl
import numpy as np
import OpenEXR
import pytest

from prefilter.cli import main
from prefilter.export import FORMAT, export_scene
from prefilter.gl.render import Renderer, composite
from prefilter.metrics import flip_map
from prefilter.scene import preset_names, resolve_scene

SIZE = (96, 72)
# one preset per material type (hart, tabulated, microsurface, normal-map, multiple-surface, diffraction),
# each in its unfiltered mode and one filtered mode
CASES = {
    "marble-cube": ("point", "gaussian"),
    "terrain-contours": ("point", "gaussian"),
    "micro-heights-sphere": ("point", "surface-filter"),
    "micro-sponge-sphere": ("surface-filter",),  # a transfer function: its tables over the driver
    "normals-hemispheres-plane-shadowed": ("point", "multilobe"),
    "normals-velvet-sphere": ("naive", "multilobe"),
    "diffraction-grating-plane": ("point", "fast"),
}
GL_ENUMS = {
    name: getattr(moderngl, name)
    for name in ("NEAREST", "LINEAR", "NEAREST_MIPMAP_NEAREST", "LINEAR_MIPMAP_NEAREST")
    + ("NEAREST_MIPMAP_LINEAR", "LINEAR_MIPMAP_LINEAR")
}


def _read_level(path: Path, components: int) -> np.ndarray:
    with OpenEXR.File(str(path), separate_channels=True) as exr:
        channels = exr.channels()
        return np.stack([channels["RGBA"[i]].pixels for i in range(components)], axis=-1).astype(np.float32)


def _upload(ctx: moderngl.Context, meta_path: Path):
    meta = json.loads(meta_path.read_text())
    c, w, h, d = meta["components"], meta["width"], meta["height"], meta["depth"]
    levels = [_read_level(meta_path.parent / lv["file"], c) for lv in meta["levels"]]
    if meta["kind"] == "2d":
        tex = ctx.texture((w, h), c, levels[0].tobytes(), dtype="f4")
        if len(levels) > 1:
            tex.build_mipmaps(0, len(levels) - 1)
            for k, level in enumerate(levels[1:], 1):
                tex.write(level.tobytes(), level=k)
    elif meta["kind"] == "2d_array":
        tex = ctx.texture_array((w, h, d), c, levels[0].tobytes(), dtype="f4")
    else:
        tex = ctx.texture3d((w, h, d), c, levels[0].tobytes(), dtype="f4")
    tex.filter = (GL_ENUMS[meta["filter"]["min"]], GL_ENUMS[meta["filter"]["mag"]])
    tex.repeat_x = meta["wrap"]["s"] == "REPEAT"
    tex.repeat_y = meta["wrap"]["t"] == "REPEAT"
    if "r" in meta["wrap"]:
        tex.repeat_z = meta["wrap"]["r"] == "REPEAT"
    if meta["anisotropy"] > 1.0:
        tex.anisotropy = meta["anisotropy"]
    return tex


def _set(prog: moderngl.Program, name: str, values: list) -> None:
    if name not in prog:
        return
    u = prog[name]
    if isinstance(values[0], int) and not isinstance(values[0], bool):
        u.value = values[0] if len(values) == 1 else tuple(values)
        return
    data = np.asarray(values, dtype=np.float32)[: u.array_length * u.dimension]
    u.write(data.tobytes())


def draw_bundle(ctx: moderngl.Context, root: Path, mode: str, target: str) -> np.ndarray:
    """What an engine would do with the bundle (README recipe); returns composited linear RGB."""
    scene = json.loads((root / "scene.json").read_text())
    w, h = scene["scene"]["size"]
    colour = ctx.texture((w, h), 4, dtype="f4")
    depth = ctx.depth_renderbuffer((w, h))
    fbo = ctx.framebuffer([colour], depth)
    fbo.use()
    ctx.viewport = (0, 0, w, h)
    ctx.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
    ctx.enable(moderngl.DEPTH_TEST)
    objects = sorted(scene["objects"], key=lambda o: o["blend"] != "opaque")
    for obj in objects:
        files = obj["shaders"][mode][target]
        prog = ctx.program(
            vertex_shader=(root / files["vertex"]).read_text(),
            fragment_shader=(root / files["fragment"]).read_text(),
        )
        mesh = obj["mesh"]
        vbo = ctx.buffer((root / mesh["vertices"]).read_bytes())
        ibo = ctx.buffer((root / mesh["indices"]).read_bytes())
        layout, names = [], []
        for a in mesh["attributes"]:
            layout.append(f"{a['size']}f" if a["name"] in prog else f"{4 * a['size']}x")
            names += [a["name"]] if a["name"] in prog else []
        vao = ctx.vertex_array(
            prog, [(vbo, " ".join(layout), *names)], index_buffer=ibo, index_element_size=4
        )
        for unit, (name, meta) in enumerate(obj["samplers"].items()):
            _upload(ctx, root / meta).use(location=unit)
            if name in prog:
                prog[name].value = unit
        for name, values in obj["view"].items():
            _set(prog, name, values)
        for name, entry in obj["uniforms"].items():
            _set(prog, name, entry["value"])
        if obj["double_sided"]:
            ctx.disable(moderngl.CULL_FACE)
        else:
            ctx.enable(moderngl.CULL_FACE)
        if obj["blend"] == "over":
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
            ctx.depth_mask = False
        else:
            ctx.disable(moderngl.BLEND)
            ctx.depth_mask = True
        vao.render(moderngl.TRIANGLES)
    ctx.depth_mask = True
    ctx.disable(moderngl.BLEND)
    rgba = np.frombuffer(colour.read(), dtype=np.float32).reshape(h, w, 4)[::-1]
    return composite(rgba, np.asarray(scene["scene"]["background"], np.float32))


@pytest.fixture(scope="module")
def fresh_context():
    ctx = moderngl.create_context(standalone=True, backend="egl", require=330)
    yield ctx
    ctx.release()


@pytest.mark.parametrize("name", sorted(CASES))
def test_exported_shaders_reproduce_the_render(name, tmp_path, fresh_context):
    scene = resolve_scene(name)
    scene.size = SIZE
    root = export_scene(scene, tmp_path / name)
    renderer = Renderer(scene, SIZE)
    try:
        for mode in CASES[name]:
            expected = composite(renderer.render(mode), scene.background)
            assert expected.std() > 1e-3, f"{mode}: flat reference image"
            for target in ("gl330", "es300"):
                image = draw_bundle(fresh_context, root, mode, target)
                error = float(flip_map(image, expected).mean())
                print(f"{name} {mode} {target}: FLIP {error:.6f}")
                assert error <= 0.01, f"{name} {mode} {target}: FLIP {error:.4f} > 0.01"
    finally:
        renderer.release()


def test_tables_round_trip_and_document_themselves(tmp_path):
    """Every level of every table reads back as the GPU holds it, with its parameterisation documented."""
    from prefilter.export import capture_scene, read_table_exr

    scene = resolve_scene("normals-hemispheres-plane-shadowed")
    root = export_scene(scene, tmp_path / "b")
    (captured,) = capture_scene(scene)
    assert captured.tables, "no tables captured"
    for name, table in captured.tables.items():
        meta = json.loads((root / "tables" / captured.directory / f"{name}.json").read_text())
        assert meta["description"], f"{name}: no @table description"
        assert len(meta["levels"]) == len(table.levels)
        for k, level in enumerate(table.levels):
            back = read_table_exr(
                root / "tables" / captured.directory / f"{name}.{k}.exr", meta["components"], meta["depth"]
            )
            np.testing.assert_array_equal(back, level)


@pytest.mark.parametrize("name", preset_names())
def test_every_sampler_of_every_preset_is_documented(name):
    from prefilter.export import capture_scene

    for captured in capture_scene(resolve_scene(name)):
        for sampler in captured.tables:
            u = captured.declarations.get(sampler)
            assert u is not None, f"{name}: sampler {sampler} bound but declared by no shader"
            assert u.comment.startswith("@table") and len(u.comment) > 20, f"{name}: {sampler} lacks @table"


def test_readme_names_uniforms_samplers_and_recipe(tmp_path):
    root = export_scene(resolve_scene("diffraction-grating-plane"), tmp_path / "b")
    text = (root / "README.md").read_text()
    data = json.loads((root / "scene.json").read_text())
    assert data["format"] == FORMAT
    for name in ("u_clipFromObject", "sh_lightDirection", "df_terms", "df_sigma", "glDrawElements"):
        assert name in text, name
    assert any(p["uniform"] == "u_exposure" for p in data["objects"][0]["parameters"])


def test_moving_uniforms_carry_their_end_value(tmp_path):
    """fire animates its noise offsets: the bundle gives the value at t = 1 for a linear interpolation."""
    root = export_scene(resolve_scene("fire"), tmp_path / "b")
    uniforms = json.loads((root / "scene.json").read_text())["objects"][0]["uniforms"]
    assert "end" in uniforms["pt_noiseOffset"]
    assert "end" not in uniforms["pt_quadric"]
    # GLSL types and array lengths for engines without reflection
    assert uniforms["pt_quadric"]["type"] == "mat4" and uniforms["pt_quadric"]["array"] is None
    offsets = uniforms["pt_noiseOffset"]
    assert offsets["type"] == "vec3" and offsets["array"] * 3 == len(offsets["value"]) > 0


def test_export_refuses_a_directory_that_is_not_a_bundle(tmp_path, capsys):
    target = tmp_path / "mine"
    target.mkdir()
    (target / "notes.txt").write_text("keep me")
    assert main(["export", "marble-cube", "-o", str(target)]) == 1
    err = capsys.readouterr().err
    assert "not an export bundle" in err and err.count("\n") == 1
    assert sorted(p.name for p in target.iterdir()) == ["notes.txt"]
    # an existing bundle is replaced, and nothing is left beside it
    assert main(["export", "marble-cube", "-o", str(tmp_path / "b")]) == 0
    assert main(["export", "marble-cube", "-o", str(tmp_path / "b")]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b", "mine"]


def test_export_of_a_bad_scene_writes_nothing(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[camera]\neye = [0, 1]\n")
    assert main(["export", str(bad), "-o", str(tmp_path / "out")]) == 2
    assert "bad.toml" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
