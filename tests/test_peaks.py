"""Phong peaks (Fournier 1992 §2.1–§2.3): normalised lobes, the hemisphere grid, spreading, exact peaks
and the non-linear least-squares fit. Oracles: quadrature, closed forms, and residuals recomputed here."""

import numpy as np
import pytest
from scipy import integrate

from prefilter.normals.peaks import HemisphereGrid, Peaks, exact_peaks, fit_peaks, lobe, spread

GRID = HemisphereGrid()


def tilted(theta_deg, phi_deg=0.0):
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def ratios(peaks: Peaks, values, grid=GRID):
    """Weighted residual RMS / weighted data RMS and max|residual| / max|data|, recomputed here."""
    r = peaks.evaluate(grid.directions) - values
    w = grid.solid_angles
    return np.sqrt(np.sum(w * r * r) / np.sum(w * values * values)), np.max(np.abs(r)) / np.max(
        np.abs(values)
    )


def check_fit(peaks: Peaks, values, tolerance=0.05):
    """The reported ratios are the achieved ones, and within the stopping tolerance."""
    rms, mx = ratios(peaks, values)
    assert peaks.rms_ratio == pytest.approx(rms, rel=1e-9, abs=1e-12)
    assert peaks.max_ratio == pytest.approx(mx, rel=1e-9, abs=1e-12)
    assert rms < tolerance and mx < tolerance
    assert not peaks.exact
    np.testing.assert_allclose(np.linalg.norm(peaks.directions, axis=1), 1.0, atol=1e-12)
    assert np.all(peaks.amplitudes >= 0.0) and np.all(peaks.exponents >= 1.0)


# --- the normalised lobe ------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [0, 1, 20, 500])
def test_lobe_integrates_to_one_over_the_sphere(n):
    # about the lobe's axis: ∫_0^π lobe(cos θ) 2π sin θ dθ, the lower half included (where it is 0)
    value, _ = integrate.quad(
        lambda t: lobe(np.cos(t), n) * 2.0 * np.pi * np.sin(t),
        0.0,
        np.pi,
        points=[0.02, 0.05, 0.1, 0.2, 0.5, np.pi / 2],
        limit=400,
        epsabs=1e-12,
    )
    assert value == pytest.approx(1.0, abs=1e-8)


@pytest.mark.parametrize("n", [1, 20])
def test_lobe_integrates_to_one_about_a_tilted_axis(n):
    # midpoint rule on a fine (θ, φ) grid of the whole sphere, axis tilted 40° from the grid's pole
    nt, nphi = 1200, 1200
    t = (np.arange(nt) + 0.5) * np.pi / nt
    p = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    tt, pp = np.meshgrid(t, p, indexing="ij")
    omega = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1)
    total = np.sum(lobe(omega @ tilted(40.0, 10.0), n) * np.sin(tt)) * (np.pi / nt) * (2 * np.pi / nphi)
    assert total == pytest.approx(1.0, abs=2e-4)


def test_lobe_closed_form_and_clamp():
    c = np.array([-0.5, 0.0, 0.3, 1.0])
    np.testing.assert_allclose(lobe(c, 3.0), [0.0, 0.0, 4 / (2 * np.pi) * 0.027, 4 / (2 * np.pi)])
    np.testing.assert_allclose(lobe(c, 0.0), [0.0, 0.0, 1 / (2 * np.pi), 1 / (2 * np.pi)])


def test_peaks_evaluate_is_the_sum_of_lobes():
    d1, d2 = tilted(0.0), tilted(60.0, 90.0)
    peaks = Peaks(np.array([d1, d2]), np.array([0.7, 0.3]), np.array([10.0, 2.0]))
    omegas = np.array([tilted(0.0), tilted(30.0, 90.0), tilted(80.0, 270.0), tilted(45.0, 0.0)])
    expected = [
        0.7 * 11 / (2 * np.pi) * max(o @ d1, 0) ** 10 + 0.3 * 3 / (2 * np.pi) * max(o @ d2, 0) ** 2
        for o in omegas
    ]
    np.testing.assert_allclose(peaks.evaluate(omegas), expected, rtol=1e-13)
    assert len(peaks) == 2


# --- the hemisphere grid ------------------------------------------------------------------------------


