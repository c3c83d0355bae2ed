"""Heitz et al. 2014 §3, §5.1, §5.2: Smith Λ, visibility, height and slope filtering distributions.

Oracles: SciPy quadrature of the defining integrals (Λ, eq. 12, eqs. 15–17, the moments of (a − z)⁺φ(z)),
closed forms (Heitz and Neyret's eq. 3; the max of n Gaussians for integer L; Gaussian moments by Stein's
identity), Monte Carlo over sampled slopes, and an FFT-synthesised Gaussian random surface whose facets
are weighted by their projected area. The GLSL twins are checked against the Python on gl330 and es300.
"""

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import erfc, erfcx
from scipy.stats import norm

from prefilter.gl.context import gl_context
from prefilter.gl.evaluate import glsl_eval
from prefilter.microsurface.curved_shadowing import (
    curved_elevation,
    curved_lit_fraction,
    descent_factor,
    lit_fraction,
    plane_bias,
    smith_lit_fraction,
)
from prefilter.microsurface.fractal_masking import effective_slope_variance
from prefilter.microsurface.height_filtering import (
    height_filtering_fit,
    height_filtering_moments,
    height_filtering_table,
)
from prefilter.microsurface.heightfield import Fractal
from prefilter.microsurface.smith import (
    ERFCX_COEFFS,
    NU_MIN,
    average_visibility,
    erfc_approx,
    erfcx_approx,
    fit_erfcx_coefficients,
    height_cdf,
    lambda_smith,
    mills_rho,
    normal_loss_scaled,
    visibility,
)
from prefilter.microsurface.visible_slopes import (
    gauss_hermite_2d,
    lambert_moments,
    projected_area,
    visible_slope_moments,
    visible_slope_moments_1d,
)

TARGETS = ("gl330", "es300")
SMITH = ("microsurface/smith.glsl",)

ISOTROPIC = np.array([[0.09, 0.0], [0.0, 0.09]])
ANISOTROPIC = np.array([[0.04, 0.03], [0.03, 0.25]])


def _direction(theta_deg, phi_deg):
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.stack(np.broadcast_arrays(np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)), axis=-1)


def _random_covs(count, rng, lo=1e-3, hi=1.0):
    """Random SPD 2x2 covariances: random rotation, log-uniform eigenvalues in [lo, hi]."""
    angle = rng.uniform(0, np.pi, count)
    ev = np.exp(rng.uniform(np.log(lo), np.log(hi), (count, 2)))
    c, s = np.cos(angle), np.sin(angle)
    r = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    return r @ (ev[:, :, None] * np.swapaxes(r, -1, -2))


def _pack(cov):
    return np.stack([cov[..., 0, 0], cov[..., 0, 1], cov[..., 1, 1]], axis=-1)


def _f32(a):
    return np.asarray(a, np.float32).astype(np.float64)


# --- smith: erfc, Λ, visibility --------------------------------------------------------------------


def test_erfcx_fit_is_reproducible_and_accurate():
    np.testing.assert_allclose(fit_erfcx_coefficients(), ERFCX_COEFFS, atol=1e-8)
    x = np.concatenate([np.linspace(0, 12, 20001), np.geomspace(12, 1e6, 2001)])
    assert np.abs(erfcx_approx(x) / erfcx(x) - 1).max() < 1.2e-7
    xs = np.linspace(-6, 26, 4001)
    assert np.abs(erfc_approx(xs) / erfc(xs) - 1).max() < 1.2e-7


@pytest.mark.parametrize("target", TARGETS)
def test_ms_erfc_against_scipy(target):
    x = np.linspace(-6.0, 9.1, 30001).astype(np.float32)
    got = glsl_eval("vec2(ms_erfc(x), ms_normalCdf(x))", {"x": x}, 2, includes=SMITH, target=target)
    xd = x.astype(np.float64)
    assert np.abs(got[:, 0] / erfc(xd) - 1).max() < 1.5e-6  # measured 6.7e-7
    # Φ(x) = erfc(−x/√2)/2: the rounding of x/√2 (≤ 6e-8 relative) costs up to x² ulp in the tail
    assert np.all(np.abs(got[:, 1] / norm.cdf(xd) - 1) < 1.5e-6 + 1.2e-7 * xd**2)
    beyond = glsl_eval("ms_erfc(x)", {"x": np.array([9.4, 20.0, 1e30], np.float32)}, includes=SMITH)
    assert np.all(beyond == 0.0)


def _lambda_by_quadrature(w, cov):
    """Λ(ω) = (1/μ) ∫_μ^∞ (q − μ) p₁(q) dq, p₁ = N(0, σ_s²) the slope density along d̂ = w_xy/|w_xy|."""
    wxy = np.hypot(w[0], w[1])
    d = w[:2] / wxy
    sigma = np.sqrt(d @ cov @ d)
    mu = w[2] / wxy
    tail = quad(lambda q: (q - mu) * norm.pdf(q, 0.0, sigma), mu, np.inf, epsabs=0, epsrel=1e-12)[0]
    return tail / mu


@pytest.mark.parametrize("cov", [ISOTROPIC, ANISOTROPIC], ids=["isotropic", "anisotropic"])
def test_lambda_against_its_defining_integral(cov):
    theta = np.array([5.0, 20.0, 40.0, 55.0, 70.0, 80.0, 85.0, 88.0, 89.5, 89.95])
    phi = np.array([0.0, 37.0, 90.0, 150.0, 233.0, 300.0])
    tt, pp = (g.ravel() for g in np.meshgrid(theta, phi))
    w = _direction(tt, pp)
    got = lambda_smith(w, cov)
    want = np.array([_lambda_by_quadrature(wi, cov) for wi in w])
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-300)
    assert want.min() < 1e-20 and want.max() > 10  # the directions span the useful range
    np.testing.assert_allclose(lambda_smith(w, _pack(cov)), got, rtol=1e-15)  # packed form


