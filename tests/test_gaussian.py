"""Heitz et al. §4.2: preconvolved colour maps and the footprint statistics of Perlin noise.

Oracles: adaptive quadrature of the colour table against a Gaussian (SciPy), brute-force Monte Carlo
sampling of noise under footprints, and the closed form C̄ = C(μ) of a linear colour map.
"""

import functools

import numpy as np
import pytest
from oracles import gaussian_density
from scipy.integrate import quad
from scipy.special import ndtr

from prefilter.colormap.gaussian import gaussian_average, preconvolve
from prefilter.colormap.table import ColourTable
from prefilter.gl.context import gl_context
from prefilter.gl.evaluate import glsl_eval
from prefilter.procedural.hart import HartMaterial, NoiseTerm, driver_gaussian
from prefilter.procedural.noise import footprint_curvature, perlin_noise, perlin_noise_grad
from prefilter.procedural.noise_stats import (
    GLSL,
    footprint_samples,
    glsl_source,
    mean_fraction,
    mean_fraction_fit,
    measure_entry,
    noise_stats,
    random_footprints,
    split_fit,
    split_fits,
)

RNG = np.random.default_rng(11)


def _table(wrap: str, n: int = 32) -> ColourTable:
    return ColourTable(np.random.default_rng(5).uniform(0, 1, (n, 4)).astype(np.float32), wrap)


def _quadrature(table: ColourTable, mu: float, sigma: float) -> np.ndarray:
    """∫ C(v) N(v; μ, σ²) dv by adaptive quadrature between the table's entry edges."""
    if sigma == 0:
        return table.point(mu)
    lo, hi = mu - 9 * sigma, mu + 9 * sigma
    inner = np.arange(np.floor(lo * table.n) + 1, np.ceil(hi * table.n)) / table.n
    edges = np.concatenate([[lo], inner[(inner > lo) & (inner < hi)], [hi]])
    out = np.zeros(4)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        weight = quad(gaussian_density, a, b, args=(mu, sigma))[0]
        out += table.point(0.5 * (a + b)).astype(np.float64) * weight  # C is constant between edges
    return out


def _eval_map(expr, inputs, baked, texture, target="gl330"):
    """Evaluate a colormap.glsl expression over `map` (a texture of the bake `baked`) and its `range`."""
    return glsl_eval(
        expr,
        inputs,
        4,
        includes=("colormap/colormap.glsl",),
        target=target,
        prelude="uniform sampler2D map;\nuniform vec3 range;",
        uniforms={"range": (*baked.mu_range, baked.sigma_max)},
        textures={"map": texture},
    )


@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_preconvolved_texels_equal_quadrature(wrap):
    table = _table(wrap)
    baked = preconvolve(table, n_sigma=64, sigma_max=0.5)
    mus, sigmas = baked.mu_nodes(), baked.sigma_nodes()
    worst = 0.0
    for _ in range(12):
        i, j = RNG.integers(len(mus)), RNG.integers(len(sigmas))
        worst = max(worst, np.abs(baked.data[j, i] - _quadrature(table, mus[i], sigmas[j])).max())
    assert worst <= 1e-3  # the bar; measured ~1e-7 (float32 storage)


@pytest.mark.parametrize("entries", [64, 4096])
def test_clamp_rows_baked_on_the_edge_lattice_equal_quadrature(entries):
    """The clamp bake sums its edge form by FFT where the μ texels and the entry edges share a lattice: a
    texel is 1/4 entry for 64 entries (four residue classes), 16 entries for 4096. Any texel of any row
    against adaptive quadrature, to the float32 storage."""
    table = _table("clamp", entries)
    baked = preconvolve(table, n_sigma=32, sigma_max=0.5)
    mus, sigmas = baked.mu_nodes(), baked.sigma_nodes()
    rng = np.random.default_rng(entries)
    for i, j in zip(rng.integers(len(mus), size=6), rng.integers(1, len(sigmas), size=6), strict=True):
        np.testing.assert_allclose(baked.data[j, i], _quadrature(table, mus[i], sigmas[j]), atol=1e-6)