def test_default_grid_is_fournier_18_by_72_plus_pole():
    assert GRID.size == 18 * 72 + 1 == 1297
    assert GRID.directions.shape == (1297, 3) and GRID.solid_angles.shape == (1297,)
    np.testing.assert_allclose(np.linalg.norm(GRID.directions, axis=1), 1.0, atol=1e-14)
    assert np.all(GRID.directions[:, 2] > 0.0)
    np.testing.assert_array_equal(GRID.directions[0], [0.0, 0.0, 1.0])
    assert GRID.solid_angles.sum() == pytest.approx(2 * np.pi, rel=1e-13)
    assert np.all(GRID.solid_angles > 0.0)
    theta = np.degrees(np.arccos(np.clip(GRID.directions[1:, 2], -1, 1)))
    rings = np.unique(np.round(theta, 6))
    assert rings.size == 18
    np.testing.assert_allclose(np.diff(rings), (90 - 5 / 12) / 18, atol=1e-6)  # ≈ every 5°
    phi = np.degrees(np.arctan2(GRID.directions[1:73, 1], GRID.directions[1:73, 0])) % 360
    np.testing.assert_allclose(np.diff(phi), 5.0, atol=1e-9)
    # the pole sample covers θ < 5/12°: about half the area of a cell of the first ring (Fournier §2.3)
    assert 0.3 < GRID.solid_angles[0] / GRID.solid_angles[1] < 0.7
    assert GRID.solid_angles[0] == pytest.approx(2 * np.pi * (1 - np.cos(np.radians(5 / 12))))


@pytest.mark.parametrize("n_theta, n_phi, cap", [(9, 36, 5 / 12), (36, 144, 0.2), (1, 4, 10.0)])
def test_grid_sizes_are_configurable(n_theta, n_phi, cap):
    grid = HemisphereGrid(n_theta=n_theta, n_phi=n_phi, pole_cap_degrees=cap)
    assert grid.size == n_theta * n_phi + 1 == grid.directions.shape[0]
    assert grid.solid_angles.sum() == pytest.approx(2 * np.pi, rel=1e-13)
    np.testing.assert_allclose(np.linalg.norm(grid.directions, axis=1), 1.0, atol=1e-14)


def test_grid_is_a_quadrature_of_the_hemisphere():
    # ∫ cos θ dω = π and ∫ cos² θ dω = 2π/3 over the upper hemisphere
    z = GRID.directions[:, 2]
    assert np.sum(GRID.solid_angles * z) == pytest.approx(np.pi, rel=2e-3)
    assert np.sum(GRID.solid_angles * z * z) == pytest.approx(2 * np.pi / 3, rel=2e-3)


def test_grid_equality_uses_its_parameters():
    assert HemisphereGrid() == GRID and hash(HemisphereGrid()) == hash(GRID)
    assert HemisphereGrid(n_phi=36) != GRID


# --- spreading ----------------------------------------------------------------------------------------


def test_spread_of_one_normal_is_the_closed_form_lobe():
    normal = tilted(25.0, 70.0)
    values = spread(normal[None], np.ones(1), 50.0, GRID)
    expected = 51.0 / (2 * np.pi) * np.clip(GRID.directions @ normal, 0.0, None) ** 50
    np.testing.assert_allclose(values, expected, rtol=1e-12, atol=1e-300)


def test_spread_is_linear_normalises_and_chunks():
    normals = np.array([tilted(10, 0), tilted(40, 100), tilted(80, 250)])
    weights = np.array([0.5, 0.3, 0.2])
    one_by_one = sum(
        w * spread(n[None], np.ones(1), 30.0, GRID) for n, w in zip(normals, weights, strict=True)
    )
    np.testing.assert_allclose(spread(normals, weights, 30.0, GRID), one_by_one, rtol=1e-12)
    np.testing.assert_allclose(spread(3.0 * normals, weights, 30.0, GRID, chunk=1), one_by_one, rtol=1e-12)


def test_spread_with_exponent_zero_is_uniform_on_the_normals_hemisphere():
    values = spread(np.array([[0.0, 0.0, 1.0]]), np.ones(1), 0.0, GRID)
    np.testing.assert_allclose(values, 1 / (2 * np.pi))
    values = spread(np.array([[1.0, 0.0, 0.0]]), np.ones(1), 0.0, GRID)
    np.testing.assert_array_equal(values > 0, GRID.directions[:, 0] > 0)


def test_spread_integrates_to_the_total_weight_on_the_grid():
    values = spread(np.array([[0.0, 0.0, 1.0], tilted(30, 45)]), np.array([0.25, 0.75]), 50.0, GRID)
    assert np.sum(GRID.solid_angles * values) == pytest.approx(1.0, rel=5e-3)


# --- exact peaks --------------------------------------------------------------------------------------


