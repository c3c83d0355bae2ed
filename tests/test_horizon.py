"""Horizon maps (Fournier 1992 §5, Fig. 12): slopes against a brute force, closed forms and a ray march."""

import time

import numpy as np
from oracles import bilinear

from prefilter.normals.horizon import horizon_slopes, visible

STEPS = ((0, 1), (0, -1), (1, 0), (-1, 0))  # (drow, dcol) of +X, -X, +Y, -Y


def brute_force(h, d_max):
    rows, cols = h.shape
    out = np.empty((rows, cols, 4))
    for i in range(rows):
        for j in range(cols):
            for c, (di, dj) in enumerate(STEPS):
                out[i, j, c] = max(
                    (h[(i + d * di) % rows, (j + d * dj) % cols] - h[i, j]) / d for d in range(1, d_max + 1)
                )
    return out


def test_horizon_slopes_match_brute_force_on_random_periodic_maps():
    h = np.random.default_rng(3).normal(size=(9, 13))
    np.testing.assert_allclose(horizon_slopes(h, 5), brute_force(h, 5), atol=1e-12)
    np.testing.assert_allclose(horizon_slopes(h), brute_force(h, 6), atol=1e-12)  # min(64, 13 // 2)
    np.testing.assert_allclose(horizon_slopes(h, 20), brute_force(h, 20), atol=1e-12)  # wraps past a tile


def test_flat_plane_has_zero_horizon():
    np.testing.assert_array_equal(horizon_slopes(np.full((8, 12), 3.7)), np.zeros((8, 12, 4)))


def test_spike_casts_height_over_distance_on_its_neighbours():
    h = np.zeros((32, 32))
    i0, j0, tall, d_max = 10, 20, 5.0, 8
    h[i0, j0] = tall
    want = np.zeros((32, 32, 4))
    want[i0, j0] = -tall / d_max  # every neighbour is lower; the farthest is the least steep drop
    for d in range(1, d_max + 1):
        want[i0, j0 - d, 0] = tall / d  # the spike is at +X
        want[i0, j0 + d, 1] = tall / d  # at -X
        want[i0 - d, j0, 2] = tall / d  # at +Y (rows grow with v)
        want[i0 + d, j0, 3] = tall / d  # at -Y
    np.testing.assert_allclose(horizon_slopes(h, d_max), want, atol=1e-12)


def _horizon_slopes_per_texel(h: np.ndarray, d_max: int, texels) -> np.ndarray:
    """The four horizon slopes of each (i, j) in `texels` by plain Python loops over the distances."""
    rows, cols = h.shape
    out = np.empty((len(texels), 4))
    for k, (i, j) in enumerate(texels):
        for channel, (di, dj) in enumerate(((0, 1), (0, -1), (1, 0), (-1, 0))):
            out[k, channel] = max(
                (h[(i + di * d) % rows, (j + dj * d) % cols] - h[i, j]) / d for d in range(1, d_max + 1)
            )
    return out


def test_horizon_slopes_are_vectorised():
    """Against a per-texel Python loop timed in the same run (a ratio, not an absolute time): the whole
    field costs less per texel than a tenth of the loop's (measured: about 1/190), and the slopes agree."""
    h = np.random.default_rng(0).random((256, 256))
    texels = [(i, j) for i in range(0, 256, 32) for j in range(0, 256, 32)]  # 64 texels
    start = time.perf_counter()
    looped = _horizon_slopes_per_texel(h, 64, texels)
    loop_per_texel = (time.perf_counter() - start) / len(texels)
    start = time.perf_counter()
    whole = horizon_slopes(h, 64)
    per_texel = (time.perf_counter() - start) / h.size
    np.testing.assert_allclose(whole[tuple(np.array(texels).T)], looped, atol=1e-12)
    assert per_texel < 0.1 * loop_per_texel, (per_texel, loop_per_texel)