@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_edge_form_equals_quadrature_off_grid(wrap):
    table = _table(wrap)
    for _ in range(10):
        mu, sigma = RNG.uniform(-1.5, 2.5), RNG.uniform(0.001, 0.6)
        np.testing.assert_allclose(
            gaussian_average(table, mu, sigma), _quadrature(table, mu, sigma), atol=1e-6
        )


@pytest.mark.parametrize("target", ["gl330", "es300"])
@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_cm_gaussian_matches_the_bake_and_the_exact_convolution(wrap, target):
    table = _table(wrap, 256)
    baked = preconvolve(table)
    texture = baked.upload(gl_context())
    try:
        mu = RNG.uniform(-1.2, 2.2, 3000)
        sigma = RNG.uniform(0.0, 1.2, 3000)
        got = _eval_map(
            f"cm_gaussian(map, mu, sigma, {table.wrap_code}, range)",
            {"mu": mu, "sigma": sigma},
            baked,
            texture,
            target,
        )
    finally:
        texture.release()
    np.testing.assert_allclose(got, baked.lookup(mu, sigma), atol=2e-3)  # GPU bilinear weights
    # against the exact convolution: interpolation error, largest for small σ where C̄ has steps
    exact = gaussian_average(table, mu, np.minimum(sigma, baked.sigma_max))
    err = np.abs(got - exact).max(axis=1)
    inside = (mu > baked.mu_range[0]) & (mu < baked.mu_range[1]) | (wrap == "modulo")  # clamp: baked range
    wide = inside & (sigma > 4.0 / table.n)
    assert err[wide].max() < 5e-3 and np.median(err[inside]) < 5e-3


def _derivative_quadrature(table: ColourTable, mu: float, sigma: float) -> np.ndarray:
    """∂C̄/∂μ = ∫ C(v) (v - μ)/σ² N(v; μ, σ²) dv by adaptive quadrature between the table's entry edges."""
    lo, hi = mu - 9 * sigma, mu + 9 * sigma
    inner = np.arange(np.floor(lo * table.n) + 1, np.ceil(hi * table.n)) / table.n
    edges = np.concatenate([[lo], inner[(inner > lo) & (inner < hi)], [hi]])
    out = np.zeros(4)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        weight = quad(lambda v: (v - mu) / sigma**2 * gaussian_density(v, mu, sigma), a, b)[0]
        out += table.point(0.5 * (a + b)).astype(np.float64) * weight  # C is constant between edges
    return out


@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_the_derivative_map_is_the_preconvolved_maps_slope(wrap):
    """surface-filter's slope colours under a light read ∂C̄/∂μ (microsurface.frag,
    ms_slopeColourDerivative) from PreconvolvedMap.derivative_data through cm_gaussian, as it reads C̄."""
    table = _table(wrap, 64)
    baked = preconvolve(table, n_sigma=64, sigma_max=0.5)
    texture = baked.upload_derivative(gl_context())
    rng = np.random.default_rng(11)
    lo, hi = baked.mu_range
    mu = rng.uniform(lo + 0.05, hi - 0.05, 40) if wrap == "clamp" else rng.uniform(-0.5, 1.5, 40)
    sigma = rng.uniform(4.0 / table.n, 0.5, 40)  # a few table entries and more: C̄ is smooth on a texel
    try:
        got = _eval_map(
            f"cm_gaussian(map, mu, sigma, {table.wrap_code}, range)",
            {"mu": mu, "sigma": sigma},
            baked,
            texture,
        )
    finally:
        texture.release()
    exact = np.array([_derivative_quadrature(table, m, v) for m, v in zip(mu, sigma, strict=True)])
    scale = np.abs(exact).max()
    assert np.abs(got - exact).max() < 0.02 * scale, (np.abs(got - exact).max(), scale)