def test_lambda_limits():
    w = _direction(np.array([0.0, 30.0]), 0.0)
    assert lambda_smith(w[0], ANISOTROPIC) == 0.0  # normal incidence
    assert lambda_smith(w[1], np.zeros((2, 2))) == 0.0  # flat microsurface
    small = lambda_smith(
        np.broadcast_to(w[1], (6, 3)), ISOTROPIC * np.geomspace(1e-1, 1e-12, 6)[:, None, None]
    )
    assert np.all(np.isfinite(small)) and np.all(np.diff(small) <= 0) and small[-1] == 0.0
    # grazing: w_z -> 0+ stays finite, grows like φ(0)/ν − 1/2, capped by the clamp ν >= NU_MIN
    wz = np.array([1e-2, 1e-3, 1e-5, 1e-9, 0.0, -0.1])
    w = np.stack([np.sqrt(1 - wz**2), 0 * wz, wz], axis=-1)
    lam = lambda_smith(w, ISOTROPIC)
    assert np.all(np.isfinite(lam)) and np.all(np.diff(lam) >= 0)
    nu = np.maximum(wz / np.sqrt(1 - wz**2) / 0.3, NU_MIN)
    np.testing.assert_allclose(lam, norm.pdf(0) / nu - 0.5 + nu / 4, rtol=1e-3)  # small-ν expansion


def test_mills_rho_against_quadrature():
    x = np.array([0.0, 0.3, 1.0, 1.49, 1.51, 2.0, 2.99, 3.01, 6.0, 40.0, 1e3])

    def j(k, xi):
        return quad(lambda t: t**k * np.exp(-xi * t - 0.5 * t * t), 0, np.inf, epsabs=0, epsrel=1e-13)[0]

    want = np.array([[j(k, xi) / (k * j(k - 1, xi)) for k in (1, 2, 3)] for xi in x])
    np.testing.assert_allclose(np.stack(mills_rho(x), axis=1), want, rtol=1e-11)
    np.testing.assert_allclose(normal_loss_scaled(x), want[:, 0] / (x + want[:, 0]), rtol=1e-12)


@pytest.mark.parametrize("sigma_h", [1.0, 0.3])
def test_average_visibility_against_quadrature_of_eq12(sigma_h):
    """V̄ = ∫ P_h^(Λo+Λi) p_h dh / ∫ P_h^Λo p_h dh (eq. 12 with the errata's p_h in the denominator)."""
    pairs = [(0.0, 0.0), (0.0, 2.0), (0.3, 0.0), (0.2, 0.7), (1.5, 4.0), (12.0, 0.5), (40.0, 90.0)]
    lam_o, lam_i = (np.array(v) for v in zip(*pairs, strict=True))
    got = average_visibility(lam_o, lam_i)

    def moment(lam):
        f = lambda h: visibility(h, sigma_h, lam) * norm.pdf(h, 0, sigma_h)  # noqa: E731
        return quad(f, -12 * sigma_h, 12 * sigma_h, points=[0.0, 3 * sigma_h], epsabs=0, epsrel=1e-11)[0]

    want = np.array([moment(lo + li) / moment(lo) for lo, li in pairs])
    np.testing.assert_allclose(got, want, rtol=1e-9)
    np.testing.assert_allclose(moment(0.0), 1.0, rtol=1e-10)  # V = 1 without masking


def test_height_colour_filtering_matches_heitz_neyret_eq3():
    """C(h) = c0 + c1 P_h(h): the mean of C under V_o V_i p_h is c0 + c1 (Λ + 1)/(Λ + 2), Λ = Λo + Λi."""
    sigma_h, c0, c1 = 0.8, 0.25, 0.6
    for lam_o, lam_i in [(0.0, 0.0), (0.4, 0.1), (2.0, 3.0), (25.0, 7.0)]:

        def weight(h, lo=lam_o, li=lam_i):
            return visibility(h, sigma_h, lo) * visibility(h, sigma_h, li) * norm.pdf(h, 0, sigma_h)

        def integrate(f):
            return quad(f, -10 * sigma_h, 10 * sigma_h, points=[0.0, 2.5 * sigma_h], epsabs=0, epsrel=1e-11)[
                0
            ]

        mean = integrate(lambda h, wt=weight: (c0 + c1 * height_cdf(h, sigma_h)) * wt(h)) / integrate(weight)
        lam = lam_o + lam_i
        assert mean == pytest.approx(c0 + c1 * (lam + 1) / (lam + 2), rel=1e-9)


