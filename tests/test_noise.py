"""Perlin's improved noise (prefilter.procedural.noise) and its GLSL twin (glsl/common/noise.glsl).

Oracles: Perlin's published value at (3.14, 42, 7); a line-by-line scalar transliteration of his Java
ImprovedNoise (doubled 512-entry table, grad() by bit tests); zeros and unit-lattice gradients on integer
points; period 256; the bound |n| <= 1.5; central finite differences; float64 NumPy for the shaders.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from prefilter.gl.evaluate import glsl_eval
from prefilter.procedural.noise import (
    PERMUTATION,
    footprint_curvature,
    linear_noise,
    linear_noise_grad,
    perlin_noise,
    perlin_noise_grad,
)

NOISE_GLSL = ("glsl/common/noise.glsl",)
VARIANTS = {
    "perlin": (perlin_noise, perlin_noise_grad),
    "linear": (linear_noise, linear_noise_grad),
}


# --- an independent scalar oracle: Perlin's Java code, transliterated ----------------------------------

_P512 = list(PERMUTATION) * 2


def _java_fade(t: float) -> float:
    return t * t * t * (t * (t * 6 - 15) + 10)


def _java_lerp(t: float, a: float, b: float) -> float:
    return a + t * (b - a)


def _java_grad(hash_: int, x: float, y: float, z: float) -> float:
    h = hash_ & 15
    u = x if h < 8 else y
    v = y if h < 4 else (x if h in (12, 14) else z)
    return (u if (h & 1) == 0 else -u) + (v if (h & 2) == 0 else -v)


def _java_noise(x: float, y: float, z: float, fade=_java_fade) -> float:
    p = _P512
    X, Y, Z = math.floor(x) & 255, math.floor(y) & 255, math.floor(z) & 255
    x -= math.floor(x)
    y -= math.floor(y)
    z -= math.floor(z)
    u, v, w = fade(x), fade(y), fade(z)
    A = p[X] + Y
    AA = p[A] + Z
    AB = p[A + 1] + Z
    B = p[X + 1] + Y
    BA = p[B] + Z
    BB = p[B + 1] + Z
    lerp, grad = _java_lerp, _java_grad
    return lerp(
        w,
        lerp(
            v,
            lerp(u, grad(p[AA], x, y, z), grad(p[BA], x - 1, y, z)),
            lerp(u, grad(p[AB], x, y - 1, z), grad(p[BB], x - 1, y - 1, z)),
        ),
        lerp(
            v,
            lerp(u, grad(p[AA + 1], x, y, z - 1), grad(p[BA + 1], x - 1, y, z - 1)),
            lerp(u, grad(p[AB + 1], x, y - 1, z - 1), grad(p[BB + 1], x - 1, y - 1, z - 1)),
        ),
    )


# --- Python float64 reference -------------------------------------------------------------------------


def test_permutation_is_a_permutation_of_0_to_255():
    assert len(PERMUTATION) == 256
    assert sorted(PERMUTATION) == list(range(256))
    assert PERMUTATION[:6] == (151, 160, 137, 91, 90, 15) and PERMUTATION[-3:] == (61, 156, 180)


def test_perlin_reference_value():
    value = perlin_noise(np.array([3.14, 42.0, 7.0]))
    assert value.shape == ()
    assert abs(value - 0.13691995878) < 1e-10
    assert value == pytest.approx(0.13691995878400012, abs=1e-16)  # the Java double, to the last bit


@pytest.mark.parametrize("variant", ["perlin", "linear"])
def test_matches_scalar_transliteration_of_java(variant):
    rng = np.random.default_rng(7)
    p = np.concatenate([rng.uniform(-600.0, 600.0, (150, 3)), rng.uniform(-2.0, 2.0, (50, 3))])
    fade = _java_fade if variant == "perlin" else (lambda t: t)
    expected = np.array([_java_noise(*map(float, q), fade=fade) for q in p])
    noise, noise_grad = VARIANTS[variant]
    np.testing.assert_array_equal(noise(p), expected)
    np.testing.assert_array_equal(noise_grad(p)[0], expected)


@pytest.mark.parametrize("variant", ["perlin", "linear"])
def test_shapes(variant):
    noise, noise_grad = VARIANTS[variant]
    p = np.zeros((4, 5, 3)) + 0.25
    assert noise(p).shape == (4, 5)
    value, grad = noise_grad(p)
    assert value.shape == (4, 5) and grad.shape == (4, 5, 3)
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        noise(np.zeros((4, 2)))


@pytest.mark.parametrize("variant", ["perlin", "linear"])
def test_zero_on_lattice_points(variant):
    rng = np.random.default_rng(1)
    p = rng.integers(-1000, 1000, (500, 3)).astype(np.float64)
    noise, noise_grad = VARIANTS[variant]
    assert np.all(noise(p) == 0.0)
    assert np.all(noise_grad(p)[0] == 0.0)


def test_perlin_gradient_on_lattice_points_is_a_cube_edge_vector():
    # fade'(0) = 0, so at a lattice point the gradient is that corner's gradient: two components +-1, one 0
    rng = np.random.default_rng(2)
    _, grad = perlin_noise_grad(rng.integers(-1000, 1000, (500, 3)).astype(np.float64))
    assert np.all(np.isin(grad, (-1.0, 0.0, 1.0)))
    np.testing.assert_array_equal(np.count_nonzero(grad, axis=-1), 2)


@pytest.mark.parametrize("variant", ["perlin", "linear"])
def test_period_256(variant):
    rng = np.random.default_rng(3)
    p = rng.integers(-(2**20), 2**20, (400, 3)) / 2**12  # dyadic, so p + 256 k is exact in float64
    shift = 256.0 * rng.integers(-3, 4, (400, 3))
    noise, noise_grad = VARIANTS[variant]
    value, grad = noise_grad(p)
    shifted_value, shifted_grad = noise_grad(p + shift)
    np.testing.assert_array_equal(shifted_value, value)
    np.testing.assert_array_equal(shifted_grad, grad)
    np.testing.assert_array_equal(noise(p + shift), value)


@pytest.mark.parametrize("variant", ["perlin", "linear"])
def test_range_bound(variant):
    # |c_ijk| <= sum_a |f_a - ijk_a| and the weights are a partition of unity with (1-u)t + u(1-t) <= 1/2
    # per axis for any symmetric monotone weight u(t), so |n| <= 3/2. In practice |n| is about 1.
    rng = np.random.default_rng(4)
    value = VARIANTS[variant][0](rng.uniform(0.0, 256.0, (200_000, 3)))
    assert np.abs(value).max() <= 1.5
    assert np.abs(value).max() > 0.85
    assert abs(value.mean()) < 0.01 and 0.2 < value.std() < 0.4


@pytest.mark.parametrize("variant", ["perlin", "linear"])
def test_gradient_matches_central_differences(variant):
    rng = np.random.default_rng(5)
    p = rng.uniform(-100.0, 100.0, (2000, 3))
    h = 1e-5
    if variant == "linear":  # C0 only: keep the stencil inside one cell
        f = p - np.floor(p)
        p = p[np.all((f > 10 * h) & (f < 1.0 - 10 * h), axis=-1)]
    noise, noise_grad = VARIANTS[variant]
    value, grad = noise_grad(p)
    np.testing.assert_array_equal(value, noise(p))
    fd = np.stack([(noise(p + h * e) - noise(p - h * e)) / (2.0 * h) for e in np.eye(3)], axis=-1)
    np.testing.assert_allclose(grad, fd, rtol=0, atol=1e-7 * max(1.0, np.abs(grad).max()))
    assert np.abs(grad).max() > 1.0  # not trivially zero


def test_linear_noise_gradient_jumps_across_cell_faces():
    # linear noise is only C0 (Hart's 100,000-gate grid artefacts); Perlin's fade makes it C2
    x = np.array([[17.0 - 1e-9, 3.3, -4.7], [17.0 + 1e-9, 3.3, -4.7]])
    lin_value, lin_grad = linear_noise_grad(x)
    perlin_value, perlin_grad = perlin_noise_grad(x)
    assert abs(lin_value[1] - lin_value[0]) < 1e-8
    assert abs(lin_grad[1, 0] - lin_grad[0, 0]) > 1e-3
    np.testing.assert_allclose(perlin_grad[1], perlin_grad[0], atol=1e-7)


# --- GLSL against the float64 reference ---------------------------------------------------------------


@pytest.fixture(scope="module")
def points32() -> np.ndarray:
    rng = np.random.default_rng(6)
    return rng.uniform(-50.0, 50.0, (2000, 3)).astype(np.float32)


@pytest.mark.parametrize("target", ["gl330", "es300"])
@pytest.mark.parametrize(
    ("variant", "value_fn", "grad_fn"),
    [("perlin", "nz_noise", "nz_noiseGrad"), ("linear", "nz_linearNoise", "nz_linearNoiseGrad")],
)
def test_glsl_matches_float64_reference(points32, target, variant, value_fn, grad_fn):
    p64 = points32.astype(np.float64)  # the exact points the shader sees
    ref_value, ref_grad = VARIANTS[variant][1](p64)
    value = glsl_eval(f"{value_fn}(p)", {"p": points32}, 1, includes=NOISE_GLSL, target=target)
    value_grad = glsl_eval(f"{grad_fn}(p)", {"p": points32}, 4, includes=NOISE_GLSL, target=target)
    np.testing.assert_allclose(value, ref_value, rtol=0, atol=1e-5)
    scale = np.abs(ref_grad).max()
    np.testing.assert_allclose(value_grad[:, :3], ref_grad, rtol=0, atol=1e-4 * scale)
    # the value part of the gradient function is the value function (bit-identical on llvmpipe)
    np.testing.assert_allclose(value_grad[:, 3], value, rtol=0, atol=1e-6)


@pytest.mark.parametrize("target", ["gl330", "es300"])
def test_glsl_corner_hashes_are_perlins(target):
    """nz_hash reads its permutation as packed pairs (P[i], P[i + 1]); every corner hash must still be
    P[P[P[X + i] + Y + j] + Z + k] of Perlin's table, for cells anywhere (negative, beyond 256)."""
    cells = np.random.default_rng(11).integers(-700, 700, (4096, 3))
    prelude = (
        "vec4 corners(vec3 p, bool upper) {\n"
        "    ivec4 lo, hi;\n"
        "    nz_hash(ivec3(p), lo, hi);\n"
        "    return vec4(upper ? hi : lo);\n"
        "}\n"
    )
    lo, hi = (
        glsl_eval(
            f"corners(p, {upper})",
            {"p": cells},
            4,
            includes=NOISE_GLSL,
            target=target,
            prelude=prelude,
        )
        for upper in ("false", "true")
    )
    perm = np.array(PERMUTATION)
    x, y, z = (cells[:, k] & 255 for k in range(3))

    def corner(i, j, k):
        return perm[(perm[(perm[(x + i) & 255] + y + j) & 255] + z + k) & 255]

    want_lo = np.stack([corner(0, 0, 0), corner(1, 0, 0), corner(0, 1, 0), corner(1, 1, 0)], 1)
    want_hi = np.stack([corner(0, 0, 1), corner(1, 0, 1), corner(0, 1, 1), corner(1, 1, 1)], 1)
    np.testing.assert_array_equal(lo, want_lo)
    np.testing.assert_array_equal(hi, want_hi)