def test_at_most_seven_distinct_normals_are_returned_exactly():
    rng = np.random.default_rng(3)
    distinct = np.array(
        [tilted(t, p) for t, p in [(0, 0), (10, 20), (20, 80), (30, 140), (45, 200), (60, 260), (75, 320)]]
    )
    labels = np.concatenate([np.arange(7), rng.integers(0, 7, 30)])
    normals = distinct[labels] + rng.uniform(-1e-8, 1e-8, (labels.size, 3))
    weights = rng.uniform(0.1, 1.0, labels.size)
    weights /= weights.sum()
    peaks = exact_peaks(normals, weights, 80.0)
    assert peaks is not None and peaks.exact and len(peaks) == 7
    assert peaks.rms_ratio == 0.0 and peaks.max_ratio == 0.0
    np.testing.assert_array_equal(peaks.exponents, 80.0)
    for d, a in zip(peaks.directions, peaks.amplitudes, strict=True):
        k = int(np.argmax(distinct @ d))
        assert np.degrees(np.arccos(min(1.0, distinct[k] @ d))) < 1e-4
        assert a == pytest.approx(weights[labels == k].sum(), rel=1e-12)
    assert peaks.amplitudes.sum() == pytest.approx(1.0, rel=1e-12)


def test_eight_distinct_normals_need_a_fit():
    normals = np.array([tilted(10 * i, 45 * i) for i in range(8)])
    assert exact_peaks(normals, np.full(8, 1 / 8), 50.0) is None
    assert exact_peaks(normals[:7], np.full(7, 1 / 7), 50.0) is not None
    # 1e-3 apart is distinct at the default tolerance, the same at a coarser one
    pair = np.array([[0.0, 0.0, 1.0], [1e-3, 0.0, 1.0]])
    assert len(exact_peaks(pair, np.full(2, 0.5), 50.0)) == 2
    assert len(exact_peaks(pair, np.full(2, 0.5), 50.0, tol=1e-2)) == 1
    assert exact_peaks(normals, np.full(8, 1 / 8), 50.0, max_peaks=8) is not None


# --- fits ---------------------------------------------------------------------------------------------


def hemisphere_bump_normals(side=32):
    """Normals of a hemispherical bump seen from above: (x, y, sqrt(1 − x² − y²)) on a disc grid."""
    c = (np.arange(side) + 0.5) / side * 2 - 1
    x, y = np.meshgrid(c, c)
    inside = x * x + y * y < 1
    x, y = x[inside], y[inside]
    return np.stack([x, y, np.sqrt(1 - x * x - y * y)], -1)


def test_fit_of_a_hemisphere_bump():
    normals = hemisphere_bump_normals()
    values = spread(normals, np.full(len(normals), 1 / len(normals)), 50.0, GRID)
    peaks = fit_peaks(values, GRID)
    check_fit(peaks, values)
    assert peaks.amplitudes.sum() == pytest.approx(1.0, abs=0.05)


def test_fit_of_a_cylinder_reports_max_peaks_and_its_ratios_honestly():
    # all normals in the xz-plane: wide in x, as narrow as one base lobe in y. Seven isotropic lobes
    # cannot reach 5 % on this ridge (about 8.5 % RMS, 10 % max); the fit must say so.
    x = (np.arange(64) + 0.5) / 64 * 2 - 1
    normals = np.stack([x, np.zeros_like(x), np.sqrt(1 - x * x)], -1)
    values = spread(normals, np.full(64, 1 / 64), 50.0, GRID)
    peaks = fit_peaks(values, GRID)
    assert len(peaks) == 7
    rms, mx = ratios(peaks, values)
    assert peaks.rms_ratio == pytest.approx(rms, rel=1e-9) and peaks.max_ratio == pytest.approx(mx, rel=1e-9)
    assert max(rms, mx) >= 0.05  # honestly not within tolerance ...
    assert rms < 0.1 and mx < 0.12  # ... but close
    assert np.all(np.abs(peaks.directions[:, 1]) < 0.05)  # the peaks stay in the plane of the normals
    assert peaks.directions[:, 0].min() < -0.5 and peaks.directions[:, 0].max() > 0.5
    assert peaks.amplitudes.sum() == pytest.approx(1.0, abs=0.03)


def test_fit_of_a_random_set_of_normals():
    rng = np.random.default_rng(1234)
    slopes = rng.normal(0.0, 0.35, (256, 2))
    normals = np.concatenate([-slopes, np.ones((256, 1))], 1)
    weights = rng.uniform(0.5, 1.5, 256)
    weights /= weights.sum()
    values = spread(normals, weights, 50.0, GRID)
    peaks = fit_peaks(values, GRID)
    check_fit(peaks, values)
    assert 1 < len(peaks) <= 7
    assert peaks.amplitudes.sum() == pytest.approx(1.0, abs=0.03)


def test_fit_recovers_known_peaks():
    truth = Peaks(
        directions=np.array([tilted(0, 0), tilted(35, 20), tilted(55, 200)]),
        amplitudes=np.array([0.5, 0.3, 0.2]),
        exponents=np.array([30.0, 120.0, 300.0]),
    )
    values = truth.evaluate(GRID.directions)
    peaks = fit_peaks(values, GRID, rms_tolerance=0.005, max_tolerance=0.005)
    check_fit(peaks, values, tolerance=0.005)
    assert len(peaks) == 3
    for d, a, n in zip(truth.directions, truth.amplitudes, truth.exponents, strict=True):
        k = int(np.argmax(peaks.directions @ d))
        assert np.degrees(np.arccos(min(1.0, peaks.directions[k] @ d))) < 0.5
        assert peaks.amplitudes[k] == pytest.approx(a, rel=0.02)
        assert peaks.exponents[k] == pytest.approx(n, rel=0.05)