@pytest.mark.parametrize("target", TARGETS)
def test_glsl_smith_twins(target):
    n = 4000
    rng = np.random.default_rng(7)
    cos_theta = np.concatenate([rng.uniform(0, 1, n - 400), np.geomspace(1e-6, 1e-2, 200), np.ones(200)])
    phi = rng.uniform(0, 2 * np.pi, n)
    sin_theta = np.sqrt(1 - cos_theta**2)
    w = _f32(np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta], -1))
    cov = _random_covs(n, rng, 1e-6, 2.0)
    cov[:40] = 0.0  # flat
    cov[40:80] *= 1e-30  # nearly flat: ν overflows towards +inf, Λ -> 0
    cov = _f32(_pack(cov))
    got = glsl_eval("ms_lambda(w, cov)", {"w": w, "cov": cov}, includes=SMITH, target=target)
    assert np.all(np.isfinite(got)) and np.all(got[:80] == 0.0)
    want = lambda_smith(w, cov)
    representable = want > 1e-30
    # float32 limit: the rounding of q = w_xyᵀ Σ w_xy (relative ~1e-7 κ, κ its condition number, large
    # for nearly singular Σ) reaches Λ multiplied by d ln Λ / d ln q ≈ (ν² + 3)/2
    terms = w[:, 0] ** 2 * cov[:, 0] + 2 * np.abs(w[:, 0] * w[:, 1] * cov[:, 1]) + w[:, 1] ** 2 * cov[:, 2]
    q = w[:, 0] ** 2 * cov[:, 0] + 2 * w[:, 0] * w[:, 1] * cov[:, 1] + w[:, 1] ** 2 * cov[:, 2]
    nu = w[:, 2] / np.sqrt(np.where(q > 0, q, 1.0))
    rtol = 1e-4 + 2e-7 * (terms / np.where(q > 0, q, 1.0)) * (nu**2 + 3)
    rel = np.abs(got / np.where(representable, want, 1) - 1)
    assert np.all(rel[representable] < rtol[representable])
    assert np.mean(rel[representable] < 1e-4) > 0.99
    assert np.abs(got - want)[~representable].max() < 1e-30
    assert representable.sum() > 0.5 * n and want.max() > 100  # many large, small and zero values
    assert np.all(got[cos_theta == 1] == 0.0)

    h = _f32(rng.normal(0, 2, n))
    sigma_h = _f32(rng.uniform(0.2, 2, n))
    lam_o = _f32(np.exp(rng.uniform(-6, 6, n)) * (rng.uniform(size=n) > 0.1))
    lam_i = _f32(np.exp(rng.uniform(-6, 6, n)))
    got = glsl_eval(
        "vec3(ms_heightCdf(h, sh), ms_visibility(h, sh, lo), ms_averageVisibility(lo, li))",
        {"h": h, "sh": sigma_h, "lo": lam_o, "li": lam_i},
        3,
        includes=SMITH,
        target=target,
    )
    x = h / sigma_h  # the rounding of h/σ_h costs up to x² ulp in the lower tail (as for ms_normalCdf)
    cdf = height_cdf(h, sigma_h)
    normal = cdf > 1e-37  # erfc flushes to 0 below the normal floats
    assert np.all((np.abs(got[:, 0] / cdf - 1) < 1.5e-6 + 1.2e-7 * x**2)[normal])
    assert np.all(got[~normal, 0] < 1e-37)
    vis = visibility(h, sigma_h, lam_o)
    # ln V = Λ ln P: Λ times the error of ln P (P's relative error, or ~2 float32 ulp near P = 1)
    ok = normal & (vis > 1e-30)
    log_p = np.log(cdf[ok])
    tol = 2e-6 + lam_o[ok] * (2e-7 + np.abs(log_p) * (1.5e-6 + 1.2e-7 * x[ok] ** 2))
    assert np.all(np.abs(np.log(got[ok, 1]) - np.log(vis[ok])) <= tol)
    assert np.all(got[lam_o == 0, 1] == 1.0)
    np.testing.assert_allclose(got[:, 2], average_visibility(lam_o, lam_i), rtol=1e-6)

    x = np.concatenate([np.linspace(0, 4, 2001), np.geomspace(4, 1e4, 500)]).astype(np.float32)
    got = glsl_eval(
        "vec4(ms_millsRho(x), ms_normalLossScaled(x))", {"x": x}, 4, includes=SMITH, target=target
    )
    want = np.stack([*mills_rho(_f32(x)), normal_loss_scaled(_f32(x))], axis=1)
    assert np.abs(got / want - 1).max() < 2e-5  # measured 9e-6 (ρ3 near x = 1.4), J_1 7e-6 below x = 4


# --- Smith over a sphere (curved_shadowing.py) ---------------------------------------------------------


def test_curved_shadowing_matches_a_ray_cast_over_a_curving_fractal_left_out_of_the_fit():
    """The curved-elevation model against fresh ray casts of shadow rays lifted by t²/2R, on a fractal and
    radius that the constants were not fitted to; plane Smith (no light at or below the horizon) misses
    by far more. Both are taken through the plane ray cast's ratio to Smith (`plane_bias`), as in the fit."""
    fractal = Fractal(octaves=5, amplitude=0.01, frequency=30.0, gain=0.55)
    radius = 0.7
    bias = plane_bias(fractal)
    slopes = np.array([-0.05, -0.02, 0.0, 0.03, 0.06, 0.12])
    cast = np.array([lit_fraction(fractal, radius, mu, seed=3) for mu in slopes])
    model = bias * curved_lit_fraction(slopes, fractal, radius)
    plane = bias * smith_lit_fraction(slopes, effective_slope_variance(fractal))
    rms_model = np.sqrt(np.mean((model - cast) ** 2))
    rms_plane = np.sqrt(np.mean((plane - cast) ** 2))
    assert cast[0] > 0.02 and cast[2] > 0.1  # the curving surface lets light in below and at the horizon
    assert rms_model < 0.03 and rms_model < 0.25 * rms_plane  # measured 0.014 against 0.120