def _box_exact(table: ColourTable, mu: float, width: float, sigma: float) -> np.ndarray:
    """(1/w) ∫ C̄(m, σ) dm over [a, b] = μ ∓ w/2, in closed form. C is a sum of steps: c_last below its
    first edge considered, and at edge x a jump by c_before − c_after, so C̄(m) = c_last + Σ jump Φ((x − m)/σ)
    and ∫_a^b Φ((x − m)/σ) dm = σ [Ψ((x − a)/σ) − Ψ((x − b)/σ)], Ψ(z) = z Φ(z) + φ(z) (Ψ' = Φ); for σ = 0
    it is the length of [a, b] below x. Modulo tables repeat their edges over every period in reach."""
    entries = table.entries.astype(np.float64)
    a, b = mu - 0.5 * width, mu + 0.5 * width
    if table.wrap == "modulo":
        periods = np.arange(np.floor(a - 10 * sigma) - 1, np.ceil(b + 10 * sigma) + 2)
        edges = (np.arange(table.n)[None, :] / table.n + periods[:, None]).ravel()  # before entry i
        jumps = np.tile(np.roll(entries, 1, axis=0) - entries, (len(periods), 1))
    else:
        edges = np.arange(1, table.n) / table.n
        jumps = entries[:-1] - entries[1:]
    if sigma == 0:
        below = np.clip(edges, a, b) - a
    else:
        psi = lambda z: z * ndtr(z) + np.exp(-0.5 * z * z) / np.sqrt(2 * np.pi)  # noqa: E731
        below = sigma * (psi((edges - a) / sigma) - psi((edges - b) / sigma))
    return entries[-1] + below @ jumps / (b - a)


@functools.cache
def _box_cases(wrap: str):
    """Random (μ, w, σ) and the exact box-times-Gaussian mean of _table(wrap) at each (shared by targets)."""
    table = _table(wrap)
    baked = preconvolve(table)
    rng = np.random.default_rng(21 if wrap == "modulo" else 22)
    count = 300
    mu = rng.uniform(-1.2, 2.2, count)
    width = np.exp(rng.uniform(np.log(1e-3), np.log(2.0), count)) * rng.choice([-1.0, 1.0], count)
    sigma = rng.uniform(0.0, 0.6 if wrap == "modulo" else 0.3, count)
    lo, hi = baked.mu_range
    texel = (hi - lo) / baked.data.shape[1]
    exact = np.empty((count, 4))
    for k in range(count):
        w = max(abs(width[k]), texel)  # widths below one μ texel are widened to one
        if wrap == "modulo" and w >= 1.0:
            exact[k] = table.entries.mean(axis=0)  # Hart's rule: the whole period
        else:
            exact[k] = _box_exact(table, mu[k], w, sigma[k])
    return table, baked, mu, width, sigma, exact


@pytest.mark.parametrize("target", ["gl330", "es300"])
@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_cm_gaussian_box_equals_the_table_under_a_box_times_a_gaussian(wrap, target):
    """cm_gaussianBox = C * box(w) * N(0, σ²): against its NumPy twin and the closed-form box mean of C̄."""
    table, baked, mu, width, sigma, exact = _box_cases(wrap)
    texture = baked.upload_box(gl_context())
    try:
        got = _eval_map(
            f"cm_gaussianBox(map, mu, width, sigma, {table.wrap_code}, range)",
            {"mu": mu, "width": width, "sigma": sigma},
            baked,
            texture,
            target,
        )
    finally:
        texture.release()
    np.testing.assert_allclose(got, baked.box_lookup(mu, width, sigma), atol=2e-3)  # GPU bilinear weights
    err = np.abs(got - exact).max(axis=1)
    # the bake holds C̄ at 256 σ rows and 256 μ texels per period: interpolation error where C̄ has steps
    smooth = (sigma > 4.0 / table.n) | (np.abs(width) > 4.0 / table.n)
    assert err[smooth].max() < 5e-3 and np.median(err) < 2e-3


def test_linear_colour_map_is_exact():
    """C linear: C̄(μ, σ) = C(μ) for any σ (Heitz eq. 31) wherever the table's ends are out of reach."""
    n = 256
    ramp = (np.arange(n) + 0.5) / n
    table = ColourTable(
        np.stack([ramp, 1 - ramp, 0.5 * ramp, np.ones(n)], axis=1).astype(np.float32), "clamp"
    )
    baked = preconvolve(table)
    texture = baked.upload(gl_context())
    try:
        sigma = RNG.uniform(2.0 / n, 0.08, 2000)
        mu = RNG.uniform(0.0, 1.0, 2000) * (1 - 10 * sigma) + 5 * sigma
        got = _eval_map("cm_gaussian(map, mu, sigma, 1, range)", {"mu": mu, "sigma": sigma}, baked, texture)
    finally:
        texture.release()
    np.testing.assert_allclose(got[:, 0], mu, atol=1e-3)
    np.testing.assert_allclose(got[:, 1], 1 - mu, atol=1e-3)
    np.testing.assert_allclose(got[:, 2], 0.5 * mu, atol=1e-3)