@pytest.mark.parametrize("target", ["gl330", "es300"])
def test_glsl_zero_on_lattice_and_periodic(target):
    rng = np.random.default_rng(8)
    lattice = rng.integers(-300, 300, (256, 3)).astype(np.float32)
    frac = rng.integers(0, 2**12, (256, 3)) / 2**12  # exact in float32 together with the offsets
    p = np.concatenate([lattice, (lattice + frac).astype(np.float32)])
    shifted = (p + 256.0 * rng.integers(-2, 3, p.shape)).astype(np.float32)
    value = glsl_eval("nz_noise(p)", {"p": p}, 1, includes=NOISE_GLSL, target=target)
    value_shifted = glsl_eval("nz_noise(p)", {"p": shifted}, 1, includes=NOISE_GLSL, target=target)
    assert np.all(value[:256] == 0.0)
    np.testing.assert_array_equal(value_shifted, value)
    np.testing.assert_allclose(value[256:], perlin_noise(p[256:].astype(np.float64)), rtol=0, atol=1e-5)


def test_footprint_curvature_is_the_second_order_shift_of_the_box_mean():
    """Oracle: dense sampling of small footprints. Their mean minus n(c) is τ = curvature / 24 up to fourth
    order; the shift is large against that remainder at a tenth of a cell."""
    rng = np.random.default_rng(12)
    c = rng.uniform(0.0, 64.0, (500, 3))
    q, _ = np.linalg.qr(rng.normal(size=(500, 3, 3)))
    e1, e2 = 0.1 * q[:, :, 0], 0.07 * q[:, :, 1]
    u = (np.arange(24) + 0.5) / 24 - 0.5
    uu, vv = (a.ravel() for a in np.meshgrid(u, u))
    points = c[:, None] + uu[None, :, None] * e1[:, None] + vv[None, :, None] * e2[:, None]
    shift = perlin_noise(points).mean(axis=1) - perlin_noise(c)
    tau = footprint_curvature(c, e1, e2) / 24.0
    # the midpoint grid's own second moment is (1 - 1/24²)/12 of the box's, hence the factor
    assert np.sqrt(np.mean((shift - tau * (1 - 1 / 24**2)) ** 2)) < 0.02 * np.sqrt(np.mean(shift**2))