@pytest.mark.parametrize("target", TARGETS)
def test_glsl_curved_light_twin(target):
    rng = np.random.default_rng(11)
    n = 3000
    elevation = rng.uniform(-0.3, 1.5, n)
    azimuth = rng.uniform(0, 2 * np.pi, n)
    across = np.cos(elevation)
    w = _f32(np.stack([across * np.cos(azimuth), across * np.sin(azimuth), np.sin(elevation)], -1))
    sigma = _f32(np.exp(rng.uniform(np.log(1e-4), np.log(0.05), n)))
    radius = _f32(rng.uniform(0.3, 3.0, n))
    got = glsl_eval(
        "vec4(ms_curvedLight(w, s, r, 0.45), ms_curvedDescent(w, s, r, 0.22))",
        {"w": w, "s": sigma, "r": radius},
        4,
        includes=SMITH,
        target=target,
    )
    mu = w[:, 2] / np.linalg.norm(w[:, :2], axis=1)
    raised = got[:, 2] / np.linalg.norm(got[:, :2], axis=1)
    np.testing.assert_allclose(np.linalg.norm(got[:, :3], axis=1), 1.0, atol=2e-6)
    np.testing.assert_allclose(raised, curved_elevation(mu, sigma, radius, 0.45), rtol=2e-5)
    np.testing.assert_allclose(got[:, 3], descent_factor(mu, sigma, radius, 0.22), rtol=1e-4, atol=1e-30)
    assert np.all(raised >= np.maximum(mu, 0) - 1e-7) and np.any(got[:, 3] < 0.5)


# --- height filtering -------------------------------------------------------------------------------


def _dh_moments_by_quad(L):
    """(μ_d, σ_d) of D_h ∝ Φ(h)^L φ(h) (σ_h = 1) by adaptive quadrature, independent of the bake's rule."""
    peak = norm.ppf((L + 1) / (L + 2)) if L > 0 else 0.0

    def integrate(f):
        return quad(
            lambda h: f(h) * np.exp(L * norm.logcdf(h) + norm.logpdf(h)),
            -12,
            12,
            points=[peak - 1, peak, peak + 1],
            limit=200,
            epsabs=1e-13,
            epsrel=1e-10,
        )[0]

    z = integrate(lambda h: 1.0)
    mu = integrate(lambda h: h) / z
    return mu, np.sqrt(integrate(lambda h: (h - mu) ** 2) / z)


def test_height_filtering_quadrature_against_closed_forms():
    mu, sd = height_filtering_moments(np.array([0.0, 1.0, 2.0]))
    assert abs(mu[0]) < 1e-12 and sd[0] == pytest.approx(1.0, abs=1e-12)  # D_h = p_h at L = 0
    # integer L: D_h is the law of the largest of L + 1 standard normals
    assert mu[1] == pytest.approx(1 / np.sqrt(np.pi), abs=1e-12)
    assert sd[1] == pytest.approx(np.sqrt(1 - 1 / np.pi), abs=1e-12)
    assert mu[2] == pytest.approx(1.5 / np.sqrt(np.pi), abs=1e-12)
    assert sd[2] ** 2 + mu[2] ** 2 == pytest.approx(1 + np.sqrt(3) / (2 * np.pi), abs=1e-12)
    for L in (0.5, 3.7, 41.0, 800.0, 1e4):
        np.testing.assert_allclose(height_filtering_moments(L), _dh_moments_by_quad(L), atol=1e-10)
    # DESIGN.md: with σ_h = 1 and L = 0.5 the true mean is 0.344
    assert height_filtering_moments(0.5)[0] == pytest.approx(0.344, abs=5e-4)


def test_height_filtering_table_within_1e3_sigma_h():
    table = height_filtering_table()
    assert table.data.shape == (256, 2) and table.data.dtype == np.float32
    # fresh adaptive quadrature at random off-grid L and at the table's own nodes
    rng = np.random.default_rng(2014)
    L = np.concatenate([rng.uniform(0, 100, 30), np.exp(rng.uniform(-8, np.log(100), 20)), [0.0, 100.0]])
    want = np.array([_dh_moments_by_quad(v) for v in L])
    assert np.abs(table.lookup(L) - want).max() < 1e-3
    nodes = table.l_nodes()[::37]
    np.testing.assert_allclose(table.data[::37], [_dh_moments_by_quad(v) for v in nodes], atol=1e-6)
    # dense sweep of [0, 100] against the (quadrature-checked) float64 moments: both moments
    dense = np.concatenate([np.linspace(0, 100, 8001), np.geomspace(1e-7, 100, 2001)])
    err = np.abs(table.lookup(dense) - np.stack(height_filtering_moments(dense), axis=1)).max(axis=0)
    assert np.all(err < 1e-4), err  # measured 4.7e-5 (μ_d), 2.4e-5 (σ_d)


def test_height_filtering_bake_is_deterministic(tmp_path, monkeypatch):
    monkeypatch.setenv("PREFILTER_CACHE", str(tmp_path))
    first = height_filtering_table(n=32, l_max=50.0)
    second = height_filtering_table(n=32, l_max=50.0)  # from the cache
    assert len(list(tmp_path.iterdir())) == 1
    assert first.data.tobytes() == second.data.tobytes()
    np.testing.assert_allclose(first.lookup(first.l_nodes()), first.data, atol=1e-7)


