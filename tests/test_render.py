"""Renderer and commands: every preset renders in every mode; the reference is a box-filtered mean;
compile errors name the real file and line; outputs are written only on success."""

import json

import numpy as np
import pytest

from prefilter.cli import main
from prefilter.gl.context import gl_context
from prefilter.gl.program import ShaderError, build_program
from prefilter.gl.render import REFERENCE, Renderer, RenderOptions, composite, coverage_mask, scene_modes
from prefilter.images import read_image
from prefilter.scene import preset_names, resolve_scene

SMALL = (64, 48)
SMOKE = (32, 24)  # the every-mode smoke test: a quarter of SMALL's fragments (xenopeltis: 41 s at SMALL)


@pytest.mark.parametrize("name", preset_names())
def test_every_preset_renders_in_every_mode(name):
    scene = resolve_scene(name)
    renderer = Renderer(scene, SMOKE)
    try:
        reference = renderer.reference(spp=1)  # one jittered pass: accumulation is tested below
        assert np.isfinite(reference).all()
        assert coverage_mask(reference).any(), "no fully covered pixel"
        for mode in scene_modes(scene, diagnostics=True):
            image = renderer.render(mode)
            assert image.shape == (SMOKE[1], SMOKE[0], 4)
            assert np.isfinite(image).all(), mode
            assert image[..., 3].max() > 0.99, f"{mode}: nothing drawn"
            assert image[..., :3].std() > 1e-3, f"{mode}: flat image"
    finally:
        renderer.release()


@pytest.mark.parametrize("name", preset_names())
def test_every_program_compiles_as_es300(name):
    scene = resolve_scene(name)
    renderer = Renderer(scene, SMALL, target="es300")
    try:
        for mode in scene_modes(scene, diagnostics=True):
            for gpu in renderer.objects:
                gpu.program(mode)
        mode = (scene.technique_modes() or ["point"])[-1]  # gaussian, surface-filter, multilobe, point
        es = renderer.render(mode)
    finally:
        renderer.release()
    desktop = Renderer(scene, SMALL)
    try:
        np.testing.assert_allclose(es, desktop.render(mode), atol=1e-4)
    finally:
        desktop.release()


def test_reference_of_a_constant_region_is_the_constant():
    """On a pixel-aligned orthographic plane with a flat colour table every sample agrees."""
    scene = resolve_scene("zone-plate")
    renderer = Renderer(scene, (32, 32))
    try:
        point = renderer.render("point")
        reference = renderer.reference(spp=16)
    finally:
        renderer.release()
    mask = coverage_mask(reference)
    assert mask.mean() > 0.9
    # the zebra is black or white at every point sample; the reference averages them
    assert set(np.unique(np.round(point[..., 0], 6))) <= {0.0, 1.0}
    assert 0.0 < reference[..., 0][mask].mean() < 1.0


def test_zone_plate_reference_is_the_box_filtered_analytic_zebra():
    """Oracle: the zone plate's exact box-filtered colour, by dense quadrature over each pixel in NumPy."""
    scene = resolve_scene("zone-plate")
    size = 32
    renderer = Renderer(scene, (size, size))
    try:
        reference = renderer.reference(spp=256)
    finally:
        renderer.release()
    # pixel (i, j) covers s in [i/size, (i+1)/size], t = 1 - row; f = 50 s^2 + 50 t^2,
    # white where fract(f) >= 1/2
    k = 64
    u = (np.arange(k) + 0.5) / k
    s = (np.arange(size)[None, :, None, None] + u[None, None, :, None]) / size
    t = 1.0 - (np.arange(size)[:, None, None, None] + u[None, None, None, :]) / size
    f = 50 * s**2 + 50 * t**2
    expected = (np.mod(f, 1.0) >= 0.5).mean(axis=(2, 3))
    err = np.abs(reference[..., 0] - expected)
    assert np.median(err) < 0.02 and err.mean() < 0.03


