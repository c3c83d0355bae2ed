"""Phong peaks: reconstruct a texel's distribution of normals and fit it with a few Phong lobes.

Fournier 1992, "Filtering Normal Maps and Creating Multiple Surfaces":
  §2.1  the normals under a texel define a distribution N(θ, φ) over the hemisphere;
  §2.2  it is *spread* (reconstructed) with a Phong lobe per normal, and approximated by a sum of at
        most 7 Phong peaks (direction, amplitude, exponent);
  §2.3  the fit is non-linear least squares on an 18 x 72 (θ, φ) sample grid plus a pole sample, peaks
        are added one at a time at the maximum of the residual, until residual RMS < 5 % of the data RMS
        and max |residual| < 5 % of max |data|, or 7 peaks; with <= 7 distinct normals no fit is needed;
  §2.4  (the pyramid, built elsewhere) fits every texel of every level from the base normals.

Normalisation (DESIGN.md erratum: a cos^n(α) is not a density). We use the normalised Phong lobe

    lobe(cos α, n) = (n + 1) / (2π) · max(cos α, 0)^n        (0 where cos α <= 0, also for n = 0)

a density over solid angle that integrates to 1 over the sphere (∫ cos^n θ sin θ dθ dφ = 2π/(n+1)).
A peak is (d, a, n): unit direction d (tangent frame, z = geometric normal), amplitude a >= 0, exponent
n >= 0; a set of peaks is D(ω) = Σ_i a_i lobe(ω·d_i, n_i). Spreading M base normals N_t with weights w_t
(fractions of projected area summing to 1) with the material's base exponent n_b gives
D(ω) = Σ_t w_t lobe(ω·N_t, n_b); amplitudes are then fractions of area too and a fit's amplitudes sum
to ≈ 1 (exactly 1 for `exact_peaks`); they fall short of 1 by the part of the tilted lobes' mass that lies
below the horizon, which the hemisphere grid does not see (negligible unless a normal is within a few
lobe widths of the horizon).

Sampling (`HemisphereGrid`, defaults from §2.3): n_theta = 18 rings of width (90° − cap)/n_theta between
θ = cap and 90°, n_phi = 72 cells of 5° in φ, samples at the cell centres, plus one pole sample standing
for the cap θ < cap = 5/12° (about half the area of its neighbouring cells); S = 18·72 + 1 = 1297
samples. Each sample carries the exact solid angle of its cell; they sum to 2π.

Weighting. Residuals are weighted by sqrt(solid angle), so the least-squares objective is a quadrature
of the continuous L2 norm ∫ (fit − D)² dω over the hemisphere and the 72 tiny cells of the first ring do
not outweigh the wide cells at the horizon. The stopping rule and `Peaks.rms_ratio` use the same
weighting: rms_ratio = sqrt(Σ Ω_s r_s² / Σ Ω_s D_s²). `Peaks.max_ratio` = max_s |r_s| / max_s |D_s| is
unweighted (a sup norm).

Fit (`fit_peaks`, §2.3). Parameters per peak: direction as slopes (p, q), d = (p, q, 1)/sqrt(1 + p² +
q²) (always unit and in the open upper hemisphere, smooth at the pole: Fournier's note 3 ignores normals
below the horizon), amplitude a = exp(s) > 0 (s clipped to [−60, 10]), and log n = log n_lo +
(log n_hi − log n_lo)·sigmoid(t), so n stays inside `exponent_range` (default (1, 1e4)). Solver:
Levenberg–Marquardt compiled with numba (`_levenberg_marquardt`: normal equations with MINPACK's
scaling by the largest diagonal of JᵀJ seen, Nielsen's damping update), analytic Jacobian, relative
cost and step tolerances 1e-4, at most `max_nfev` = 200 evaluations per refit. It replaced scipy's
least_squares (MINPACK "lm"), whose Python call overhead was most of a fit: the same fits (mean residual
ratio of every level of 128x128 pyramids equal on the twill, within 3e-4 on two noise maps) in 1.5-2.2x
less time. With tolerances of 1e-3
the 7-peak twill texels stopped early (RMS ratio 7.1 % instead of 6.4 %).
First guess: the sample where D is largest gives d and y0 = D(d); n comes from how fast D falls off
around it (least squares of log(D/y0) = n log cos δ over the samples at angular distance δ in
[0.5, 1.5] θ-steps, clipped to `exponent_range`); a from y0 = a (n + 1)/(2π). One peak is fitted; each
further peak is guessed the same way at the maximum of the residual D − fit, and all peaks are refitted
jointly from the previous solution (warm start), until both tolerances are met or `max_peaks` peaks are
used. If no stage meets them, the stage with the lowest weighted RMS is returned (almost always the
last); the achieved ratios are always reported. Each refit uses only the samples where the data or the
starting model exceeds 1e-4 · max D (the others hold nothing to fit; this saves a third of the time on
compact distributions, and the reported ratios are computed on the whole grid). Deterministic: no
random numbers, ties of the maximum go to the lowest sample index.

Limits. A distribution of few, well separated normals (e.g. 16 normals spread over the hemisphere) is
as many separate lobes, and 7 peaks cannot reach 5 %; nor can they follow a 180° ridge (the normals of a
cylinder: ≈ 8.5 % RMS, 10 % max). The 5° grid resolves base exponents up to a few hundred (the half
width at half maximum of cos^n is 4.7° at n = 200).

Timings: see docs/normals.md, "Bake time" (`prefilter bench`, study pyramid_build).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np
from scipy.special import expit

__all__ = [
    "HemisphereGrid",
    "Peaks",
    "exact_peaks",
    "fit_peaks",
    "lobe",
    "spread",
]

TWO_PI = 2.0 * np.pi
_LSQ_TOL = 1e-4  # relative cost and step tolerances of the Levenberg–Marquardt refits
_LOG_AMPLITUDE_RANGE = (-60.0, 10.0)  # a = exp(s) is clipped to this range of s
_ACTIVE_THRESHOLD = 1e-4  # samples below this fraction of max D (data and starting model) are left out


def lobe(cos_alpha, n):
    """Normalised Phong lobe (n + 1)/(2π) max(cos α, 0)^n: a density over the sphere (integral 1).

    Broadcasts `cos_alpha` against `n`. Zero where cos α <= 0 (also for n = 0, where it is the uniform
    density 1/(2π) over the lobe's hemisphere).
    """
    c = np.asarray(cos_alpha, dtype=np.float64)
    n = np.asarray(n, dtype=np.float64)
    pos = c > 0.0
    value = (n + 1.0) / TWO_PI * np.power(np.where(pos, c, 1.0), n)
    return np.where(pos, value, 0.0)


@dataclass(frozen=True, eq=False)
class Peaks:
    """A sum of Phong peaks D(ω) = Σ_i a_i lobe(ω·d_i, n_i), with the diagnostics of its fit.

    directions (k, 3) unit vectors, amplitudes (k,) >= 0, exponents (k,) >= 0. `rms_ratio` is the
    solid-angle-weighted residual RMS over the data RMS and `max_ratio` max|residual| / max|data| on the
    fitting grid (0 for exact peaks); `exact` is True when the peaks are the merged base normals.
    """

    directions: np.ndarray
    amplitudes: np.ndarray
    exponents: np.ndarray
    rms_ratio: float = 0.0
    max_ratio: float = 0.0
    exact: bool = False

    def __len__(self) -> int:
        return int(self.amplitudes.shape[0])

    def evaluate(self, omegas: np.ndarray) -> np.ndarray:
        """D(ω) at unit directions `omegas` (S, 3) -> (S,)."""
        omegas = np.asarray(omegas, dtype=np.float64)
        if len(self) == 0:
            return np.zeros(omegas.shape[0])
        return lobe(omegas @ self.directions.T, self.exponents) @ self.amplitudes


@dataclass(frozen=True)
class HemisphereGrid:
    """Fournier's (θ, φ) sampling of the upper hemisphere (§2.3), z up.

    Sample 0 is the pole (0, 0, 1), standing for θ < `pole_cap_degrees`. Then `n_theta` rings with
    θ-edges evenly spaced in [cap, 90°] and `n_phi` φ-cells of 360°/n_phi each (φ-index fastest),
    sampled at the cell centres. `solid_angles` are the exact areas of the cells (sum 2π).
    """

    n_theta: int = 18
    n_phi: int = 72
    pole_cap_degrees: float = 5.0 / 12.0
    directions: np.ndarray = field(init=False, repr=False, compare=False)
    solid_angles: np.ndarray = field(init=False, repr=False, compare=False)
    theta_step: float = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.n_theta < 1 or self.n_phi < 1:
            raise ValueError("n_theta and n_phi must be >= 1")
        if not 0.0 < self.pole_cap_degrees < 90.0:
            raise ValueError("pole_cap_degrees must be in (0, 90)")
        cap = np.radians(self.pole_cap_degrees)
        edges = np.linspace(cap, 0.5 * np.pi, self.n_theta + 1)
        theta = 0.5 * (edges[:-1] + edges[1:])
        dphi = TWO_PI / self.n_phi
        phi = (np.arange(self.n_phi) + 0.5) * dphi
        th, ph = np.meshgrid(theta, phi, indexing="ij")
        ring = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
        directions = np.concatenate([[[0.0, 0.0, 1.0]], ring.reshape(-1, 3)])
        band = (np.cos(edges[:-1]) - np.cos(edges[1:])) * dphi
        solid = np.concatenate([[TWO_PI * (1.0 - np.cos(cap))], np.repeat(band, self.n_phi)])
        for name, value in (("directions", directions), ("solid_angles", solid)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "theta_step", float(edges[1] - edges[0]))

    @property
    def size(self) -> int:
        """Number of samples S = n_theta·n_phi + 1."""
        return int(self.solid_angles.shape[0])


def _unit_normals(normals, weights):
    normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    weights = np.asarray(weights, dtype=np.float64).reshape(-1)
    if normals.shape[0] != weights.shape[0]:
        raise ValueError(f"{normals.shape[0]} normals but {weights.shape[0]} weights")
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    if np.any(length == 0.0):
        raise ValueError("zero-length normal")
    return normals / length, weights


def spread(normals, weights, exponent: float, grid: HemisphereGrid, chunk: int = 2_000_000) -> np.ndarray:
    """Fournier's spreading (§2.2): D(ω_s) = Σ_t w_t lobe(ω_s·N_t, exponent) at the grid samples -> (S,).

    `normals` (M, 3) are normalised here; `weights` (M,) are usually fractions of area summing to 1.
    Work is chunked over M so that at most about `chunk` lobe values exist at once. D is linear in the
    weights, so a parent texel's D is the weighted sum of its children's (a pyramid can spread once, at
    its finest fitted level, and sum upwards).
    """
    normals, weights = _unit_normals(normals, weights)
    dirs_t = np.ascontiguousarray(grid.directions.T)
    out = np.zeros(grid.size)
    norm = (exponent + 1.0) / TWO_PI
    step = max(1, chunk // grid.size)
    for start in range(0, normals.shape[0], step):
        c = normals[start : start + step] @ dirs_t
        if exponent == 0.0:
            c = (c > 0.0).astype(np.float64)
        else:
            np.maximum(c, 0.0, out=c)
            np.power(c, exponent, out=c)
        out += weights[start : start + step] @ c
    return out * norm


def exact_peaks(normals, weights, exponent: float, max_peaks: int = 7, tol: float = 1e-6) -> Peaks | None:
    """The base normals themselves as peaks, if at most `max_peaks` distinct ones (§2.3), else None.

    Normals within `tol` (max-norm of the difference of unit vectors) of the first normal of a group
    are merged, in input order: the peak's direction is the normalised weighted mean of the group, its
    amplitude the summed weight and its exponent the base `exponent`. Zero-weight normals are ignored.
    """
    normals, weights = _unit_normals(normals, weights)
    keep = weights != 0.0
    normals, weights = normals[keep], weights[keep]
    dirs, amps = [], []
    while normals.shape[0]:
        if len(dirs) == max_peaks:
            return None
        group = np.max(np.abs(normals - normals[0]), axis=1) <= tol
        mean = weights[group] @ normals[group]
        dirs.append(mean / np.linalg.norm(mean))
        amps.append(weights[group].sum())
        normals, weights = normals[~group], weights[~group]
    k = len(dirs)
    return Peaks(
        directions=np.array(dirs).reshape(k, 3),
        amplitudes=np.array(amps),
        exponents=np.full(k, float(exponent)),
        exact=True,
    )


@numba.njit(cache=True)
def _peak_parameters(x, j, lo, hi):
    """Peak j of the parameter vector: direction, amplitude, exponent, |(p, q, 1)|, d log n / dt and
    whether s lies inside the amplitude clip."""
    p, q, s, t = x[4 * j], x[4 * j + 1], x[4 * j + 2], x[4 * j + 3]
    r = np.sqrt(1.0 + p * p + q * q)
    sig = 1.0 / (1.0 + np.exp(-t))
    n = np.exp(lo + (hi - lo) * sig)
    a = np.exp(min(max(s, _LOG_AMPLITUDE_RANGE[0]), _LOG_AMPLITUDE_RANGE[1]))
    inside = 1.0 if _LOG_AMPLITUDE_RANGE[0] < s < _LOG_AMPLITUDE_RANGE[1] else 0.0
    return p / r, q / r, 1.0 / r, a, n, r, (hi - lo) * sig * (1.0 - sig), inside


@numba.njit(cache=True)
def _lobes_residual(dirs, sqrt_w, x, lo, hi, y):
    """sqrt(Ω) (Σ_j a_j lobe(ω·d_j, n_j) − y) at every sample ω of `dirs`."""
    out = -y.copy()
    for j in range(x.size // 4):
        dx, dy, dz, a, n, _, _, _ = _peak_parameters(x, j, lo, hi)
        scale = a * (n + 1.0) / TWO_PI
        for i in range(dirs.shape[0]):
            c = dirs[i, 0] * dx + dirs[i, 1] * dy + dirs[i, 2] * dz
            if c > 0.0:
                out[i] += scale * np.exp(n * np.log(c))
    return out * sqrt_w


@numba.njit(cache=True)
def _lobes_jacobian(dirs, sqrt_w, x, lo, hi):
    """d residual / d x, (S, 4k): per peak d/dp, d/dq (direction slopes), d/ds (log amplitude, 0 where
    clipped), d/dt (the exponent's sigmoid parameter); 0 where a sample is below the lobe's horizon."""
    k = x.size // 4
    jac = np.zeros((dirs.shape[0], 4 * k))
    for j in range(k):
        dx, dy, dz, a, n, r, dlogn_dt, inside = _peak_parameters(x, j, lo, hi)
        norm = (n + 1.0) / TWO_PI
        for i in range(dirs.shape[0]):
            c = dirs[i, 0] * dx + dirs[i, 1] * dy + dirs[i, 2] * dz
            if c > 0.0:
                logc = np.log(c)
                base = np.exp((n - 1.0) * logc)  # c^(n-1)
                g = base * (a * n * norm / r) * sqrt_w[i]  # sqrt(Ω) a dlobe/dcos / |(p, q, 1)|
                al = base * c * norm * a * sqrt_w[i]  # sqrt(Ω) a lobe
                jac[i, 4 * j] = g * (dirs[i, 0] - c * dx)
                jac[i, 4 * j + 1] = g * (dirs[i, 1] - c * dy)
                jac[i, 4 * j + 2] = al * inside
                jac[i, 4 * j + 3] = al * (n / (n + 1.0) + n * logc) * dlogn_dt
    return jac


def _guess(values, grid: HemisphereGrid, exponent_range):
    """First guess of one peak at the maximum of `values` (§2.3) -> (d, a, n), or None if max <= 0."""
    j = int(np.argmax(values))
    y0 = values[j]
    if not y0 > 0.0:
        return None
    d = grid.directions[j]
    cos_delta = grid.directions @ d
    delta = np.arccos(np.clip(cos_delta, -1.0, 1.0))
    ring = (delta > 0.5 * grid.theta_step) & (delta < 1.5 * grid.theta_step)
    ratio = np.clip(values[ring] / y0, 1e-6, 1.0)
    lc = np.log(cos_delta[ring])
    n = float(np.sum(np.log(ratio) * lc) / np.sum(lc * lc)) if ring.any() else exponent_range[0]
    n = float(np.clip(n, exponent_range[0], exponent_range[1]))
    a = y0 * TWO_PI / (n + 1.0)
    return d, a, n


@numba.njit(cache=True)
def _normal_equations(jac, r):
    """JᵀJ and Jᵀr by loops: BLAS here would start threads in every Dask worker process."""
    m, n = jac.shape
    normal = np.zeros((n, n))
    gradient = np.zeros(n)
    for i in range(m):
        for a in range(n):
            ja = jac[i, a]
            if ja != 0.0:
                gradient[a] += ja * r[i]
                for b in range(a + 1):
                    normal[a, b] += ja * jac[i, b]
    for a in range(n):
        for b in range(a):
            normal[b, a] = normal[a, b]
    return normal, gradient


@numba.njit(cache=True)
def _solve_spd(matrix, rhs):
    """Cholesky solve of a small symmetric positive definite system."""
    n = rhs.size
    low = np.zeros((n, n))
    for a in range(n):
        for b in range(a + 1):
            total = matrix[a, b]
            for c in range(b):
                total -= low[a, c] * low[b, c]
            if a == b:
                low[a, a] = np.sqrt(max(total, 1e-300))
            else:
                low[a, b] = total / low[b, b]
    z = np.zeros(n)
    for a in range(n):
        total = rhs[a]
        for c in range(a):
            total -= low[a, c] * z[c]
        z[a] = total / low[a, a]
    out = np.zeros(n)
    for a in range(n - 1, -1, -1):
        total = z[a]
        for c in range(a + 1, n):
            total -= low[c, a] * out[c]
        out[a] = total / low[a, a]
    return out


@numba.njit(cache=True)
def _levenberg_marquardt(dirs, sqrt_w, y, x0, lo, hi, max_nfev, tol):
    """Levenberg–Marquardt on the peaks' residuals from x0: steps solve (JᵀJ + λ D²) δ = −Jᵀr with D² the
    largest diagonal of JᵀJ seen so far (MINPACK's scaling), λ updated by the gain ratio (Nielsen). Stops
    when an accepted step lowers the cost by less than `tol` of it, or moves x by less than `tol` of |D x|,
    or after `max_nfev` residual evaluations."""
    x = x0.copy()
    r = _lobes_residual(dirs, sqrt_w, x, lo, hi, y)
    cost = np.sum(r * r)
    normal, gradient = _normal_equations(_lobes_jacobian(dirs, sqrt_w, x, lo, hi), r)
    scale = np.maximum(np.diag(normal).copy(), 1e-300)
    damping = 1e-3
    growth = 2.0
    for _ in range(max_nfev - 1):
        step = -_solve_spd(normal + damping * np.diag(scale), gradient)
        trial = x + step
        r_trial = _lobes_residual(dirs, sqrt_w, trial, lo, hi, y)
        cost_trial = np.sum(r_trial * r_trial)
        predicted = -(2.0 * np.sum(step * gradient) + np.sum(step * (normal * step).sum(axis=1)))
        if cost_trial < cost and predicted > 0.0:
            gain = (cost - cost_trial) / predicted
            damping *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            growth = 2.0
            small_step = np.sqrt(np.sum(scale * step * step)) <= tol * (np.sqrt(np.sum(scale * x * x)) + tol)
            small_gain = cost - cost_trial <= tol * cost
            x, r, cost = trial, r_trial, cost_trial
            if small_step or small_gain:
                break
            normal, gradient = _normal_equations(_lobes_jacobian(dirs, sqrt_w, x, lo, hi), r)
            scale = np.maximum(scale, np.diag(normal))
        else:
            damping *= growth
            growth *= 2.0
            if damping > 1e16:
                break
    return x


class _Model:
    """Sum of k normalised Phong lobes on the grid, residuals sqrt(Ω)(fit − y), analytic Jacobian
    (compiled: these two are where a fit spends its time).

    Parameters per peak, x.reshape(k, 4) = (p, q, s, t): d = (p, q, 1)/|(p, q, 1)|, a = exp(s),
    log n = lo + (hi − lo) sigmoid(t).
    """

    def __init__(self, directions, solid_angles, exponent_range):
        self.dirs = np.ascontiguousarray(directions, dtype=np.float64)
        self.sqrt_w = np.sqrt(solid_angles)
        self.lo, self.hi = float(np.log(exponent_range[0])), float(np.log(exponent_range[1]))

    def pack(self, d, a, n):
        d = np.atleast_2d(d)
        a, n = np.atleast_1d(a), np.atleast_1d(n)
        z = np.maximum(d[:, 2], 1e-3)
        frac = np.clip((np.log(n) - self.lo) / (self.hi - self.lo), 0.02, 0.98)
        t = np.log(frac / (1.0 - frac))
        return np.stack([d[:, 0] / z, d[:, 1] / z, np.log(a), t], axis=1).reshape(-1)

    def unpack(self, x):
        """Directions (k, 3), amplitudes (k,), exponents (k,)."""
        p, q, s, t = x.reshape(-1, 4).T
        r = np.sqrt(1.0 + p * p + q * q)
        d = np.stack([p, q, np.ones_like(p)], axis=1) / r[:, None]
        n = np.exp(self.lo + (self.hi - self.lo) * expit(t))
        a = np.exp(np.clip(s, *_LOG_AMPLITUDE_RANGE))
        return d, a, n

    def evaluate(self, x):
        """Model D at the samples."""
        ones = np.ones(len(self.dirs))
        return _lobes_residual(self.dirs, ones, x, self.lo, self.hi, np.zeros(len(self.dirs)))

    def residual(self, x, y):
        return _lobes_residual(self.dirs, self.sqrt_w, x, self.lo, self.hi, y)

    def jacobian(self, x):
        return _lobes_jacobian(self.dirs, self.sqrt_w, x, self.lo, self.hi)

    def solve(self, x, y, max_nfev):
        """Levenberg–Marquardt from `x` to the data `y` at the samples, tolerances _LSQ_TOL."""
        y = np.ascontiguousarray(y, dtype=np.float64)
        return _levenberg_marquardt(self.dirs, self.sqrt_w, y, x, self.lo, self.hi, max_nfev, _LSQ_TOL)


def fit_peaks(
    values,
    grid: HemisphereGrid,
    max_peaks: int = 7,
    rms_tolerance: float = 0.05,
    max_tolerance: float = 0.05,
    exponent_range=(1.0, 1e4),
    max_nfev: int = 200,
) -> Peaks:
    """Fit at most `max_peaks` normalised Phong peaks to a distribution sampled on `grid` (§2.3).

    `values` (S,) are D at `grid.directions` (e.g. from `spread`). Peaks are added at the maximum of the
    residual until the weighted residual RMS < rms_tolerance · weighted data RMS and max|residual| <
    max_tolerance · max|data|, or `max_peaks` peaks are used; each joint least-squares refit is limited
    to `max_nfev` evaluations. When no stage meets the tolerances, the stage with the lowest weighted RMS
    is returned (almost always the last). The returned `rms_ratio`/`max_ratio` are those achieved on the
    whole grid: check them, they may exceed the tolerances. An all-zero distribution gives zero peaks.
    """
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    if values.shape[0] != grid.size:
        raise ValueError(f"{values.shape[0]} values for a grid of {grid.size} samples")
    if max_peaks < 1:
        raise ValueError("max_peaks must be >= 1")
    lo, hi = exponent_range
    if not 0.0 < lo < hi:
        raise ValueError(f"exponent_range must satisfy 0 < lo < hi, got {exponent_range}")
    weights = grid.solid_angles
    data_ss = float(np.sum(weights * values * values))
    data_max = float(np.max(np.abs(values)))
    if data_max == 0.0:
        return Peaks(np.zeros((0, 3)), np.zeros(0), np.zeros(0))
    full = _Model(grid.directions, weights, exponent_range)
    negligible = _ACTIVE_THRESHOLD * data_max
    x = np.zeros(0)
    fit = np.zeros_like(values)
    best = None
    for _ in range(max_peaks):
        guess = _guess(values - fit, grid, exponent_range)
        if guess is None:
            break
        x = np.concatenate([x, full.pack(*guess)])
        # least squares on the samples where the data or the starting model is not negligible
        rows = np.flatnonzero((values > negligible) | (full.evaluate(x) > negligible))
        if rows.size < 8 * x.size:  # too few samples for a well-posed fit: use them all
            rows = np.arange(grid.size)
        x = _Model(grid.directions[rows], weights[rows], exponent_range).solve(x, values[rows], max_nfev)
        fit = full.evaluate(x)
        r = fit - values
        rms = float(np.sqrt(np.sum(weights * r * r) / data_ss))
        mx = float(np.max(np.abs(r)) / data_max)
        if best is None or rms < best[1]:
            best = (x, rms, mx)
        if rms < rms_tolerance and mx < max_tolerance:
            best = (x, rms, mx)
            break
    if best is None:  # no positive value to fit
        return Peaks(np.zeros((0, 3)), np.zeros(0), np.zeros(0), rms_ratio=1.0, max_ratio=1.0)
    x, rms, mx = best
    d, a, n = full.unpack(x)
    return Peaks(directions=d, amplitudes=a, exponents=n, rms_ratio=rms, max_ratio=mx, exact=False)