@pytest.mark.parametrize("target", TARGETS)
def test_glsl_height_filtering_lookup(target):
    table = height_filtering_table()
    texture = table.upload(gl_context())
    rng = np.random.default_rng(2015)
    L = np.concatenate([rng.uniform(0, 100, 3000), np.exp(rng.uniform(-10, np.log(1e4), 1000)), [0.0]])
    L = L.astype(np.float32)
    try:
        got = glsl_eval(
            "vec4(ms_heightFiltering(tab, L), ms_heightFilteringFit(L))",
            {"L": L},
            4,
            includes=("microsurface/height_filtering.glsl",),
            target=target,
            prelude="uniform sampler2D tab;",
            textures={"tab": texture},
        )
    finally:
        texture.release()
    np.testing.assert_allclose(got[:, :2], table.lookup(_f32(L)), atol=2e-6)  # the twin, same interpolation
    in_range = L <= 100
    exact = np.stack(height_filtering_moments(_f32(L)), axis=1)
    assert np.abs(got[in_range, :2] - exact[in_range]).max() < 1e-3
    sparse = np.flatnonzero(in_range)[:12]  # and against fresh adaptive quadrature
    want = np.array([_dh_moments_by_quad(float(v)) for v in L[sparse]])
    assert np.abs(got[sparse, :2] - want).max() < 1e-3
    np.testing.assert_allclose(
        got[:, 2:], np.stack(height_filtering_fit(_f32(L)), axis=1), rtol=2e-6, atol=2e-6
    )


def test_log_fit_against_design_numbers():
    """DESIGN.md errata: at σ_h = 1, L = 0.5 the fit (eq. 16) gives 0.474 where the truth is 0.344."""
    mu, sd = height_filtering_fit(0.5)
    assert mu == pytest.approx(0.474, abs=5e-4)
    assert mu - _dh_moments_by_quad(0.5)[0] == pytest.approx(0.474 - 0.344, abs=1e-3)
    mu2, sd2 = height_filtering_fit(0.5, sigma_h=2.0)
    assert (mu2, sd2) == pytest.approx((2 * mu, 2 * sd))
    assert height_filtering_fit(0.0) == pytest.approx((0.0, 1.0))


# --- visible slopes ---------------------------------------------------------------------------------


def test_visible_slope_moments_1d_against_quadrature():
    """(z̄, var_z) of (a − z)⁺ φ(z), in z for moderate a and in t = a − z where φ(a) underflows."""
    for a in (-40.0, -12.0, -5.0, -2.5, -1.6, -1.4, -0.5, 0.0, 0.7, 3.0, 9.0, 30.0):
        if a > -8:
            m = [
                quad(lambda z, k=k, a=a: z**k * (a - z) * norm.pdf(z), -40, a, epsabs=0, epsrel=1e-12)[0]
                for k in (0, 1, 2)
            ]
            zbar, var = m[1] / m[0], m[2] / m[0] - (m[1] / m[0]) ** 2
        else:
            m = [
                quad(
                    lambda t, k=k, a=a: t ** (k + 1) * np.exp(a * t - 0.5 * t * t),
                    0,
                    np.inf,
                    epsabs=0,
                    epsrel=1e-12,
                )[0]
                for k in (0, 1, 2)
            ]
            zbar, var = a - m[1] / m[0], m[2] / m[0] - (m[1] / m[0]) ** 2
        got = visible_slope_moments_1d(a)
        assert got[0] == pytest.approx(zbar, rel=1e-9, abs=1e-12), a
        assert got[1] == pytest.approx(var, rel=1e-8, abs=1e-12), a


def _weighted_moments_with_errors(s, w):
    """Weighted mean/covariance of samples s (n, 2) and their standard errors (ratio estimator)."""
    total = w.sum()
    mean = (w[:, None] * s).sum(0) / total
    d = s - mean
    mean_se = np.sqrt((w[:, None] ** 2 * d**2).sum(0)) / total
    outer = d[:, :, None] * d[:, None, :]
    cov = (w[:, None, None] * outer).sum(0) / total
    cov_se = np.sqrt((w[:, None, None] ** 2 * (outer - cov) ** 2).sum(0)) / total
    return mean, mean_se, cov, cov_se


@pytest.mark.parametrize(
    "theta,phi", [(0.0, 0.0), (30.0, 100.0), (60.0, 200.0), (80.0, 30.0), (80.0, 250.0), (88.0, 0.0)]
)
def test_visible_slopes_against_monte_carlo(theta, phi):
    rng = np.random.default_rng(int(theta * 1000 + phi))
    mean = np.array([0.12, -0.2])
    s = rng.multivariate_normal(mean, ANISOTROPIC, 1_200_000)
    wo = _direction(theta, phi)
    w = np.maximum(wo[2] - s @ wo[:2], 0.0)
    mc_mean, mean_se, mc_cov, cov_se = _weighted_moments_with_errors(s, w)
    got_mean, got_cov = visible_slope_moments(wo, mean, ANISOTROPIC)
    assert np.all(np.abs(got_mean - mc_mean) <= 5 * mean_se + 1e-12), (got_mean, mc_mean, mean_se)
    assert np.all(np.abs(got_cov - mc_cov) <= 5 * cov_se + 1e-12), (got_cov, mc_cov, cov_se)
    area_se = w.std() / np.sqrt(len(w))
    assert abs(projected_area(wo, mean, ANISOTROPIC) - w.mean()) <= 5 * area_se + 1e-12
    if theta >= 60:  # the view moves the distribution by many standard errors
        assert np.abs(got_mean - mean).max() > 50 * mean_se.max()