@pytest.mark.parametrize("target", ["gl330", "es300"])
def test_glsl_curvature_matches_central_differences(target):
    """nz_noiseGradCurv's analytic e1ᵀHe1 + e2ᵀHe2 against central differences of the float64 reference."""
    rng = np.random.default_rng(13)
    p = rng.uniform(-40.0, 40.0, (2000, 3)).astype(np.float32)
    e1 = rng.normal(size=(2000, 3)).astype(np.float32)
    e2 = (0.5 * rng.normal(size=(2000, 3))).astype(np.float32)
    prelude = (
        "vec4 curv(vec3 p, vec3 a, vec3 b) { float k; vec4 g = nz_noiseGradCurv(p, a, b, k);"
        " vec4 h = nz_noiseGrad(p); return vec4(k, length(g - h), 0.0, 0.0); }"
    )
    got = glsl_eval(
        "curv(p, e1, e2)",
        {"p": p, "e1": e1, "e2": e2},
        4,
        includes=NOISE_GLSL,
        target=target,
        prelude=prelude,
    )
    want = footprint_curvature(p.astype(np.float64), e1.astype(np.float64), e2.astype(np.float64))
    np.testing.assert_allclose(got[:, 0], want, rtol=0, atol=2e-4 * np.abs(want).max())
    assert got[:, 1].max() < 1e-5  # its value and gradient are nz_noiseGrad's


def test_glsl_linear_noise_curvature_inside_cells():
    """The trilinear variant is smooth inside a cell: compare with central differences of linear_noise."""
    rng = np.random.default_rng(14)
    cells = rng.integers(-30, 30, (1000, 3))
    p = (cells + rng.uniform(0.1, 0.9, (1000, 3))).astype(np.float32)
    e1 = rng.normal(size=(1000, 3)).astype(np.float32)
    e2 = rng.normal(size=(1000, 3)).astype(np.float32)
    prelude = "float curv(vec3 p, vec3 a, vec3 b) { float k; nz_linearNoiseGradCurv(p, a, b, k); return k; }"
    got = glsl_eval("curv(p, e1, e2)", {"p": p, "e1": e1, "e2": e2}, 1, includes=NOISE_GLSL, prelude=prelude)
    p64, h = p.astype(np.float64), 1e-3
    want = np.zeros(len(p))
    for e in (e1.astype(np.float64), e2.astype(np.float64)):
        want += (linear_noise(p64 + h * e) - 2 * linear_noise(p64) + linear_noise(p64 - h * e)) / h**2
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-3 * np.abs(want).max())
