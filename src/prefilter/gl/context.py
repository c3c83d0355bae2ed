"""The one place a GL context is made: standalone EGL (Mesa llvmpipe where there is no GPU).

See ../shared/STACK-NOTES.md (a): without backend="egl" moderngl tries X11 and fails headless.
`fine_derivatives()` probes once whether dFdx/dFdy of this context are fine (each row of a 2x2 quad
differences its own pixels; GLSL 3.30 and ES 3.00 leave coarse or fine to the implementation).
"""

from __future__ import annotations

import moderngl

from prefilter import PrefilterError

INSTALL_HINT = "apt-get install -y libegl1 libegl-mesa0 libgl1-mesa-dri libgl1"

_context: moderngl.Context | None = None
_fine_derivatives: bool | None = None


def gl_context() -> moderngl.Context:
    """Return the process-wide OpenGL 3.3+ core context, creating it on first use."""
    global _context
    if _context is None:
        try:
            ctx = moderngl.create_context(standalone=True, backend="egl", require=330)
        except Exception as exc:  # glcontext raises plain Exceptions with the EGL error text
            raise PrefilterError(
                f"cannot create an OpenGL 3.3 context through EGL ({exc}); install Mesa with: {INSTALL_HINT}"
            ) from exc
        if ctx.version_code < 330:
            raise PrefilterError(
                f"OpenGL {ctx.version_code} is too old (3.3 needed) on {ctx.info['GL_RENDERER']}; "
                f"{INSTALL_HINT}"
            )
        _context = ctx
        _probe_fine_derivatives(ctx)  # now, while no framebuffer or viewport of anyone else is bound
    return _context


def renderer_name() -> str:
    return gl_context().info["GL_RENDERER"]


_PROBE_VERT = """#version 330 core
void main() {
    gl_Position = vec4(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0, 0.0, 1.0);
}
"""
_PROBE_FRAG = """#version 330 core
out vec4 o_colour;
void main() {
    float v = gl_FragCoord.x * gl_FragCoord.x * (1.0 + gl_FragCoord.y);
    o_colour = vec4(dFdx(v), dFdy(v), 0.0, 1.0);
}
"""


def fine_derivatives() -> bool:
    """True if dFdx/dFdy are fine derivatives on 2x2 quads aligned to even pixel coordinates (probed
    once, when the context is made)."""
    gl_context()
    assert _fine_derivatives is not None
    return _fine_derivatives


def _probe_fine_derivatives(ctx: moderngl.Context) -> None:
    """Draw v = x^2 (1 + y) over 4x4 pixels (x, y = gl_FragCoord) and check that every pixel's dFdx is
    v(right) - v(left) of its own row's pixel pair, and dFdy likewise along its column."""
    global _fine_derivatives
    import numpy as np

    prog = ctx.program(vertex_shader=_PROBE_VERT, fragment_shader=_PROBE_FRAG)
    texture = ctx.texture((4, 4), 4, dtype="f4")
    fbo = ctx.framebuffer([texture])
    vao = ctx.vertex_array(prog, [])
    try:
        fbo.use()
        ctx.viewport = (0, 0, 4, 4)
        ctx.clear(0.0, 0.0, 0.0, 0.0)
        vao.render(moderngl.TRIANGLES, vertices=3)
        got = np.frombuffer(texture.read(), dtype=np.float32).reshape(4, 4, 4)  # [row y][column x]
    finally:
        for thing in (vao, fbo, texture, prog):
            thing.release()
    centre = np.arange(4) + 0.5
    x, y = centre[None, :], centre[:, None]
    left, bottom = x - (np.arange(4)[None, :] & 1), y - (np.arange(4)[:, None] & 1)
    want_x = (left + 1.0) ** 2 * (1.0 + y) - left**2 * (1.0 + y)
    want_y = x**2 * (1.0 + bottom + 1.0) - x**2 * (1.0 + bottom)
    _fine_derivatives = bool(
        np.allclose(got[..., 0], want_x, atol=1e-3) and np.allclose(got[..., 1], want_y, atol=1e-3)
    )