def test_visible_slopes_limits_and_packed_form():
    mean = np.array([0.3, -0.1])
    m, c = visible_slope_moments([0.0, 0.0, 1.0], mean, ANISOTROPIC)  # normal view: D_s = p_s
    np.testing.assert_allclose(m, mean, atol=1e-15)
    np.testing.assert_allclose(c, ANISOTROPIC, atol=1e-15)
    wo = _direction(70.0, 20.0)
    m, c = visible_slope_moments(wo, mean, np.zeros((2, 2)))  # no slope variance: D_s = δ(s − s̄)
    np.testing.assert_allclose(m, mean, atol=1e-15)
    np.testing.assert_allclose(c, 0.0, atol=1e-15)
    assert projected_area(wo, mean, np.zeros((2, 2))) == pytest.approx(max(wo[2] - wo[:2] @ mean, 0))
    # continuity as Σ -> 0 (σ_u -> 0 with a -> ∞)
    m, c = visible_slope_moments(wo, mean, ANISOTROPIC * 1e-10)
    np.testing.assert_allclose(m, mean, atol=1e-5)
    m2, c2 = visible_slope_moments(wo, mean, _pack(ANISOTROPIC))
    m1, c1 = visible_slope_moments(wo, mean, ANISOTROPIC)
    np.testing.assert_allclose(m2, m1, rtol=1e-15)
    np.testing.assert_allclose(c2, c1, rtol=1e-15)
    # vectorised over leading dimensions
    wos = _direction(np.array([10.0, 50.0, 85.0]), np.array([0.0, 90.0, 200.0]))
    mv, cv = visible_slope_moments(wos, mean, ANISOTROPIC)
    assert mv.shape == (3, 2) and cv.shape == (3, 2, 2)
    np.testing.assert_allclose(cv[2], visible_slope_moments(wos[2], mean, ANISOTROPIC)[1], rtol=1e-15)


def _gaussian_surface_slopes(n=512, lengths=(4.0, 2.0), angle=0.5, seed=3):
    """Slopes (n², 2) of a periodic Gaussian random height field (Gaussian spectrum, rotated
    anisotropic correlation lengths in texels) synthesised by FFT filtering of white noise, by central
    finite differences on the unit grid."""
    rng = np.random.default_rng(seed)
    k = 2 * np.pi * np.fft.fftfreq(n)
    kx, ky = np.meshgrid(k, k, indexing="xy")
    u = np.cos(angle) * kx + np.sin(angle) * ky
    v = -np.sin(angle) * kx + np.cos(angle) * ky
    amplitude = np.exp(-0.25 * ((u * lengths[0]) ** 2 + (v * lengths[1]) ** 2))  # √ of the spectrum
    h = np.real(np.fft.ifft2(np.fft.fft2(rng.standard_normal((n, n))) * amplitude))
    h /= h.std()
    sx = 0.5 * (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1))
    sy = 0.5 * (np.roll(h, -1, axis=0) - np.roll(h, 1, axis=0))
    return np.stack([sx.ravel(), sy.ravel()], axis=1)


def test_visible_slopes_on_a_sampled_random_surface():
    tilt = np.array([0.15, -0.1])  # a macro tilt: h + tilt·x adds it to every facet slope
    s = _gaussian_surface_slopes() + tilt
    mean, cov = s.mean(axis=0), np.cov(s.T)
    sigma_s = np.sqrt(np.linalg.eigvalsh(cov).max())
    assert 0.3 < sigma_s < 0.6 and np.linalg.eigvalsh(cov).min() < 0.5 * sigma_s**2  # anisotropic
    for phi in (0.0, 135.0, 250.0):
        wo = _direction(60.0, phi)
        area = np.maximum(wo[2] - s @ wo[:2], 0.0)  # projected area of each facet towards ω_o
        facet_mean, _, facet_cov, _ = _weighted_moments_with_errors(s, area)
        got_mean, got_cov = visible_slope_moments(wo, mean, cov)
        assert np.abs(got_mean - facet_mean).max() < 0.02 * sigma_s  # measured <= 0.15 %
        assert np.abs(got_cov - facet_cov).max() < 0.03 * sigma_s**2  # measured <= 0.9 %
        assert np.abs(got_mean - mean).max() > 0.3 * sigma_s  # while the view moves D_s by ~45 %
        assert projected_area(wo, mean, cov) == pytest.approx(area.mean(), rel=0.01)


def _gaussian_moment(p, q, mean, cov):
    """E[X^p Y^q] for (X, Y) ~ N(mean, cov): central moments by Stein's identity
    E[X f] = Σxx E[∂x f] + Σxy E[∂y f], then the binomial expansion about the mean."""
    from math import comb

    central = {}

    def c(i, j):
        if i < 0 or j < 0:
            return 0.0
        if (i, j) not in central:
            if i == 0 and j == 0:
                central[i, j] = 1.0
            elif i > 0:
                central[i, j] = (i - 1) * cov[0, 0] * c(i - 2, j) + j * cov[0, 1] * c(i - 1, j - 1)
            else:
                central[i, j] = (j - 1) * cov[1, 1] * c(i, j - 2)
        return central[i, j]

    return sum(
        comb(p, i) * comb(q, j) * mean[0] ** (p - i) * mean[1] ** (q - j) * c(i, j)
        for i in range(p + 1)
        for j in range(q + 1)
    )


GH_CASES = [
    (np.array([0.1, -0.3]), ANISOTROPIC),
    (np.array([-0.5, 0.2]), np.array([[0.3, -0.2], [-0.2, 0.4]])),
    (np.array([0.0, 0.4]), np.array([[0.16, 0.16], [0.16, 0.16]])),  # semidefinite (rank 1)
    (np.array([0.2, 0.1]), np.array([[0.0, 0.0], [0.0, 0.09]])),  # Σxx = 0
]
MONOMIALS = [(p, q) for p in range(6) for q in range(6) if p + q <= 5]


def _check_cubature(nodes, weights, mean, cov, atol):
    for p, q in MONOMIALS:
        got = np.sum(weights * nodes[:, 0] ** p * nodes[:, 1] ** q)
        assert got == pytest.approx(_gaussian_moment(p, q, mean, cov), abs=atol), (p, q)
    # and not beyond: degree 6 along a direction with variance is not integrated exactly
    got6 = np.sum(weights * (nodes[:, 1] - mean[1]) ** 6)
    assert abs(got6 - _gaussian_moment(0, 6, np.zeros(2), cov)) > 1e-3 * cov[1, 1] ** 3


