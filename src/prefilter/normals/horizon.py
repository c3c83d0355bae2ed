"""Horizon maps for shadowing and masking: Fournier 1992 §5 and Fig. 12.

"For the X and Y axes in texture space and for each texel the slope of the horizon in both directions
(left (negative X), right (positive X), top (negative Y) and bottom (positive Y)) is computed and stored
as a map". While rendering the unfiltered texture, a direction whose slope in the XZ (YZ) plane is below
the stored horizon slope is shadowed (light) or masked (eye); the filtered version (per-peak mean and
standard deviation of these slopes, a linear ramp between mean - std and mean + std) is built in
normals/pyramid.py.

Conventions are those of normals/normal_maps.py: heights (H, W) indexed [row, column] = [y, x] in texel
widths, +X = increasing column (u), +Y = increasing row (v; Fournier's "top"/"bottom" name image rows,
here only the signs matter), maps tile periodically.

- horizon_slopes: channels (+X, -X, +Y, -Y); for texel p and axis direction e,
  max over d = 1..D of (h[p + d e] - h[p]) / d, D = min(64, max(W, H) // 2) by default. A texel above
  all its neighbours gets a negative slope (its horizon lies below the tangent plane).
- visible: the binary test of the unfiltered renderer, the NumPy reference for its GLSL version.
"""

from __future__ import annotations

import numpy as np

CHANNELS = ("+X", "-X", "+Y", "-Y")


def default_distance(width: int, height: int) -> int:
    """The default horizon search radius D in texels: min(64, max(W, H) // 2), at least 1."""
    return max(1, min(64, max(width, height) // 2))


def horizon_slopes(heights: np.ndarray, max_distance: int | None = None) -> np.ndarray:
    """(H, W, 4) float64 horizon slopes (+X, -X, +Y, -Y) of periodic heights (texel widths)."""
    h = np.asarray(heights, dtype=np.float64)
    if h.ndim != 2 or h.size == 0:
        raise ValueError(f"expected (H, W) heights, got shape {h.shape}")
    d_max = default_distance(h.shape[1], h.shape[0]) if max_distance is None else int(max_distance)
    if d_max < 1:
        raise ValueError(f"max_distance must be at least 1, got {max_distance}")
    out = np.full(h.shape + (4,), -np.inf)
    # (channel, axis, roll sign): np.roll(h, -d, axis)[p] = h[p + d] along that axis
    for channel, axis, sign in ((0, 1, -1), (1, 1, 1), (2, 0, -1), (3, 0, 1)):
        best = out[..., channel]
        for d in range(1, d_max + 1):
            np.maximum(best, (np.roll(h, sign * d, axis=axis) - h) / d, out=best)
    return out


def visible(horizon, direction):
    """Whether tangent-space direction(s) w (towards the light or the eye) clear the texel's horizon.

    horizon (..., 4) as from horizon_slopes, direction (..., 3), broadcast together. For the x axis:
    if w.x > 0 the slope w.z / w.x must exceed horizon[+X], if w.x < 0 then w.z / -w.x must exceed
    horizon[-X], and w.x = 0 sets no constraint; the same for y with +-Y. Both axes must pass, and
    w.z <= 0 is never visible. Returns a bool, or a bool array for batched inputs.
    """
    hz = np.asarray(horizon, dtype=np.float64)
    w = np.asarray(direction, dtype=np.float64)
    wx, wy, wz = w[..., 0], w[..., 1], w[..., 2]
    # w.z / |w.x| > slope  <=>  w.z > slope |w.x|  (no division)
    ok_x = np.where(wx > 0, wz > hz[..., 0] * wx, np.where(wx < 0, wz > hz[..., 1] * -wx, True))
    ok_y = np.where(wy > 0, wz > hz[..., 2] * wy, np.where(wy < 0, wz > hz[..., 3] * -wy, True))
    result = (wz > 0) & ok_x & ok_y
    return bool(result) if result.ndim == 0 else result
