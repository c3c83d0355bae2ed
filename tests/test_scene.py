"""Scene files: every preset parses; invalid files give one-line errors naming file and key path (exit 2)."""

from pathlib import Path

import pytest

from prefilter.cli import main
from prefilter.scene import SceneError, load_scene, preset_names, resolve_scene

VALID = """
name = "t"
size = [64, 48]
[camera]
eye = [0.0, 0.0, 3.0]
target = [0.0, 0.0, 0.0]
[[object]]
shape = "sphere"
[object.material]
type = "hart"
[object.material.colour_table]
stops = [[0.0, "#000000"], [1.0, "#ffffff"]]
"""


def test_every_preset_parses():
    names = preset_names()
    assert {
        "wood-teapot",
        "marble-teapot",
        "marble-cube",
        "seascape",
        "fire",
        "planet",
        "moonrise",
        "zone-plate",
        "wood-torus",
    } <= set(names)
    for name in names:
        scene = resolve_scene(name)
        assert scene.objects and scene.camera.fov > 0


def test_valid_minimal_scene(tmp_path):
    path = tmp_path / "ok.toml"
    path.write_text(VALID)
    scene = load_scene(path)
    assert scene.size == (64, 48) and scene.objects[0].shape == "sphere"


BAD = [
    ("name = \n", "TOML syntax error"),
    (VALID.replace("[camera]\neye = [0.0, 0.0, 3.0]\n", "[camera]\n"), "camera.eye: missing"),
    (
        VALID.replace("target = [0.0, 0.0, 0.0]", 'target = [0.0, 0.0, 0.0]\nfov = "wide"'),
        "camera.fov: expected a number",
    ),
    (VALID.replace('shape = "sphere"', 'shape = "prism"'), "object[0].shape: expected one of"),
    (VALID.replace('shape = "sphere"', 'shape = "sphere"\ncolour = 3'), "object[0].colour: unknown key"),
    (VALID.replace('"#ffffff"', '"#ffzzff"'), "object[0].material.colour_table.stops"),
    (VALID.replace("[[0.0,", "[[0.7,").replace("[1.0,", "[0.2,"), "object[0].material.colour_table.stops"),
    (VALID.replace("stops =", 'wrap = "clmp"\nstops ='), "colour_table.wrap: expected one of"),
    (VALID.replace("stops =", "size = 100\nstops ="), "colour_table.size: colour table size"),
    (
        VALID.replace("stops =", 'interpolation = "cubic"\nstops ='),
        "colour_table.interpolation: expected one of",
    ),
    (
        VALID.replace('type = "hart"', 'type = "hart"\n[object.material.fractal]\noctaves = 9'),
        "object[0].material.fractal.octaves",
    ),
    (
        VALID.replace('type = "hart"', 'type = "hart"\n[object.material.fractal]\nlacunarity = 1e9'),
        "object[0].material.fractal.lacunarity: octave 1's frequency scale exceeds",
    ),
    (
        VALID.replace('type = "hart"', 'type = "hart"\n[object.material.fractal]\ngain = 1e9'),
        "object[0].material.fractal.gain: octave 1's amplitude exceeds",
    ),
    (VALID.replace('shape = "sphere"', 'mesh = "nowhere.obj"'), "object[0].mesh: file not found"),
    (
        VALID.replace('shape = "sphere"', 'shape = "sphere"\nscale = [1.0, 0.0, 1.0]'),
        "object[0].scale: must be",
    ),
    (VALID.replace("eye = [0.0, 0.0, 3.0]", "eye = [0.0, 3.0, 0.0]"), "camera.up: must not be parallel"),
    (
        VALID.replace("eye = [0.0, 0.0, 3.0]", "eye = [0.0, 0.0, 3.0]\neye_end = [0.0, 3.0, 0.0]"),
        "camera.up: must not be parallel to the view direction (target - eye) at t = 1",
    ),
    (
        VALID.replace('shape = "sphere"', 'shape = "sphere"\nparams = { radious = 2.0 }'),
        "object[0].params: primitive 'sphere' has no parameter 'radious'",
    ),
    (VALID.replace("size = [64, 48]", "size = [64]"), "size: expected a list of 2 numbers"),
    (VALID.replace('type = "hart"', 'type = "velvet"'), "object[0].material.type: expected one of"),
]


@pytest.mark.parametrize("text,expected", BAD)
def test_invalid_scene_errors_name_the_key(tmp_path, capsys, text, expected):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    # named once: an error re-raised under an enclosing key had named the file and a wrong key first
    assert message.count(str(path)) == 1 and expected in message and "\n" not in message
    out = tmp_path / "out.png"
    assert main(["render", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("prefilter: error:") and expected in err[0]
    assert not out.exists()


def test_toml_syntax_error_names_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('name = "x"\n[camera\n')
    with pytest.raises(SceneError, match=r"line 2"):
        load_scene(path)


def test_unknown_preset_lists_presets():
    with pytest.raises(SceneError, match="wood-teapot"):
        resolve_scene("no-such-preset")


def test_missing_scene_file(tmp_path):
    with pytest.raises(SceneError, match="cannot read"):
        load_scene(Path(tmp_path) / "absent.toml")


def test_bad_primitive_values_name_the_file_and_object(tmp_path, capsys):
    """Values are checked when the mesh is built (at render), and the error still names the file and key."""
    path = tmp_path / "bad.toml"
    path.write_text(VALID.replace('shape = "sphere"', 'shape = "sphere"\nparams = { radius = -1.0 }'))
    load_scene(path)  # names are checked at load, values by the primitive
    out = tmp_path / "out.png"
    assert main(["render", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"prefilter: error: {path}: object[0].params: sphere: radius")
    assert not out.exists()


def test_an_unreadable_mesh_names_the_scene_file_and_key(tmp_path, capsys):
    (tmp_path / "empty.obj").write_text("")
    path = tmp_path / "bad.toml"
    path.write_text(VALID.replace('shape = "sphere"', 'mesh = "empty.obj"'))
    out = tmp_path / "out.png"
    assert main(["render", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"prefilter: error: {path}: object[0].mesh: mesh file")
    assert "contains no triangles" in err[0] and not out.exists()


def test_a_missing_asset_is_the_set_up_s_fault_not_the_scene_s(tmp_path, monkeypatch, capsys):
    """The teapot's asset missing is not a scene-file error: exit 1, no file key, and how to get it."""
    monkeypatch.setenv("PREFILTER_ASSETS", str(tmp_path / "elsewhere"))
    path = tmp_path / "teapot.toml"
    path.write_text(VALID.replace('shape = "sphere"', 'shape = "teapot"\nname = "pot"'))
    out = tmp_path / "out.png"
    assert main(["render", str(path), "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    asset = tmp_path / "elsewhere" / "teapot.obj"
    assert err == [f"prefilter: error: object 'pot': Utah teapot asset missing at {asset}; run: make setup"]
    assert not out.exists()