def test_gauss_hermite_2d_exact_to_degree_5():
    for mean, cov in GH_CASES:
        nodes, weights = gauss_hermite_2d(mean, cov, 3)
        assert nodes.shape == (9, 2) and weights.shape == (9,)
        _check_cubature(nodes, weights, mean, cov, atol=1e-12)
    nodes, weights = gauss_hermite_2d(GH_CASES[0][0], GH_CASES[0][1], 5)  # other orders: degree 9
    assert np.sum(weights * nodes[:, 0] ** 8) == pytest.approx(
        _gaussian_moment(8, 0, *GH_CASES[0]), rel=1e-12
    )


GH_PRELUDE = """
vec4 visMeanCov(vec3 wo, vec2 mean, vec3 cov) {
    vec2 m;
    vec3 c;
    ms_visibleSlopes(wo, mean, cov, m, c);
    return vec4(m, c.xy);
}
vec2 visCovArea(vec3 wo, vec2 mean, vec3 cov) {
    vec2 m;
    vec3 c;
    float area = ms_visibleSlopes(wo, mean, cov, m, c);
    return vec2(c.z, area);
}
"""
VISIBLE = ("microsurface/visible_slopes.glsl",)


@pytest.mark.parametrize("target", TARGETS)
def test_glsl_visible_slopes_twin(target):
    rng = np.random.default_rng(21)
    n = 3000
    theta = np.degrees(np.arccos(rng.uniform(0.0, 1.0, n)))
    theta[:300] = 0.0  # normal view
    theta[300:600] = rng.uniform(85.0, 89.99, 300)  # grazing
    wo = _f32(_direction(theta, rng.uniform(0, 360, n)))
    cov = _random_covs(n, rng, 1e-4, 0.5)
    cov[:100] = 0.0  # flat microsurface
    cov = _f32(_pack(cov))
    mean = _f32(rng.normal(0, 0.4, (n, 2)))  # includes means facing away from the view (a < 0)
    inputs = {"wo": wo, "mean": mean, "cov": cov}
    a = glsl_eval("visMeanCov(wo, mean, cov)", inputs, 4, includes=VISIBLE, target=target, prelude=GH_PRELUDE)
    b = glsl_eval("visCovArea(wo, mean, cov)", inputs, 2, includes=VISIBLE, target=target, prelude=GH_PRELUDE)
    want_mean, want_cov = visible_slope_moments(wo, mean, cov)
    scale = np.sqrt(cov[:, 0] + cov[:, 2])[:, None]  # slope standard deviation
    shift = np.abs(want_mean - mean).max(axis=1, keepdims=True)
    assert np.all(np.abs(a[:, :2] - want_mean) <= 1e-4 * (scale + shift) + 1e-6)
    got_cov = np.stack([a[:, 2], a[:, 3], b[:, 0]], axis=1)
    assert np.all(np.abs(got_cov - _pack(want_cov)) <= 2e-4 * scale**2 + 1e-9)
    want_area = projected_area(wo, mean, cov)
    assert np.all(np.abs(b[:, 1] - want_area) <= 1e-5 * np.maximum(want_area, 1e-3) + 1e-12)
    c = wo[:, 2] - np.sum(wo[:, :2] * mean, axis=1)
    assert (c < 0).sum() > 100  # the back-facing side (a < 0) is exercised


# --- Lambert under the slope distribution, and the slope colour where the light falls --------------


def _lambert_cases(count, rng):
    mean = rng.normal(0.0, 0.3, (count, 2))
    cov = _random_covs(count, rng, 1e-3, 0.3)
    wi = _direction(rng.uniform(0.0, 75.0, count), rng.uniform(0.0, 360.0, count))
    return mean, cov, wi


def _lambert_monte_carlo(mean, cov, wi, rng, n=200_000):
    s = rng.multivariate_normal(mean, cov, n)
    normals = np.concatenate([-s, np.ones((n, 1))], axis=1)
    cosine = np.maximum(normals @ wi / np.linalg.norm(normals, axis=1), 0.0)
    return s, cosine


def test_lambert_moments_against_monte_carlo():
    """E[L] and Cov(s, L) of Lambert's cosine over Gaussian slopes: the 9-node cubature against 200 000
    sampled slopes per case (light up to 75° from the normal, slope deviations up to 0.55). Measured: E[L]
    within 0.0032, Cov(s, L) within 0.015 of the slopes' deviation (Lambert's kink at the terminator)."""
    rng = np.random.default_rng(5)
    mean, cov, wi = _lambert_cases(40, rng)
    got_l, got_cov = lambert_moments(mean, _pack(cov), wi)
    for k in range(len(mean)):
        s, cosine = _lambert_monte_carlo(mean[k], cov[k], wi[k], rng)
        assert abs(got_l[k] - cosine.mean()) < 0.005, k
        want = ((s - s.mean(axis=0)) * (cosine - cosine.mean())[:, None]).mean(axis=0)
        np.testing.assert_allclose(got_cov[k], want, atol=0.02 * np.sqrt(np.trace(cov[k])), err_msg=str(k))