def test_fit_model_jacobian_matches_central_differences_of_its_residual():
    """Oracle: central differences of the residual, for the compiled Jacobian the solver steps with."""
    from prefilter.normals.peaks import _Model

    model = _Model(GRID.directions, GRID.solid_angles, (1.0, 1e4))
    rng = np.random.default_rng(3)
    x = np.concatenate(
        [model.pack(tilted(t, p), a, n) for t, p, a, n in ((10, 30, 0.5, 40.0), (40, 250, 0.3, 300.0))]
    )
    y = rng.uniform(0, 1, GRID.size)
    jacobian = model.jacobian(x)
    for k in range(x.size):
        h = 1e-6 * max(1.0, abs(x[k]))
        up, down = x.copy(), x.copy()
        up[k] += h
        down[k] -= h
        numeric = (model.residual(up, y) - model.residual(down, y)) / (2 * h)
        np.testing.assert_allclose(jacobian[:, k], numeric, atol=1e-6 * np.abs(numeric).max() + 1e-9)


def fig2_normals(count=200, seed=5):
    """Fournier's Fig. 2: half the normals tilted +30° about y, half −30°, with 0.1° of jitter."""
    rng = np.random.default_rng(seed)
    angle = np.radians(np.where(np.arange(count) % 2 == 0, 30.0, -30.0) + rng.normal(0, 0.1, count))
    tilt = np.radians(rng.normal(0, 0.1, count))
    return np.stack([np.sin(angle) * np.cos(tilt), np.sin(tilt), np.cos(angle) * np.cos(tilt)], -1)


def test_fig2_two_populations_keep_two_peaks_not_the_average():
    normals = fig2_normals()
    weights = np.full(len(normals), 1 / len(normals))
    assert exact_peaks(normals, weights, 100.0) is None  # > 7 distinct normals: a real fit
    values = spread(normals, weights, 100.0, GRID)
    peaks = fit_peaks(values, GRID)
    check_fit(peaks, values)
    assert len(peaks) == 2
    for target in (tilted(30, 0), tilted(-30, 0)):
        k = int(np.argmax(peaks.directions @ target))
        assert np.degrees(np.arccos(min(1.0, peaks.directions[k] @ target))) < 1.0
        assert peaks.amplitudes[k] == pytest.approx(0.5, abs=0.02)
    mean = normals.mean(axis=0)
    mean /= np.linalg.norm(mean)
    assert np.degrees(np.arccos(mean[2])) < 0.5  # the averaged normal is (0, 0, 1) ...
    assert np.all(np.degrees(np.arccos(peaks.directions @ mean)) > 25.0)  # ... and no peak is there
    at_mean = peaks.evaluate(mean[None])[0]
    at_peaks = peaks.evaluate(peaks.directions)
    assert at_mean < 0.01 * at_peaks.min()


def test_fit_honours_the_exponent_range_and_edge_cases():
    values = spread(np.array([[0.0, 0.0, 1.0], tilted(40, 0)]), np.array([0.5, 0.5]), 200.0, GRID)
    peaks = fit_peaks(values, GRID, exponent_range=(5.0, 60.0))
    assert np.all((peaks.exponents >= 5.0) & (peaks.exponents <= 60.0))
    rms, mx = ratios(peaks, values)
    assert peaks.rms_ratio == pytest.approx(rms, rel=1e-9) and peaks.max_ratio == pytest.approx(mx, rel=1e-9)
    empty = fit_peaks(np.zeros(GRID.size), GRID)
    assert len(empty) == 0
    np.testing.assert_array_equal(empty.evaluate(GRID.directions), 0.0)
    with pytest.raises(ValueError):
        fit_peaks(np.zeros(10), GRID)


def test_fit_is_deterministic():
    rng = np.random.default_rng(77)
    slopes = rng.normal(0.0, 0.5, (64, 2))
    normals = np.concatenate([-slopes, np.ones((64, 1))], 1)
    values = spread(normals, np.full(64, 1 / 64), 40.0, GRID)
    first, second = fit_peaks(values, GRID), fit_peaks(values.copy(), GRID)
    for name in ("directions", "amplitudes", "exponents"):
        assert getattr(first, name).tobytes() == getattr(second, name).tobytes()
    assert (first.rms_ratio, first.max_ratio) == (second.rms_ratio, second.max_ratio)