def smooth_surface(n=32):
    x, y = np.meshgrid(np.arange(n) + 0.5, np.arange(n) + 0.5)
    k = 2 * np.pi / n
    return 3.0 * np.sin(k * x) * np.cos(k * y) + 1.5 * np.sin(k * (x + 2 * y) + 1.0)


def ray_margin(h, i, j, w, reach):
    """Ray slope minus the steepest slope to the surface along the ray (positive: the ray clears it).

    The ray leaves the texel centre in direction w; the march stops when |dx| or |dy| reaches `reach`.
    """
    rho = np.hypot(w[0], w[1])
    s_max = reach / max(abs(w[0]), abs(w[1])) * rho
    s = np.linspace(0.0, s_max, int(s_max * 16) + 1)[1:]
    x, y = j + 0.5 + s * w[0] / rho, i + 0.5 + s * w[1] / rho
    return w[2] / rho - np.max((bilinear(h, x, y) - h[i, j]) / s)


def test_visible_agrees_with_a_ray_march():
    h = smooth_surface()
    reach = 16
    horizon = horizon_slopes(h, reach)
    rng = np.random.default_rng(5)
    outcomes = []
    # Axis-aligned directions: the ray crosses texel centres at whole steps and the bilinear surface is
    # linear between them, so the march and the horizon test must agree wherever the margin is not a tie.
    for azimuth in (0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi):
        for elevation in np.radians([5.0, 20.0, 40.0, 60.0]):
            w = np.array([np.cos(azimuth) * np.cos(elevation), np.sin(azimuth) * np.cos(elevation), 0.0])
            w[2] = np.sin(elevation)
            w[np.abs(w) < 1e-12] = 0.0
            for i, j in rng.integers(0, 32, size=(40, 2)):
                margin = ray_margin(h, i, j, w, reach)
                if abs(margin) > 1e-9:
                    assert visible(horizon[i, j], w) == (margin > 0), (i, j, w, margin)
                    outcomes.append(margin > 0)
    assert 0.2 < np.mean(outcomes) < 0.8  # both answers are exercised
    # Off-axis directions where the answer is unambiguous: steep ones clear everything and directions
    # below the tangent plane are never visible. (Grazing diagonal rays are where Fournier's separable
    # test is only an approximation: it looks along X and Y, not along the ray.)
    checked = 0
    for w in ([0.2, 0.3, 0.93], [-0.25, 0.2, 0.95], [0.3, -0.3, 0.9], [0.5, 0.5, -0.1], [-0.6, 0.1, -0.02]):
        w = np.asarray(w) / np.linalg.norm(w)
        for i, j in rng.integers(0, 32, size=(40, 2)):
            margin = ray_margin(h, i, j, w, reach) if w[2] > 0 else -1.0
            if abs(margin) > 0.2:
                assert visible(horizon[i, j], w) == (margin > 0), (i, j, w, margin)
                checked += 1
    assert checked > 100


def test_visible_rules_and_broadcasting():
    hz = np.array([0.5, 1.0, -0.2, 0.3])  # +X, -X, +Y, -Y
    assert visible(hz, [1.0, 0.0, 0.6]) and not visible(hz, [1.0, 0.0, 0.4])
    assert visible(hz, [-1.0, 0.0, 1.1]) and not visible(hz, [-1.0, 0.0, 0.9])
    assert visible(hz, [0.0, 1.0, 0.01]) and not visible(hz, [0.0, -1.0, 0.2])
    assert visible(hz, [0.0, 0.0, 1.0]) and not visible(hz, [0.0, 0.0, 0.0])
    assert not visible(hz, [1.0, -2.0, 0.55])  # x passes (0.55 > 0.5), y fails (0.275 < 0.3)
    dirs = np.array([[1.0, 0.0, 0.6], [1.0, 0.0, 0.4], [0.0, 0.0, -1.0]])
    np.testing.assert_array_equal(visible(hz, dirs), [True, False, False])
    maps = np.broadcast_to(hz, (5, 7, 4))
    assert visible(maps, [1.0, 0.0, 0.6]).shape == (5, 7)