def test_filtered_modes_beat_point_on_the_zone_plate():
    scene = resolve_scene("zone-plate")
    renderer = Renderer(scene, (128, 128))
    try:
        ref = composite(renderer.reference(spp=64), scene.background)
        errors = {
            m: np.abs(composite(renderer.render(m), scene.background) - ref).mean()
            for m in ("point", "hart-mip", "hart-sat", "hart-sat-aniso")
        }
    finally:
        renderer.release()
    for mode in ("hart-mip", "hart-sat", "hart-sat-aniso"):
        assert errors[mode] < 0.5 * errors["point"], errors


def test_shader_compile_error_names_real_file_and_line(tmp_path):
    broken = tmp_path / "broken.glsl"
    broken.write_text("float ok() { return 1.0; }\nfloat bad() { return undefined_thing; }\n")
    source = f'#include "{broken}"\nout vec4 c;\nvoid main() {{ c = vec4(bad()); }}\n'
    with pytest.raises(ShaderError, match=r"broken\.glsl:2: .*undefined_thing"):
        build_program(gl_context(), "void main() { gl_Position = vec4(0.0); }", source)


def test_render_command_png_exr_and_frames(tmp_path):
    png, exr = tmp_path / "a.png", tmp_path / "a.exr"
    assert main(["render", "zone-plate", "--mode", "hart-sat", "--size", "32x32", "-o", str(png)]) == 0
    assert (
        main(["render", "zone-plate", "--mode", "reference", "--spp", "4", "--size", "32x32", "-o", str(exr)])
        == 0
    )
    image, meta = read_image(exr)
    assert image.shape == (32, 32, 3) and meta["mode"] == REFERENCE and meta["spp"] == 4
    assert main(["render", "fire", "--frames", "3", "--size", "24x32", "-o", str(tmp_path / "f.png")]) == 0
    frames = [read_image(tmp_path / f"f_{k:04d}.png")[0] for k in range(3)]
    assert np.abs(frames[0] - frames[2]).mean() > 1e-3, "the fire phase should animate"


def test_a_frame_sequence_that_fails_to_write_leaves_no_frames(tmp_path, capsys, monkeypatch):
    """Each frame is written atomically, but a failure at the third (a full disk) had left the first two."""
    import prefilter.images

    real, calls = prefilter.images.write_image, []

    def failing(path, *args, **kwargs):
        calls.append(path)
        if len(calls) == 3:
            raise OSError(28, "No space left on device")
        return real(path, *args, **kwargs)

    monkeypatch.setattr(prefilter.images, "write_image", failing)
    assert main(["render", "fire", "--frames", "4", "--size", "16x16", "-o", str(tmp_path / "f.png")]) == 1
    assert len(calls) == 3 and not list(tmp_path.iterdir())
    assert capsys.readouterr().err.strip() == "prefilter: error: [Errno 28] No space left on device"


def test_running_out_of_memory_is_one_line(tmp_path, capsys, monkeypatch):
    """A render too large for the machine (8192 x 8192 peaks at about 11 GiB) had ended in a traceback."""
    import prefilter.gl.render

    def no_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(prefilter.gl.render.Renderer, "render", no_memory)
    assert main(["render", "zone-plate", "--size", "16x16", "-o", str(tmp_path / "x.png")]) == 1
    assert capsys.readouterr().err.strip().splitlines() == [
        "prefilter: error: out of memory; try a smaller --size (or --spp)"
    ]
    assert not list(tmp_path.iterdir())


