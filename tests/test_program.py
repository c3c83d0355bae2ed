"""GLSL assembler: includes, source map, error mapping, targets."""

import pytest

from prefilter.gl.context import gl_context
from prefilter.gl.program import ShaderError, assemble, build_program

FRAG = "out vec4 c;\nvoid main() { c = vec4(nz_noise(vec3(gl_FragCoord.xy, 0.5))); }\n"
VERT = "void main() { gl_Position = vec4(0.0, 0.0, 0.0, 1.0); }\n"


@pytest.mark.parametrize("target", ["gl330", "gl450", "es300"])
@pytest.mark.parametrize("line_directives", [False, True])
def test_assembled_sources_compile_for_every_target(target, line_directives):
    body = '#include "glsl/common/noise.glsl"\n' + FRAG
    source = assemble(body, target, {"ANSWER": 42, "SCALE": 2.0}, "fragment", line_directives).source
    assert source.startswith("#version")
    assert "#define SCALE 2.0" in source and "#define ANSWER 42" in source
    assert ("#line" in source) == line_directives
    ctx = gl_context()
    ctx.program(vertex_shader=assemble(VERT, target).source, fragment_shader=source).release()


def test_each_file_is_included_once(tmp_path):
    (tmp_path / "a.glsl").write_text('#include "b.glsl"\nfloat a() { return b(); }\n')
    (tmp_path / "b.glsl").write_text("float b() { return 1.0; }\n")
    main = tmp_path / "main.glsl"
    main.write_text(
        '#include "a.glsl"\n#include "b.glsl"\n' + "out vec4 c;\nvoid main() { c = vec4(a()); }\n"
    )
    assembled = assemble(main)
    assert assembled.source.count("float b()") == 1
    line = assembled.source.splitlines().index("float a() { return b(); }") + 1
    assert assembled.locate(line) == (str(tmp_path / "a.glsl"), 2)


def test_missing_and_recursive_includes_name_file_and_line(tmp_path):
    main = tmp_path / "main.glsl"
    main.write_text('float x;\n#include "absent.glsl"\n')
    with pytest.raises(ShaderError, match=r"main\.glsl:2: .*absent\.glsl"):
        assemble(main)
    (tmp_path / "p.glsl").write_text('#include "q.glsl"\n')
    (tmp_path / "q.glsl").write_text('#include "p.glsl"\n')
    assert "float" not in assemble(tmp_path / "p.glsl").source  # included once: the cycle stops


def test_es300_rules_are_enforced():
    """Implicit int -> float is legal in 330 core and an error in ES 3.00 (STACK-NOTES (b))."""
    bad = "out vec4 c;\nvoid main() {\n    float f = 1;\n    c = vec4(f);\n}\n"
    ctx = gl_context()
    build_program(ctx, VERT, bad, target="gl330").release()
    with pytest.raises(ShaderError, match=r"<inline>:3: "):
        build_program(ctx, VERT, bad, target="es300")


def test_unknown_target():
    with pytest.raises(ShaderError, match="unknown GLSL target"):
        assemble("void main() {}", "gl999")