@pytest.mark.parametrize("target", TARGETS)
def test_glsl_lambert_moments_twin(target):
    rng = np.random.default_rng(6)
    mean, cov, wi = _lambert_cases(500, rng)
    mean, cov, wi = _f32(mean), _f32(_pack(cov)), _f32(wi / np.linalg.norm(wi, axis=1, keepdims=True))
    got = glsl_eval("ms_lambertMoments(mean, cov, wi)", {"mean": mean, "cov": cov, "wi": wi}, 3,
                    includes=VISIBLE, target=target)  # fmt: skip
    want_l, want_cov = lambert_moments(mean, cov, wi)
    np.testing.assert_allclose(got[:, 0], want_l, atol=2e-6)
    np.testing.assert_allclose(got[:, 1:], want_cov, atol=2e-6)


def test_slope_colour_under_light_against_monte_carlo():
    """microsurface.frag's ms_slopeColourUnderLight (with ms_slopeColourDerivative): E[C(x) L]/E[L] for
    x = scale s_x + offset through micro-slopes-sphere's slope colour map, as C̄ + ∂C̄/∂μ Cov(s_x, L)/E[L]
    (Stein's lemma; ∂C̄/∂μ over ± half the deviation; C̄ by colormap/gaussian.py's exact edge form),
    against 200 000 sampled slopes per case. The plain filtered colour C̄ = E[C] misses by what the
    correlation of colour and light adds. Measured (mean over the cases of the largest channel error):
    0.043 for C̄ alone, 0.0056 with the term."""
    from prefilter.colormap.gaussian import gaussian_average
    from prefilter.scene import resolve_scene

    colours = resolve_scene("micro-slopes-sphere").objects[0].material.maps["slope"]
    table, scale, offset = colours.table, colours.scale, colours.offset
    rng = np.random.default_rng(7)
    mean, cov, wi = _lambert_cases(30, rng)
    e_l, cov_sl = lambert_moments(mean, _pack(cov), wi)
    plain_err, lit_err = [], []
    for k in range(len(mean)):
        if e_l[k] < 0.05:
            continue  # (the light barely reaches these slopes)
        s, cosine = _lambert_monte_carlo(mean[k], cov[k], wi[k], rng)
        truth = (table.point(scale * s[:, 0] + offset) * cosine[:, None]).mean(axis=0) / cosine.mean()
        mu, sigma = scale * mean[k, 0] + offset, abs(scale) * np.sqrt(cov[k, 0, 0])
        plain = gaussian_average(table, mu, sigma)
        h = max(0.5 * sigma, 1.0 / 256.0)  # in the map's argument; the shader works in slope units
        above, below = gaussian_average(table, mu + h, sigma), gaussian_average(table, mu - h, sigma)
        derivative = (above - below) / (2.0 * h)
        lit = np.clip(plain + derivative * scale * cov_sl[k, 0] / e_l[k], 0.0, 1.0)
        plain_err.append(np.abs(plain - truth).max())
        lit_err.append(np.abs(lit - truth).max())
    assert len(lit_err) >= 20
    assert np.mean(lit_err) < 0.25 * np.mean(plain_err), (np.mean(lit_err), np.mean(plain_err))
    assert np.mean(lit_err) < 0.008


def test_slope_colour_under_an_environment_against_monte_carlo():
    """The same term under an environment's irradiance E (SH9 of the low-sun sky), per channel:
    E[C E] = C̄ Ē + ∂C̄/∂μ Cov(s_x, E) with Cov from irradiance.filtered_irradiance_moments, against
    200 000 sampled slopes per case on frames tilted towards and away from the sun. Measured (mean over
    the cases of the largest channel error, relative to the mean radiance): 0.028 for C̄ Ē alone, 0.0039
    with the term."""
    from pathlib import Path

    from scipy.spatial.transform import Rotation

    from prefilter.colormap.gaussian import gaussian_average
    from prefilter.microsurface.irradiance import (
        filtered_irradiance_moments,
        irradiance_sh,
        read_environment,
        sh9_project,
        slope_normals,
    )
    from prefilter.scene import resolve_scene

    data = Path(__file__).resolve().parent.parent / "src/prefilter/scenes/data"
    coeffs = sh9_project(read_environment(data / "sky-low-sun.exr"))
    colours = resolve_scene("micro-slopes-sphere").objects[0].material.maps["slope"]
    table, scale, offset = colours.table, colours.scale, colours.offset
    rng = np.random.default_rng(8)
    mean = rng.normal(0.0, 0.3, (16, 2))
    cov = _random_covs(16, rng, 1e-3, 0.3)
    d = np.array([1.0, 0.0])
    plain_err, term_err = [], []
    for k in range(len(mean)):
        frame = Rotation.from_rotvec(rng.normal(0.0, 0.5, 3)).as_matrix()
        s = rng.multivariate_normal(mean[k], cov[k], 200_000)
        e = irradiance_sh(coeffs, slope_normals(frame, s))
        truth = (table.point(scale * s[:, 0] + offset)[:, :3] * e).mean(axis=0)
        e_mean, e_cov = filtered_irradiance_moments(coeffs, frame, mean[k], cov[k], d)
        mu, sigma = scale * mean[k, 0] + offset, abs(scale) * np.sqrt(cov[k, 0, 0])
        plain = gaussian_average(table, mu, sigma)[:3] * e_mean
        h = max(0.5 * sigma, 1.0 / 256.0)
        derivative = (gaussian_average(table, mu + h, sigma) - gaussian_average(table, mu - h, sigma)) / (
            2.0 * h
        )
        with_term = np.maximum(plain + derivative[:3] * scale * e_cov, 0.0)
        plain_err.append(np.abs(plain - truth).max() / truth.mean())
        term_err.append(np.abs(with_term - truth).max() / truth.mean())
    assert np.mean(term_err) < 0.25 * np.mean(plain_err), (np.mean(term_err), np.mean(plain_err))
    assert np.mean(term_err) < 0.008, np.mean(term_err)
