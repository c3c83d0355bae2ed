"""@param / @table annotations on GLSL uniforms: parsed from assembled sources, errors name file and line."""

import pytest

from prefilter.gl.annotations import parameter, referenced_uniforms, table_description, uniform_declarations
from prefilter.gl.program import ShaderError, assemble

SOURCE = """\
uniform float u_exposure;  // @param 0.5..16 log Exposure: multiplies the radiance
uniform vec3 u_albedo;  // @param 0..1 colour Albedo
uniform highp float u_amp[PT_ARRAY_SIZE];  // @param -2..2 Amplitudes: one per noise term
uniform sampler2D u_table;  // @table u: f mapped by u_range; v: sigma / u_range.z
uniform int u_count;  // a plain comment
"""


def _declarations(text: str):
    return uniform_declarations(assemble(text, "gl330"))


def test_declarations_and_parameters_are_parsed():
    d = _declarations(SOURCE)
    assert set(d) == {"u_exposure", "u_albedo", "u_amp", "u_table", "u_count"}
    assert d["u_amp"].array == "PT_ARRAY_SIZE" and d["u_amp"].type == "float"
    exposure = parameter(d["u_exposure"])
    assert (exposure.lo, exposure.hi, exposure.log, exposure.label) == (0.5, 16.0, True, "Exposure")
    assert exposure.description == "multiplies the radiance"
    albedo = parameter(d["u_albedo"])
    assert albedo.colour and not albedo.log and albedo.description == ""
    assert parameter(d["u_amp"]).lo == -2.0
    assert parameter(d["u_count"]) is None and parameter(d["u_table"]) is None
    text = table_description(d["u_table"])
    assert text.startswith("u: f mapped")
    assert referenced_uniforms(text, {"u_range", "u_other"}) == ["u_range"]


@pytest.mark.parametrize(
    "line, problem",
    [
        ("uniform float u_x;  // @param 1 to 2 X", "malformed"),
        ("uniform float u_x;  // @param 2..1 X", "MIN < MAX"),
        ("uniform float u_x;  // @param 0..1 log X", "MIN > 0"),
        ("uniform float u_x;  // @param 0..1 colour X", "needs a vec3"),
        ("uniform mat4 u_x;  // @param 0..1 X", "cannot be a parameter"),
    ],
)
def test_malformed_annotations_name_file_and_line(line, problem):
    (u,) = _declarations("// first line\n" + line + "\n").values()
    with pytest.raises(ShaderError) as info:
        parameter(u)
    assert str(info.value).startswith("<inline>:2: ") and problem in str(info.value)


def test_empty_table_annotation_is_an_error():
    (u,) = _declarations("uniform sampler2D u_t;  // @table\n").values()
    with pytest.raises(ShaderError, match="empty @table"):
        table_description(u)
