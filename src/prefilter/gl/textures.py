"""Float lookup tables as GL textures: the one upload every bake's table goes through."""

from __future__ import annotations

import moderngl
import numpy as np


def float_texture(
    ctx: moderngl.Context, data: np.ndarray, filter: int = moderngl.LINEAR, repeat_x: bool = False
) -> moderngl.Texture:
    """A (rows, columns, channels) or (columns, channels) float array as a 32-bit float texture of
    `columns` x `rows` texels (row 0 at v = 0), no MIP, clamped in y (and in x unless repeat_x)."""
    texels = np.ascontiguousarray(data, np.float32)
    if texels.ndim == 2:
        texels = texels[None]
    rows, columns, channels = texels.shape
    texture = ctx.texture((columns, rows), channels, texels.tobytes(), dtype="f4")
    texture.filter = (filter, filter)
    texture.repeat_x = repeat_x
    texture.repeat_y = False
    return texture
