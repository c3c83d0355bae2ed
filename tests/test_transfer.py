"""Heitz et al. 2014 §7: height transfer functions h = g(f), preconvolved moments and footprint statistics.

Oracles: adaptive SciPy quadrature of (g, g², g′, g′²) against N(μ, σ²); closed-form moments of the
linear transfer; central finite differences of g; Monte Carlo over Gaussian random fields (FFT-filtered
white noise plus a linear ramp, under a Gaussian pixel filter) with finite-difference gradients of h.
"""

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.stats import norm

from prefilter.gl.context import gl_context
from prefilter.gl.evaluate import glsl_eval
from prefilter.microsurface.transfer import (
    TRANSFER_FUNCTIONS,
    PreconvolvedTransfer,
    TransferFunction,
    preconvolve_transfer,
    transfer_stats,
)

NAMES = ["linear", "moss", "sponge"]
INCLUDES = ("microsurface/transfer.glsl",)


def _quadrature(tf: TransferFunction, mu: float, sigma: float) -> np.ndarray:
    """(E[g], E[g²], E[g′], E[g′²]) under N(μ, σ²) by adaptive quadrature over μ ± 10σ, split at the
    transfer function's threshold (where its shape changes over the softness)."""
    if sigma == 0:
        return tf.moments_integrand(mu)
    a, b = mu - 10 * sigma, mu + 10 * sigma
    t = tf.params.get("threshold", a)
    cuts = [a, t, b] if a < t < b else [a, b]
    integrand = lambda v: tf.moments_integrand(v) * norm.pdf(v, mu, sigma)  # noqa: E731
    return sum(
        quad_vec(integrand, p, q, epsabs=1e-13, epsrel=1e-11)[0]
        for p, q in zip(cuts[:-1], cuts[1:], strict=True)
    )


def _scale(tf: TransferFunction, baked: PreconvolvedTransfer) -> np.ndarray:
    """Per channel: the range of the function over the table's μ span (its magnitude if constant)."""
    values = tf.moments_integrand(np.linspace(*baked.mu_range, 20001))
    return np.maximum(values.max(0) - values.min(0), np.abs(values).max(0))


@pytest.mark.parametrize("name", NAMES)
def test_texels_equal_quadrature(name):
    tf = TRANSFER_FUNCTIONS[name]()
    baked = preconvolve_transfer(tf)
    mus, sigmas = baked.mu_nodes(), baked.sigma_nodes()
    rng = np.random.default_rng(1)
    # nodes near the threshold and at the narrowest rows are the hard ones: half the draws go there
    near = np.flatnonzero(np.abs(mus - tf.params.get("threshold", 0.0)) < 0.2)
    picks = [(rng.choice(near), rng.integers(0, 4)) for _ in range(8)]
    picks += [(rng.integers(len(mus)), rng.integers(len(sigmas))) for _ in range(8)]
    worst = max(
        (np.abs(baked.data[j, i] - _quadrature(tf, mus[i], sigmas[j])) / _scale(tf, baked)).max()
        for i, j in picks
    )
    assert worst <= 1e-4  # the brief's bar; measured ~1e-8 (float32 storage)


@pytest.mark.parametrize("name", ["moss", "sponge"])
def test_lookup_off_grid_is_bilinear_interpolation_of_the_exact_moments(name):
    """Off the grid the lookup differs from the exact moments by the bilinear interpolation error only:
    measured over 200 draws up to 6e-3 of the range (E[g′²] of moss, at σ below the softness near the
    threshold, where g′² changes over a few texels), 9e-4 for σ >= 0.1, median 1.5e-5; the worst error
    falls 3.1-3.4x when both spacings halve (second order: 4x), which an error of the bake would not do."""
    tf = TRANSFER_FUNCTIONS[name]()
    coarse = preconvolve_transfer(tf)
    fine = preconvolve_transfer(tf, n_mu=512, n_sigma=127)
    scale = _scale(tf, coarse)
    rng = np.random.default_rng(2)
    t = tf.params["threshold"]
    mu = np.concatenate([rng.uniform(t - 0.3, t + 0.3, 24), rng.uniform(-1.99, 1.99, 16)])
    sigma = np.concatenate([rng.uniform(0.0, 0.15, 24), rng.uniform(0.0, 1.0, 16)])
    exact = np.array([_quadrature(tf, m, s) for m, s in zip(mu, sigma, strict=True)])
    err_coarse = np.abs(coarse.lookup(mu, sigma) - exact) / scale
    err_fine = np.abs(fine.lookup(mu, sigma) - exact) / scale
    assert err_coarse.max() < 1e-2
    assert err_coarse[sigma >= 0.1].max() < 2e-3
    assert err_fine.max() < 0.4 * err_coarse.max()
    assert np.median(err_coarse) < 1e-4


