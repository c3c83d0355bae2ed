"""The wavelength-preintegrated fast path: XYZ(u, v, w) = Σ_λ |P̃(k u, k v; k w)|² x (D65 x CIE 1931).

Dhillon et al. 2014 take the wavelength loop out of the pixel shader by integrating the |Σ|² cross terms
of the Taylor series over 380-780 nm into 2N + 1 tables over (u, v), combined per pixel by powers of w.
Those products of large terms cancel down to |P̃|² ≤ 1 (for the snake ridges, terms of 1e4 and more), which
float32 tables cannot carry. We preintegrate the same quantity one step later instead: the spectrally
integrated power itself, a function of (u, v, w) alone, tabulated on a 3D grid — u, v in [-2, 2],
w in [-2, 0], texel centres on the grid points — and read with one trilinear lookup. The wavelength-
independent gain (Fresnel, G / w², 2 cos²θ1) is applied per pixel (stam.glsl `df_fastReflectance`).

The table is baked on the GPU by the accurate path's own GLSL (`df_spectralXYZ`), one w-slice per pass,
and cached by content. Its resolution bounds the narrowest lobe it can hold: lobes are about 1 / (k σ)
wide in u and v, so σ up to a few µm (the presets) needs 256 samples per axis; σ = 16 µm would need
thousands, and the accurate path is then the one to use.
"""

from __future__ import annotations

import numpy as np

from prefilter.gl.program import build_program
from prefilter.gl.render import FULLSCREEN_TRIANGLE_VERT
from prefilter.gl.uniforms import bind_samplers, set_uniforms

DEFAULT_SIZE = (256, 256, 32)  # u, v, w samples

_FRAG = """
#include "diffraction/stam.glsl"
uniform vec3 u_tableSize;
uniform float u_slice;
out vec4 o_xyz;
void main() {
    vec3 grid = vec3(floor(gl_FragCoord.xy), u_slice) / (u_tableSize - 1.0);
    vec3 uvw = vec3(-2.0, -2.0, -2.0) + grid * vec3(4.0, 4.0, 2.0);
    o_xyz = vec4(df_spectralXYZ(uvw), 1.0);
}
"""


def bake_fast_table(ctx, textures: dict, uniforms: dict, size=DEFAULT_SIZE) -> np.ndarray:
    """(w samples, v samples, u samples, 4) float32: XYZ (and 1) of the spectrally integrated power."""
    nu, nv, nw = size
    prog = build_program(ctx, FULLSCREEN_TRIANGLE_VERT, _FRAG, target="gl330")
    vao = ctx.vertex_array(prog, [])
    target = ctx.texture((nu, nv), 4, dtype="f4")
    fbo = ctx.framebuffer([target])
    out = np.empty((nw, nv, nu, 4), np.float32)
    try:
        bind_samplers(prog, textures)
        set_uniforms(prog, {**uniforms, "u_tableSize": (float(nu), float(nv), float(nw))})
        fbo.use()
        ctx.viewport = (0, 0, nu, nv)
        ctx.disable(ctx.BLEND | ctx.DEPTH_TEST)
        for k in range(nw):
            prog["u_slice"].value = float(k)
            vao.render(vertices=3)
            out[k] = np.frombuffer(target.read(), np.float32).reshape(nv, nu, 4)
    finally:
        fbo.release()
        target.release()
        vao.release()
        prog.release()
    return out