@pytest.mark.parametrize("rho1,rho2", [(0.5, 0.5), (1.0, 1.0), (2.0, 0.7), (3.0, 3.0), (8.0, 0.25)])
def test_noise_table_reproduces_brute_force_variance(rho1, rho2):
    """The stored table against a fresh Monte Carlo run (other seed): residual and total variance."""
    stats = noise_stats()
    rng = np.random.default_rng(99)
    beta, kappa, gamma, lam = (float(v) for v in stats.lookup(np.array(rho1), np.array(rho2)))
    fresh = measure_entry(rng, rho1, rho2, stats.variance, count=2048)
    assert abs(fresh[0] - beta) < 0.03 and abs(fresh[1] - kappa) < 0.03 and abs(fresh[2] - gamma) < 0.03
    assert abs(fresh[3] - lam) <= 0.05 * max(fresh[3], 0.2)
    # the spread the Gaussian must carry: the second moment of n about the filtered mean β n(c) + κ τ(c),
    # predicted as γ² E[(∇n·e1)² + (∇n·e2)²] / 12 (linear part over a box) + λ σ_n² (residual)
    centres, e1, e2 = random_footprints(rng, 2048, rho1, rho2)
    points, _ = footprint_samples(centres, e1, e2)
    centre_value, grad = perlin_noise_grad(centres)
    mean = beta * centre_value + kappa * footprint_curvature(centres, e1, e2) / 24.0
    measured = np.mean((perlin_noise(points) - mean[:, None]) ** 2)
    linear = gamma**2 * ((grad * e1).sum(1) ** 2 + (grad * e2).sum(1) ** 2).mean() / 12.0
    assert linear + lam * stats.variance == pytest.approx(measured, rel=0.05)


def test_fitted_split_stays_close_to_the_table():
    stats = noise_stats()
    fits = split_fits()
    r1, r2 = np.meshgrid(2.0**stats.grid, 2.0**stats.grid, indexing="ij")
    beta, kappa, gamma, lam = split_fit(fits, r1, r2)
    assert np.abs(beta - stats.beta).max() < 0.13
    assert np.abs(kappa - stats.kappa).max() < 0.12
    assert np.abs(gamma - stats.gamma).max() < 0.13
    assert np.abs(lam - stats.lam).max() < 0.1
    # limits: point footprints keep the noise in the mean (the Taylor series: β = κ = 1), huge ones move
    # it all to σ
    b, k, g, lam_ = split_fit(fits, np.array([1e-3, 1e3]), np.array([1e-3, 1e3]))
    np.testing.assert_allclose(b, [1, 0], atol=1e-9)
    np.testing.assert_allclose(k, [1, 0], atol=1e-6)
    np.testing.assert_allclose(lam_, [0, 1], atol=1e-9)


def test_fitted_split_keeps_the_taylor_mean_and_drops_terms_that_grow_with_the_footprint():
    """Small footprints: 1 - β and λ vanish faster than ρ², the order of the curvature term κ τ that
    completes the Taylor mean (and of the linear part's spread). Long footprints: κ τ ~ κ ρ² and the
    linear part γ ∇n·e ~ γ ρ must vanish, not grow with the footprint's length."""
    fits = split_fits()
    rho = np.array([0.01, 0.02, 0.04, 0.08])
    beta, _, _, lam = split_fit(fits, rho, rho)
    for vanishing in (1.0 - beta, lam):
        ratio = vanishing / rho**2  # O(ρ) or smaller: at least halves with ρ
        assert (ratio[1:] / ratio[:-1] > 1.9).all() and ratio[0] < 2e-3, ratio
    length = np.array([16.0, 64.0, 256.0, 1024.0])
    _, kappa, gamma, _ = split_fit(fits, np.full(4, 0.1), length)
    curvature_weight, linear_weight = kappa * length**2, gamma * length
    assert (np.diff(curvature_weight) < 0).all() and curvature_weight[0] < 0.05, curvature_weight
    assert (np.diff(linear_weight) < 0).all() and linear_weight[0] < 0.01, linear_weight