def test_render_rejects_bad_mode_and_extension(tmp_path, capsys):
    assert main(["render", "zone-plate", "--mode", "blurry", "-o", str(tmp_path / "x.png")]) == 1
    assert "--mode blurry" in capsys.readouterr().err
    assert main(["render", "zone-plate", "-o", str(tmp_path / "x.gif")]) == 1
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    "command",
    [
        ["render", "zone-plate", "--size", "16x16", "-o", "{blocked}/x.png"],
        ["compare", "zone-plate", "--size", "16x16", "--spp", "1", "-o", "{blocked}/cmp"],
        ["export", "zone-plate", "-o", "{blocked}/exp"],
        ["bench", "zone-plate", "--quick", "--json", "{blocked}/b.json"],
        ["bench", "zone-plate", "--quick", "--json", "{ok}/b.json", "--plots", "{blocked}/plots"],
    ],
)
def test_an_output_that_cannot_be_written_fails_before_rendering(tmp_path, capsys, command):
    """A file where a directory should be: one line naming the output, exit 1, nothing written (it had been a
    traceback from the writer's temporary file, after the rendering)."""
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    argv = [a.format(blocked=blocker / "sub", ok=tmp_path / "ok") for a in command]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("prefilter: error:") and str(blocker) in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["render", "zone-plate", "--mode", "reference", "--spp", "5", "-o", "x.png"], "nearest 4 or 9"),
        (["bench", "zone-plate", "--spp", "1000"], "nearest 961 or 1024"),
        (["render", "marble-cube", "--quant-bits", "25", "-o", "x.png"], "expected 1..24 bits"),
        (["view", "--port", "70000"], "expected a TCP port 0..65535"),
        # it had been checked after the scene was read and its first object announced
        (
            ["bake", "normals-denim-plane", "--scheduler", "thread"],
            "expected synchronous, threads, processes",
        ),
    ],
)
def test_arguments_out_of_range_are_refused_by_the_parser(argv, expected, tmp_path, capsys, monkeypatch):
    """A non-square --spp had been rounded to (round √spp)² without a word, --quant-bits 2000 overflowed in
    the Hart material's uniforms, --port 70000 was a traceback from bind(), and a misspelt --scheduler was
    found only once the bake had started."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    assert expected in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("flag", [["--quant-bits", "8"], ["--reduced"], ["--first-order"]])
def test_hart_options_on_a_scene_without_hart_textures_are_refused(flag, tmp_path, capsys):
    """They had been ignored: the image was the same with or without them."""
    assert main(["render", "micro-heights-sphere", *flag, "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{flag[0]}: micro-heights-sphere has no Hart solid texture" in err[0], err
    assert not list(tmp_path.iterdir())


def test_compare_replaces_an_earlier_comparison_and_nothing_else(tmp_path, capsys):
    """write_comparison replaces its -o directory whole: it had deleted any directory given to it, the user's
    files included (and failed with a bare errno message on a file)."""
    precious = tmp_path / "mine"
    precious.mkdir()
    (precious / "notes.txt").write_text("keep me")
    a_file = tmp_path / "a-file"
    a_file.write_text("keep me too")
    for target in (precious, a_file):
        argv = ["compare", "zone-plate", "--size", "16x16", "--spp", "1", "-o", str(target)]
        assert main(argv) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [
            f"prefilter: error: {target}: exists and is not a comparison directory; choose another -o"
            " directory"
        ]
    assert (precious / "notes.txt").read_text() == "keep me" and a_file.read_text() == "keep me too"
    out = tmp_path / "cmp"
    for size in ("16x16", "24x24"):  # the second run replaces the first's directory
        assert main(["compare", "zone-plate", "--size", size, "--spp", "1", "-o", str(out)]) == 0
    assert json.loads((out / "report.json").read_text())["size"] == [24, 24]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file", "cmp", "mine"]


def test_compare_command_writes_report(tmp_path):
    out = tmp_path / "cmp"
    assert main(["compare", "zone-plate", "--size", "48x48", "--spp", "16", "-o", str(out)]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["scene"] == "zone-plate" and report["size"] == [48, 48] and report["reference_spp"] == 16
    assert set(report["modes"]) >= {"point", "naive", "hart-mip", "hart-sat", REFERENCE}
    for entry in report["modes"].values():
        assert set(entry) >= {"flip", "delta_e", "rmse", "ms"}
    for name in ("strip.png", "flip.png", "report.md", "reference.exr", "hart-width.png"):
        assert (out / name).is_file()


def test_quantisation_and_reduced_model_change_the_image():
    scene = resolve_scene("marble-teapot")
    images = {}
    for key, options in {
        "full": None,
        "q6": RenderOptions(quant_bits=6),
        "reduced": RenderOptions(reduced=True),
    }.items():
        renderer = Renderer(scene, SMALL, options=options)
        try:
            images[key] = renderer.render("hart-sat")
        finally:
            renderer.release()
    assert np.abs(images["q6"] - images["full"]).mean() > 1e-3
    assert np.abs(images["reduced"] - images["full"]).mean() > 1e-3


_SPHERE_OVER_PLANE = """
name = "sphere-over-plane"
size = [96, 72]
background = "#000000"
[camera]
eye = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
fov = 40.0
[[object]]
name = "wall"
shape = "plane"
params = { size = 8.0 }
rotate = [90.0, 0.0, 0.0]
translate = [0.0, 0.0, -1.0]
lit = false
[object.material]
type = "hart"
quadric = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.25]
[object.material.colour_table]
stops = [[0.0, "#336699"], [1.0, "#336699"]]
[[object]]
name = "ball"
shape = "sphere"
params = { radius = 0.8 }
lit = false
[object.material]
type = "hart"
quadric = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.75]
[object.material.colour_table]
stops = [[0.0, "#cc8844"], [1.0, "#cc8844"]]
"""


def test_covered_pixels_leave_out_the_edges_between_objects(tmp_path):
    """Oracle: the ball alone, whose reference alpha is its geometric coverage. With the wall behind it every
    pixel is fully covered, but those the ball covers partly (its silhouette over the wall) are excluded,
    and no others."""
    from dataclasses import replace

    from prefilter.scene import load_scene

    path = tmp_path / "scene.toml"
    path.write_text(_SPHERE_OVER_PLANE)
    scene = load_scene(path)
    both = Renderer(scene)
    ball = Renderer(replace(scene, objects=[scene.objects[1]]))
    try:
        reference = both.reference(256)
        covered = both.covered(reference, 256)
        ball_alpha = ball.reference(256)[..., 3]
    finally:
        both.release()
        ball.release()
    assert coverage_mask(reference).all()
    edge = (ball_alpha > 1e-4) & (ball_alpha < 1 - 1e-4)
    assert edge.sum() > 50  # the silhouette is there
    np.testing.assert_array_equal(covered, ~edge)


def test_time_rounds_gives_one_time_per_round_and_more_pixels_take_longer():
    """Renderer.time_rounds: one wall time per round and mode; 64 x the fragments of the same shader take
    longer, and time_modes is the median of such rounds."""
    scene = resolve_scene("noise-plane")
    times = {}
    for size in ((32, 32), (256, 256)):
        renderer = Renderer(scene, size)
        try:
            times[size] = renderer.time_rounds(["point", "naive"], frames=5)
            medians = renderer.time_modes(["point"], frames=5)
        finally:
            renderer.release()
        assert all(len(v) == 5 and min(v) > 0.0 for v in times[size].values())
        assert set(medians) == {"point"} and medians["point"] > 0.0
    renderer = Renderer(scene, (32, 32))
    try:  # time_modes takes the median of whatever rounds time_rounds gives
        renderer.time_rounds = lambda modes, *args: {m: [3.0, 1.0, 2.0, 5.0, 4.0] for m in modes}
        assert renderer.time_modes(["point", "naive"]) == {"point": 3.0, "naive": 3.0}
    finally:
        renderer.release()
    for mode in ("point", "naive"):
        assert np.median(times[(256, 256)][mode]) > np.median(times[(32, 32)][mode])
