"""Evaluate a GLSL expression over NumPy arrays, for shader unit tests against NumPy/SciPy oracles.

Each row of the inputs becomes one vertex; a vertex shader computes `result = EXPR` and transform
feedback writes it back (STACK-NOTES (a) 5: transform feedback writes zeros unless a framebuffer is
bound, so a 1x1 one is bound around the call). Samplers are bound from NumPy tables as float textures.
"""

from __future__ import annotations

import numpy as np

from prefilter.gl.context import gl_context
from prefilter.gl.program import build_program
from prefilter.gl.uniforms import bind_samplers, set_uniforms

_GLSL_TYPES = {1: "float", 2: "vec2", 3: "vec3", 4: "vec4"}


def glsl_eval(
    expr: str,
    inputs: dict[str, np.ndarray],
    out_components: int = 1,
    includes: tuple[str, ...] = (),
    target: str = "gl330",
    defines: dict[str, object] | None = None,
    uniforms: dict[str, object] | None = None,
    textures: dict[str, object] | None = None,
    prelude: str = "",
) -> np.ndarray:
    """Return EXPR evaluated for every row of `inputs` (arrays of shape (n,) or (n, k), k <= 4).

    `textures` maps sampler names to moderngl textures (bound to consecutive units);
    `prelude` is extra GLSL placed after the includes (helper functions, uniform declarations).
    Uniform values given as NumPy arrays are written as raw float32 bytes (transpose matrices first:
    GLSL is column-major).
    """
    ctx = gl_context()
    columns = {name: np.asarray(a, dtype=np.float32).reshape(len(a), -1) for name, a in inputs.items()}
    count = {len(a) for a in columns.values()}
    if len(count) != 1:
        raise ValueError(
            f"glsl_eval inputs have different lengths: { {k: len(v) for k, v in columns.items()} }"
        )
    n = count.pop()
    decls = "\n".join(f"in {_GLSL_TYPES[a.shape[1]]} {name};" for name, a in columns.items())
    source = "\n".join(
        [
            *(f'#include "{inc}"' for inc in includes),
            prelude,
            decls,
            f"out {_GLSL_TYPES[out_components]} result;",
        ]
        + ["void main() {", f"    result = {expr};", "    gl_Position = vec4(0.0, 0.0, 0.0, 1.0);", "}"]
    )
    fragment = "out vec4 fragColor;\nvoid main() { fragColor = vec4(0.0); }\n"
    program = build_program(ctx, source, fragment, target=target, defines=defines, varyings=("result",))
    set_uniforms(program, uniforms or {})
    bind_samplers(program, textures or {})
    present = [name for name in columns if name in program]  # the compiler drops unused inputs
    data = np.hstack([columns[name] for name in present]) if present else np.zeros((n, 1), np.float32)
    vbo = ctx.buffer(np.ascontiguousarray(data, dtype=np.float32).tobytes())
    fmt = " ".join(f"{columns[name].shape[1]}f" for name in present)
    vao = ctx.vertex_array(program, [(vbo, fmt, *present)] if present else [])
    out = ctx.buffer(reserve=n * out_components * 4)
    fbo = ctx.simple_framebuffer((1, 1))
    fbo.use()
    try:
        vao.transform(out, mode=ctx.POINTS, vertices=n)
        result = np.frombuffer(out.read(), dtype=np.float32).reshape(n, out_components).copy()
    finally:
        for obj in (vao, vbo, out, fbo, program):
            obj.release()
    return result[:, 0] if out_components == 1 else result