def test_driver_statistics_against_brute_force_footprints():
    """μ and σ² of a 1/f sum (eq. 6) over random parallelogram footprints against dense sampling."""
    terms = [NoiseTerm(2.0**-i, 2.0**i * np.eye(3), np.zeros(3)) for i in range(1, 7)]
    material = HartMaterial(np.zeros((4, 4)), terms, table=None, solid_from_object=np.eye(4))
    rng = np.random.default_rng(3)
    for scale in (0.05, 0.4, 3.0):  # footprint side in units of the first octave's lattice
        count = 400
        centres = rng.uniform(0, 64, (count, 3))
        q, _ = np.linalg.qr(rng.normal(size=(count, 3, 3)))
        dsdx, dsdy = q[:, :, 0] * scale, q[:, :, 1] * scale * rng.uniform(0.3, 1.0, (count, 1))
        mu, var_lin, var_res = driver_gaussian(material, centres, dsdx, dsdy)
        u = (np.arange(16) + 0.5) / 16 - 0.5
        uu, vv = (a.ravel() for a in np.meshgrid(u, u))
        points = centres[:, None] + uu[None, :, None] * dsdx[:, None] + vv[None, :, None] * dsdy[:, None]
        f = sum(t.amplitude * perlin_noise(points @ t.matrix.T) for t in terms)
        true_mean = f.mean(axis=1)
        second_moment = np.mean((f - mu[:, None]) ** 2, axis=1)  # the spread about μ the Gaussian carries
        assert (var_lin + var_res).mean() == pytest.approx(second_moment.mean(), rel=0.2), scale
        # the mean estimate beats both the centre value (point) and 0 (everything unresolved) by far:
        # measured 0.0002 / 0.013 / 0.021 of the total variance, the centre value 0.004 / 0.21 / 0.98
        total = sum(t.amplitude**2 for t in terms) * noise_stats().variance
        centre = sum(t.amplitude * perlin_noise(centres @ t.matrix.T) for t in terms)
        error = np.mean((mu - true_mean) ** 2)
        assert error < 0.1 * np.mean((centre - true_mean) ** 2) and error < 0.05 * total, scale


def test_the_checked_in_glsl_is_what_the_generator_writes():
    """noise_stats.glsl is generated from the template in noise_stats.py (`python -m
    prefilter.procedural.noise_stats`): an edit to either side without regenerating fails here."""
    assert GLSL.read_text() == glsl_source(noise_stats())


def test_generated_glsl_holds_the_fitted_coefficients():
    """noise_stats.glsl (what the shader reads) and the NumPy twin use the same fit of the same table."""
    import re

    text = GLSL.read_text()
    fits = list(split_fits().values())  # β, κ, γ, 1 - λ: the order of the vec4 components
    for index, constant in enumerate(("NS_FALL_A", "NS_FALL_B", "NS_FALL_C", "NS_FALL_D")):
        m = re.search(rf"{constant} = vec4\(([-\d.e]+), ([-\d.e]+), ([-\d.e]+), ([-\d.e]+)\)", text)
        assert m, constant
        for component, fit in enumerate(fits):
            assert float(m.group(component + 1)) == pytest.approx(fit[index], abs=1e-6), (constant, component)
    m = re.search(r"NS_VARIANCE = ([\d.]+);", text)
    assert float(m.group(1)) == pytest.approx(noise_stats().variance, abs=1e-6)
    m = re.search(r"NS_MEAN_FALL = vec4\(([-\d.e]+), ([-\d.e]+), ([-\d.e]+), ([-\d.e]+)\)", text)
    assert m
    np.testing.assert_allclose([float(v) for v in m.groups()], mean_fraction_fit(), atol=1e-6)


def test_mean_fraction_fit_stays_close_to_the_table():
    """β₁ (the microsurfaces' scale split): the fit against the measured table, and its limits."""
    stats = noise_stats()
    r1, r2 = np.meshgrid(2.0**stats.grid, 2.0**stats.grid, indexing="ij")
    assert np.abs(mean_fraction(r1, r2) - stats.beta_mean).max() < 0.05  # measured 0.041
    np.testing.assert_allclose(mean_fraction(np.array([1e-3, 1e3]), np.array([1e-3, 1e3])), [1, 0], atol=1e-5)