def test_linear_transfer_moments_are_closed_form():
    baked = preconvolve_transfer(TRANSFER_FUNCTIONS["linear"]())
    mus, sigmas = baked.mu_nodes(), baked.sigma_nodes()
    m, s = np.meshgrid(mus, sigmas)
    np.testing.assert_allclose(baked.data[..., 0], m, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(baked.data[..., 1], m**2 + s**2, rtol=1e-6, atol=1e-7)
    np.testing.assert_array_equal(baked.data[..., 2:], 1.0)
    # off the grid: E[g] = μ is bilinear, hence exact; μ² and σ² are interpolated linearly between
    # nodes, an error of at most (Δμ² + Δσ²)/4
    rng = np.random.default_rng(3)
    mu, sigma = rng.uniform(mus[0], mus[-1], 1000), rng.uniform(0.0, baked.sigma_max, 1000)
    got = baked.lookup(mu, sigma)
    bound = ((mus[1] - mus[0]) ** 2 + sigmas[1] ** 2) / 4
    np.testing.assert_allclose(got[:, 0], mu, atol=1e-6)
    err = np.abs(got[:, 1] - mu**2 - sigma**2)
    assert err.max() <= bound + 1e-6 and err.max() > 0.5 * bound  # the bound is reached, not loose
    np.testing.assert_array_equal(got[:, 2:], 1.0)


@pytest.mark.parametrize("name", NAMES)
def test_g_prime_equals_finite_differences(name):
    tf = TRANSFER_FUNCTIONS[name]()
    v = np.linspace(-2.0, 2.0, 40001)
    step = 1e-5
    fd = (tf.g(v + step) - tf.g(v - step)) / (2 * step)
    np.testing.assert_allclose(tf.g_prime(v), fd, rtol=1e-6, atol=1e-7)
    # C¹ (smooth): no jump of g′ between neighbouring samples beyond what its own slope explains
    assert np.abs(np.diff(tf.g_prime(v))).max() < 0.01


def test_moss_and_sponge_shapes():
    """Moss: flat ground (g ≈ 0) below the threshold, rising tufts above; sponge: flat top, pits below."""
    moss, sponge = TRANSFER_FUNCTIONS["moss"](), TRANSFER_FUNCTIONS["sponge"]()
    for tf, sign in ((moss, 1.0), (sponge, -1.0)):
        t, s = tf.params["threshold"], tf.params["softness"]
        flat = t - sign * np.linspace(6 * s, 2.0, 100)  # the ground (moss) / top (sponge) side
        deep = t + sign * np.linspace(0.1, 1.0, 100)
        assert np.abs(tf.g(flat)).max() < np.sqrt(s) * np.exp(-3.0) * 1.01
        assert np.all(sign * tf.g(deep) > 0.3)
        assert np.all(tf.g_prime(np.linspace(-2, 2, 1001)) > 0)  # monotone in the driver
        # a cushion's profile: sqrt of the excess, g² = |v − t| + s ln(1 + e^{−|v − t|/s}) past the foot
        far = t + sign * np.linspace(0.5, 1.0, 50)
        np.testing.assert_allclose(tf.g(far) ** 2, sign * (far - t), rtol=0, atol=s * np.exp(-0.5 / s) * 1.01)
    assert TRANSFER_FUNCTIONS["moss"](threshold=0.3).params == {"threshold": 0.3, "softness": 0.04}
    with pytest.raises(ValueError, match="softness"):
        TransferFunction("moss", {"softness": 0.0})
    with pytest.raises(ValueError, match="no parameter"):
        TransferFunction("linear", {"threshold": 0.1})
    with pytest.raises(ValueError, match="unknown transfer"):
        TransferFunction("lichen")


def test_bake_is_deterministic_and_cached(tmp_path, monkeypatch):
    tf = TRANSFER_FUNCTIONS["moss"](softness=0.05)
    monkeypatch.setenv("PREFILTER_CACHE", str(tmp_path))
    first = preconvolve_transfer(tf, n_mu=64, n_sigma=16)
    assert len(list(tmp_path.glob("transfer-moments-*.npy"))) == 1
    again = preconvolve_transfer(tf, n_mu=64, n_sigma=16)  # from the cache
    assert first.data.dtype == np.float32 and first.data.tobytes() == again.data.tobytes()
    for path in tmp_path.glob("*.npy"):
        path.unlink()
    assert preconvolve_transfer(tf, n_mu=64, n_sigma=16).data.tobytes() == first.data.tobytes()
    other = preconvolve_transfer(TRANSFER_FUNCTIONS["moss"](softness=0.06), n_mu=64, n_sigma=16)
    assert other.data.tobytes() != first.data.tobytes()


# --- Monte Carlo: a Gaussian driver field under a Gaussian pixel filter ---------------------------------


def _driver_field_statistics(tf: TransferFunction, rng, count=9600, n=16, chunk=800):
    """Pooled statistics over `count` periodic n x n Gaussian random fields, each seen through a Gaussian
    pixel filter (std 1.8 px) centred on the tile, with the driver f = f0 + a·(x − c) + noise.

    The noise: white noise filtered by an anisotropic Gaussian spectrum (correlation lengths 3 and 2 px,
    rotated by 0.5 rad, so Σ_∇f has an off-diagonal term), σ = 0.25. Under the Gaussian filter the ramp
    is N(0, |a|² 1.8²), so f is exactly Gaussian: σ_f ≈ 0.34. Gradients are central differences with a
    step of 0.02 px, the fields evaluated off the grid by the Fourier shift theorem (the noise's
    trigonometric interpolant), so that g's foot (softness 0.04 in f, ~0.4 px) is resolved.
    Returns the driver statistics (f̄, σ_f, ∇f̄, Σ_∇f), the h statistics (mean, var, slope mean, slope
    cov) and their standard errors (from the spread of the per-field estimates).
    """
    f0, a, sigma_n, eps, width = 0.0, np.array([0.11, -0.07]), 0.25, 0.02, 1.8
    k = 2 * np.pi * np.fft.fftfreq(n)
    kx, ky = np.meshgrid(k, k)  # [y, x]
    ku, kv = np.cos(0.5) * kx + np.sin(0.5) * ky, -np.sin(0.5) * kx + np.cos(0.5) * ky
    amplitude = np.exp(-0.25 * ((3.0 * ku) ** 2 + (2.0 * kv) ** 2))  # √ of the Gaussian spectrum
    amplitude *= sigma_n / np.sqrt((amplitude**2).sum() / n**2)  # Var = Σ A² / n² (Parseval)
    ys, xs = np.meshgrid(np.arange(n) - n / 2 + 0.5, np.arange(n) - n / 2 + 0.5, indexing="ij")
    weight = np.exp(-0.5 * (xs**2 + ys**2) / width**2)
    weight /= weight.sum()
    shifts = [(0.0, 0.0), (eps, 0.0), (-eps, 0.0), (0.0, eps), (0.0, -eps)]
    f_all, gf_all, h_all, gh_all = [], [], [], []
    for _ in range(count // chunk):
        spectrum = np.fft.fft2(rng.standard_normal((chunk, n, n))) * amplitude
        f = [
            f0
            + a[0] * (xs + dx)
            + a[1] * (ys + dy)
            + np.fft.ifft2(spectrum * np.exp(1j * (kx * dx + ky * dy))).real
            for dx, dy in shifts
        ]
        h = [tf.g(v) for v in f]
        f_all.append(f[0])
        h_all.append(h[0])
        gf_all.append(np.stack([f[1] - f[2], f[3] - f[4]], -1) / (2 * eps))
        gh_all.append(np.stack([h[1] - h[2], h[3] - h[4]], -1) / (2 * eps))
    f, h, gf, gh = (np.concatenate(x) for x in (f_all, h_all, gf_all, gh_all))

    per_field = lambda x: np.tensordot(x, weight, axes=([1, 2], [0, 1]))  # noqa: E731

    def mean_and_error(x):
        p = per_field(x)
        return p.mean(0), p.std(0) / np.sqrt(len(p))

    def pair_products(d):  # (xx, xy, yy) of the last axis
        return np.stack([d[..., 0] ** 2, d[..., 0] * d[..., 1], d[..., 1] ** 2], -1)

    f_mean = mean_and_error(f)[0]
    f_sigma = np.sqrt(mean_and_error((f - f_mean) ** 2)[0])
    grad_mean = mean_and_error(gf)[0]
    grad_cov = mean_and_error(pair_products(gf - grad_mean))[0]
    h_mean, h_mean_err = mean_and_error(h)
    h_var, h_var_err = mean_and_error((h - h_mean) ** 2)
    slope_mean, slope_mean_err = mean_and_error(gh)
    slope_cov, slope_cov_err = mean_and_error(pair_products(gh - slope_mean))
    return (
        (f_mean, f_sigma, grad_mean, grad_cov),
        (h_mean, h_var, slope_mean, slope_cov),
        (h_mean_err, h_var_err, slope_mean_err, slope_cov_err),
    )


@pytest.mark.parametrize("name", NAMES)
def test_slope_gain_is_the_rms_derivative_under_the_driver(name):
    """TransferFunction.slope_gain(σ)² = E[g′(f)²] for f ~ N(0, σ²), against adaptive quadrature (the shadow
    profile's reach scales the driver's slope deviation by it)."""
    tf = TRANSFER_FUNCTIONS[name]()
    for sigma in (0.05, 0.3, 1.0):
        assert tf.slope_gain(sigma) ** 2 == pytest.approx(_quadrature(tf, 0.0, sigma)[3], rel=1e-6), sigma


@pytest.mark.parametrize("name", ["moss", "sponge"])
def test_transfer_stats_against_monte_carlo(name):
    tf = TRANSFER_FUNCTIONS[name]()
    driver, measured, errors = _driver_field_statistics(tf, np.random.default_rng(7))
    f_mean, f_sigma, grad_mean, grad_cov = driver
    assert 0.3 < f_sigma < 0.38 and np.abs(grad_mean - [0.11, -0.07]).max() < 0.005  # the intended driver
    moments = preconvolve_transfer(tf).lookup(f_mean, f_sigma)
    h_mean, h_var, slope_mean, slope_cov = transfer_stats(moments, grad_mean, grad_cov)
    m_mean, m_var, m_slope_mean, m_slope_cov = measured
    # scales: the height spread for heights, the slope spread for slopes; tolerance 3 % of them,
    # while the Monte Carlo standard errors are below 1 % (asserted, so the test can resolve 3 %)
    h_scale, s_scale = np.sqrt(m_var), m_slope_cov[0] + m_slope_cov[2]  # trace of the slope covariance
    assert errors[0] < 0.01 * h_scale and errors[1] < 0.01 * m_var
    assert errors[2].max() < 0.01 * np.sqrt(s_scale) and errors[3].max() < 0.01 * s_scale
    assert abs(h_mean - m_mean) < 0.03 * h_scale
    assert h_var == pytest.approx(m_var, rel=0.03)
    assert np.abs(slope_mean - m_slope_mean).max() < 0.03 * np.sqrt(s_scale)
    assert np.abs(slope_cov - m_slope_cov).max() < 0.03 * s_scale
    # the test discriminates: dropping the spread of g′ (E[g′²] − E[g′]²) ∇f̄∇f̄ᵀ, or scaling Σ_∇f by
    # E[g′]² (the chain rule on the mean), misses by far more than the tolerance
    assert np.abs(moments[3] * grad_cov - m_slope_cov).max() > 0.1 * s_scale
    assert np.abs(moments[2] ** 2 * grad_cov - m_slope_cov).max() > 0.1 * s_scale


# --- GLSL ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("target", ["gl330", "es300"])
def test_glsl_moments_match_the_lookup_and_the_quadrature(target):
    tf = TRANSFER_FUNCTIONS["moss"]()
    baked = preconvolve_transfer(tf)
    scale = _scale(tf, baked)
    rng = np.random.default_rng(4)
    mu = np.concatenate([rng.uniform(-2.5, 2.5, 2000), rng.uniform(-0.2, 0.4, 1000)])
    sigma = np.concatenate([rng.uniform(0.0, 1.3, 2000), rng.uniform(0.0, 0.1, 1000)])
    texture = baked.upload(gl_context())
    try:
        got = glsl_eval(
            "ms_transferMoments(table, mu, sigma, range)",
            {"mu": mu, "sigma": sigma},
            4,
            includes=INCLUDES,
            target=target,
            prelude="uniform sampler2D table;\nuniform vec3 range;",
            uniforms={"range": baked.range_uniform},
            textures={"table": texture},
        )
    finally:
        texture.release()
    err = np.abs(got - baked.lookup(mu, sigma)) / scale
    # llvmpipe: 6e-7 (float weights); a GPU's fixed-point bilinear weights allow 1/256 of a texel step
    assert err.max() < 2e-3
    assert np.median(err) < 1e-5
    # beyond the table: the edge column, and sigma_max
    inside = (np.abs(mu) < 1.99) & (sigma <= baked.sigma_max)
    picks = np.flatnonzero(inside)[:6]
    for p in picks:
        exact = _quadrature(tf, mu[p], sigma[p])
        assert np.all(np.abs(got[p] - exact) / scale < 1e-2)
    edge = baked.lookup(np.clip(mu, *baked.mu_range), np.minimum(sigma, baked.sigma_max))
    np.testing.assert_allclose(got[~inside], edge[~inside], atol=2e-3 * scale.max())


@pytest.mark.parametrize("target", ["gl330", "es300"])
def test_glsl_stats_match_python(target):
    rng = np.random.default_rng(5)
    n = 2000
    mean_g = rng.uniform(-1, 1, n)
    mean_gp = rng.uniform(0, 1.5, n)
    moments = np.stack(
        [mean_g, mean_g**2 + rng.uniform(0, 0.3, n), mean_gp, mean_gp**2 + rng.uniform(0, 0.5, n)], 1
    )
    moments[:5, 1] = moments[:5, 0] ** 2 - 1e-4  # rounding below the mean's square: clamped to 0
    grad_mean = rng.normal(0, 0.3, (n, 2))
    lower = rng.normal(0, 0.3, (n, 2, 2)) * [[1, 0], [1, 1]]
    cov = lower @ lower.transpose(0, 2, 1)
    grad_cov = np.stack([cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]], 1)
    prelude = """
vec4 heights(vec4 m, vec2 gm, vec3 gc) {
    float hm; float hv; vec2 sm; vec3 sc;
    ms_transferStats(m, gm, gc, hm, hv, sm, sc);
    return vec4(hm, hv, sm);
}
vec3 slopes(vec4 m, vec2 gm, vec3 gc) {
    float hm; float hv; vec2 sm; vec3 sc;
    ms_transferStats(m, gm, gc, hm, hv, sm, sc);
    return sc;
}"""
    inputs = {"m": moments, "gm": grad_mean, "gc": grad_cov}
    kwargs = dict(includes=INCLUDES, target=target, prelude=prelude)
    first = glsl_eval("heights(m, gm, gc)", inputs, 4, **kwargs)
    cov_out = glsl_eval("slopes(m, gm, gc)", inputs, 3, **kwargs)
    h_mean, h_var, slope_mean, slope_cov = transfer_stats(moments, grad_mean, grad_cov)
    np.testing.assert_allclose(first[:, 0], h_mean, atol=1e-6)
    np.testing.assert_allclose(first[:, 1], h_var, atol=1e-5)
    assert np.all(first[:5, 1] == 0.0)
    np.testing.assert_allclose(first[:, 2:], slope_mean, atol=1e-6)
    np.testing.assert_allclose(cov_out, slope_cov, atol=1e-5)
    # an independent check of the formula: E[∇h∇hᵀ] − E[∇h]E[∇h]ᵀ with E[∇h∇hᵀ] = E[g′²](∇f̄∇f̄ᵀ + Σ)
    gx, gy = grad_mean[:, 0], grad_mean[:, 1]
    second = moments[:, 3, None] * (np.stack([gx * gx, gx * gy, gy * gy], 1) + grad_cov)
    mean = moments[:, 2, None] * grad_mean
    np.testing.assert_allclose(
        slope_cov,
        second - np.stack([mean[:, 0] ** 2, mean[:, 0] * mean[:, 1], mean[:, 1] ** 2], 1),
        atol=1e-12,
    )


@pytest.mark.parametrize("target", ["gl330", "es300"])
@pytest.mark.parametrize("name", NAMES)
def test_glsl_transfer_value_and_derivative(name, target):
    tf = TRANSFER_FUNCTIONS[name]()
    v = np.concatenate([np.linspace(-3.0, 3.0, 3001), [-40.0, 40.0]])
    got = glsl_eval(
        "vec2(ms_transferValue(kind, params, v), ms_transferDerivative(kind, params, v))",
        {"v": v},
        2,
        includes=INCLUDES,
        target=target,
        prelude="uniform int kind;\nuniform vec2 params;",
        uniforms={"kind": tf.code, "params": tf.param_vector},
    )
    np.testing.assert_allclose(got[:, 0], tf.g(v), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(got[:, 1], tf.g_prime(v), rtol=1e-5, atol=1e-6)
