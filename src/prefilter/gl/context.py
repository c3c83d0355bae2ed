"""The one place a GL context is made: standalone EGL (Mesa llvmpipe where there is no GPU).

See ../shared/STACK-NOTES.md (a): without backend="egl" moderngl tries X11 and fails headless.
"""

from __future__ import annotations

import moderngl

from prefilter import PrefilterError

INSTALL_HINT = "apt-get install -y libegl1 libegl-mesa0 libgl1-mesa-dri libgl1"

_context: moderngl.Context | None = None


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
    return _context


def renderer_name() -> str:
    return gl_context().info["GL_RENDERER"]
