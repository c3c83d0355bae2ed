"""Statistics of Perlin noise under a box pixel footprint, for filtering colour tables of noise.

Heitz et al. 2014 §4.2: "For procedural (e.g., noise) functions f, such as Perlin noise, we precompute
the noise standard deviation for different levels of detail and store it in a 1D texture". We measure,
by Monte Carlo once, how a footprint splits one noise term between the filtered mean and the spread σ.
A box pixel maps to a parallelogram in noise space spanned by axes e1, e2 (|e1| = ρ1, |e2| = ρ2 in
lattice units); the measurement uses orthogonal axes, random 3D orientations and random positions:

  σ_n²       Var[n] over space (one number);
  β, κ, γ    the least-squares fit n(x) ≈ β n(c) + κ τ(c) + γ ∇n(c)·(x - c) over all footprints and
             samples, with τ = (e1ᵀ H e1 + e2ᵀ H e2) / 24 the second-order Taylor shift from n(c) to the
             footprint's mean (H the Hessian of n at c; noise.footprint_curvature): the filtered mean is
             β n(c) + κ τ(c). Beyond Heitz et al., who keep β n(c) only: for a point footprint β = κ = 1
             (Taylor), for a huge one both are 0 (everything is spread); a footprint of half a lattice
             cell leaves 2 % of the mean's error variance that β n(c) alone leaves, one of a cell 15 %.
             γ is the part of Hart's first-order variation that is real at this footprint size;
  λ(ρ1, ρ2)  = E[ mean_{x in P} (n(x) - β n(c) - κ τ(c) - γ ∇n(c)·(x - c))² ] / σ_n²: the variance
             that this model of the resolved part leaves unexplained (0 tiny, 1 huge);
  β₁         the least-squares fit n(x) ≈ β₁ n(c) alone: the footprint's mean correlation with its centre,
             E[n(x) n(c)] / σ_n². The heights in the footprint are then spread about β₁ n(c) with variance
             (1 - β₁²) σ_n² (tests/test_microsurface_stats.py), the scale split of the microsurfaces
             (microsurface/heightfield.py), which have no κ τ term. β is larger (0.86 against 0.59 at a
             footprint of one cell) because κ τ, anti-correlated with n(c), completes it.

At run time (through the rational fits of `fit_split`, written to noise_stats.glsl) a term a n(T s)
adds a (β n(c) + κ τ(c)) to the mean μ, a γ ∇n(c) to the gradient whose footprint variance gives σ_lin²,
and a² σ_n² λ to σ²: Hart's first-order width where the footprint is small against the noise period,
Heitz's statistics where it is large. The table is a function of (log2 ρ1, log2 ρ2) on GRID (symmetric),
stored in data/noise_stats.npz; regenerate it with `python -m prefilter.procedural.noise_stats` (about a
minute).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from prefilter.procedural.noise import footprint_curvature, perlin_noise, perlin_noise_grad

DATA = Path(__file__).resolve().parent / "data" / "noise_stats.npz"
GLSL = Path(__file__).resolve().parent / "noise_stats.glsl"
GRID = np.arange(-5.0, 5.0 + 0.5, 0.5)  # log2 of footprint axis lengths, in lattice units
FOOTPRINTS = 1024  # random footprints per table entry
SAMPLES = 12  # stratified samples per footprint axis (SAMPLES² per footprint)
SEED = 20130704


@dataclass(frozen=True)
class NoiseStats:
    variance: float  # σ_n²
    grid: np.ndarray  # log2 ρ at the table nodes
    beta: np.ndarray  # (len(grid), len(grid)), symmetric
    kappa: np.ndarray
    gamma: np.ndarray
    lam: np.ndarray
    beta_mean: np.ndarray  # β₁

    def lookup(self, rho1: np.ndarray, rho2: np.ndarray) -> tuple[np.ndarray, ...]:
        """Bilinear interpolation in (log2 ρ1, log2 ρ2), clamped to the grid (as the shader does)."""
        x = np.interp(np.log2(np.maximum(rho1, 1e-30)), self.grid, np.arange(len(self.grid)))
        y = np.interp(np.log2(np.maximum(rho2, 1e-30)), self.grid, np.arange(len(self.grid)))
        x0, y0 = (
            np.minimum(np.floor(x).astype(int), len(self.grid) - 2),
            np.minimum(np.floor(y).astype(int), len(self.grid) - 2),
        )
        tx, ty = x - x0, y - y0

        def bilinear(table: np.ndarray) -> np.ndarray:
            return (
                (1 - tx) * (1 - ty) * table[x0, y0]
                + tx * (1 - ty) * table[x0 + 1, y0]
                + (1 - tx) * ty * table[x0, y0 + 1]
                + tx * ty * table[x0 + 1, y0 + 1]
            )

        return bilinear(self.beta), bilinear(self.kappa), bilinear(self.gamma), bilinear(self.lam)


def random_footprints(rng: np.random.Generator, count: int, rho1: float, rho2: float):
    """Centres uniform over one noise period and orthogonal axes of lengths rho1, rho2, random rotation."""
    centres = rng.uniform(0.0, 256.0, size=(count, 3))
    q, r = np.linalg.qr(rng.normal(size=(count, 3, 3)))
    q = q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]
    return centres, q[:, :, 0] * rho1, q[:, :, 1] * rho2


def footprint_samples(centres, e1, e2, samples: int = SAMPLES):
    """Midpoints of a samples x samples grid over each parallelogram: (count, samples², 3) and offsets."""
    u = (np.arange(samples) + 0.5) / samples - 0.5
    uu, vv = np.meshgrid(u, u, indexing="ij")
    uu, vv = uu.ravel(), vv.ravel()
    offsets = uu[None, :, None] * e1[:, None, :] + vv[None, :, None] * e2[:, None, :]
    return centres[:, None, :] + offsets, offsets


def measure_variance(rng: np.random.Generator, points: int = 4_000_000) -> float:
    values = perlin_noise(rng.uniform(0.0, 256.0, size=(points, 3)))
    return float(np.mean(values**2) - np.mean(values) ** 2)


def measure_entry(
    rng: np.random.Generator,
    rho1: float,
    rho2: float,
    variance: float,
    count: int = FOOTPRINTS,
    samples: int = SAMPLES,
) -> tuple[float, float, float, float]:
    """(β, κ, γ, λ, β₁) of one footprint shape by Monte Carlo over `count` random footprints."""
    centres, e1, e2 = random_footprints(rng, count, rho1, rho2)
    points, offsets = footprint_samples(centres, e1, e2, samples)
    values = perlin_noise(points)
    centre_value, centre_grad = perlin_noise_grad(centres)
    value_term = np.broadcast_to(centre_value[:, None], values.shape)
    shift_term = np.broadcast_to(footprint_curvature(centres, e1, e2)[:, None] / 24.0, values.shape)
    slope_term = np.einsum("kj,ksj->ks", centre_grad, offsets)
    design = np.stack([value_term.ravel(), shift_term.ravel(), slope_term.ravel()], axis=1)
    (beta, kappa, gamma), *_ = np.linalg.lstsq(design, values.ravel(), rcond=None)
    model = beta * value_term + kappa * shift_term + gamma * slope_term
    lam = float(np.mean((values - model) ** 2) / variance)
    beta_mean = float(np.sum(values * value_term) / np.sum(value_term**2))
    return float(beta), float(kappa), float(gamma), lam, beta_mean


def measure(seed: int = SEED) -> NoiseStats:
    rng = np.random.default_rng(seed)
    variance = measure_variance(rng)
    n = len(GRID)
    tables = np.zeros((5, n, n))  # β, κ, γ, λ, β₁
    for i in range(n):
        for j in range(i + 1):
            tables[:, i, j] = tables[:, j, i] = measure_entry(rng, 2.0 ** GRID[i], 2.0 ** GRID[j], variance)
    return NoiseStats(variance, GRID.copy(), *tables)


@lru_cache(maxsize=1)
def noise_stats() -> NoiseStats:
    with np.load(DATA) as data:
        return NoiseStats(
            float(data["variance"]),
            data["grid"],
            data["beta"],
            data["kappa"],
            data["gamma"],
            data["lam"],
            data["beta_mean"],
        )


def _rational_fall(rho: np.ndarray, a: float, b: float, c: float, d: float) -> np.ndarray:
    """(1 + a ρ²) / (1 + (a + d) ρ² + b ρ³ + c ρ⁴), as GLSL computes it."""
    x = np.square(rho)
    numerator = 1.0 + a * x
    return numerator / (numerator + x * (d + b * rho + c * x))


# Which coefficients each fit may use. β and 1 - λ have no ρ² term (d = 0) and β no ρ³ term: β falls as
# 1 - O(ρ⁴) at a point footprint, so that β n stays the Taylor value that κ τ completes to second order,
# and λ = O(ρ³) adds no spread that a small footprint does not have. κ and γ weight terms that grow with
# the footprint (τ ~ ρ², the linear part's spread ~ ρ): they use d and c and fall as ρ⁻⁴, so that κ τ and
# γ ∇n·e vanish for huge footprints (with a ρ⁻¹ tail the curvature along footprints 16 cells long leaked
# into the mean: noise-plane FLIP 0.051 -> 0.059).
_FREE = {
    "beta": (True, False, True, False),
    "kappa": (False, False, True, True),
    "gamma": (False, False, True, True),
    "one_minus_lambda": (True, True, True, False),
    # β₁ falls as 1 - O(ρ²) (the correlation's curvature at 0) and as ρ⁻² or faster (the footprint's area)
    "beta_mean": (True, True, True, True),
}


def _fit_fall(
    grid: np.ndarray, target: np.ndarray, free: tuple[bool, ...]
) -> tuple[float, float, float, float]:
    """(a, b, c, d) of F(ρ1) F(ρ2) ≈ target on the table's nodes, least squares, a..d >= 0, the entries
    that `free` marks False held at 0."""
    from scipy.optimize import least_squares

    r1, r2 = np.meshgrid(2.0**grid, 2.0**grid, indexing="ij")  # ρ at the table's nodes
    free = np.array(free)

    def coefficients(values):
        c = np.zeros(4)
        c[free] = values
        return c

    def residual(values):
        c = coefficients(values)
        return (_rational_fall(r1, *c) * _rational_fall(r2, *c) - target).ravel()

    fit = min(
        (least_squares(residual, [start] * free.sum(), bounds=(0.0, np.inf)) for start in (0.01, 0.1, 1.0)),
        key=lambda result: result.cost,
    )
    return tuple(float(v) for v in coefficients(fit.x))


def fit_split(stats: NoiseStats) -> dict[str, tuple[float, float, float, float]]:
    """Separable rational fits of the table, cheap enough for the shader's inner loop:

        β ≈ F_b(ρ1) F_b(ρ2),  κ ≈ F_k(ρ1) F_k(ρ2),  γ ≈ F_g(..) F_g(..),  1 - λ ≈ F_h(..) F_h(..),
        F(ρ) = (1 + a ρ²) / (1 + (a + d) ρ² + b ρ³ + c ρ⁴),  a, b, c, d >= 0 (some held at 0: _FREE)

    with ρ the footprint's axis lengths in lattice units. They need no log2 and no texture: a term costs
    two square roots and one division for all four. A texture fetch or a const-array lookup per noise
    term made the gaussian mode about 1.5x the naive frame time on llvmpipe. The previous fits,
    smoothsteps in log2 ρ, cost 0.03-0.07x a point frame more than these (hart-sat and gaussian on the
    8-term planet and on fire, round-robin). These are closer to the table: largest error 0.111 / 0.087
    / 0.089 / 0.062 against 0.124 / 0.108 / 0.115 / 0.073 for the smoothsteps, RMS 0.034 / 0.011 /
    0.013 / 0.016 against 0.044 / 0.024 / 0.024 / 0.023 (β / κ / γ / λ). tests/test_gaussian.py checks
    the largest errors.
    """
    targets = (
        ("beta", stats.beta),
        ("kappa", stats.kappa),
        ("gamma", stats.gamma),
        ("one_minus_lambda", 1.0 - stats.lam),
    )
    return {name: _fit_fall(stats.grid, target, _FREE[name]) for name, target in targets}


def fit_mean_fraction(stats: NoiseStats) -> tuple[float, float, float, float]:
    """(a, b, c, d) of the separable rational fit β₁ ≈ F(ρ1) F(ρ2) (the form of fit_split)."""
    return _fit_fall(stats.grid, stats.beta_mean, _FREE["beta_mean"])


@lru_cache(maxsize=1)
def mean_fraction_fit() -> tuple[float, float, float, float]:
    """The fit of the stored table, computed once (the coefficients noise_stats.glsl's NS_MEAN_FALL holds)."""
    return fit_mean_fraction(noise_stats())


def mean_fraction(rho1: np.ndarray, rho2: np.ndarray) -> np.ndarray:
    """NumPy twin of ns_splitFractions(ρ1², ρ2²).y: β₁ of a footprint with axis lengths ρ1, ρ2 (lattice
    units)."""
    fit = mean_fraction_fit()
    return _rational_fall(rho1, *fit) * _rational_fall(rho2, *fit)


@lru_cache(maxsize=1)
def split_fits() -> dict[str, tuple[float, float, float, float]]:
    """The fits of the stored table, computed once (the same coefficients noise_stats.glsl holds)."""
    return fit_split(noise_stats())


def split_fit(fits: dict, rho1: np.ndarray, rho2: np.ndarray) -> tuple[np.ndarray, ...]:
    """NumPy twin of pt_noiseSplit: (β, κ, γ, λ) from the fitted coefficients."""

    def product(name: str) -> np.ndarray:
        return _rational_fall(rho1, *fits[name]) * _rational_fall(rho2, *fits[name])

    return product("beta"), product("kappa"), product("gamma"), 1.0 - product("one_minus_lambda")


def glsl_source(stats: NoiseStats) -> str:
    fits = fit_split(stats)
    lines = [
        "// Generated by `python -m prefilter.procedural.noise_stats` (data/noise_stats.npz); do not edit.",
        "// Perlin noise under a box footprint with axis lengths rho1, rho2 (lattice units):",
        "// beta = F(rho1) F(rho2), kappa, gamma and 1 - lambda likewise,",
        "// F(rho) = (1 + a rho^2) / (1 + (a + d) rho^2 + b rho^3 + c rho^4);",
        "// NS_FALL_A .. NS_FALL_D hold a .. d of (beta, kappa, gamma, 1 - lambda);",
        "// NS_MEAN_FALL holds (a, b, c, d) of beta_1, the mean fraction without the curvature term.",
        f"const float NS_VARIANCE = {stats.variance:.6f};",
    ]
    for index, constant in enumerate(("NS_FALL_A", "NS_FALL_B", "NS_FALL_C", "NS_FALL_D")):
        values = ", ".join(f"{fit[index]:.6f}" for fit in fits.values())
        lines.append(f"const vec4 {constant} = vec4({values});")
    mean_fit = fit_mean_fraction(stats)
    lines.append(f"const vec4 NS_MEAN_FALL = vec4({', '.join(f'{v:.6f}' for v in mean_fit)});")
    return "\n".join(lines) + "\n" + _GLSL_FALL


# The fits' evaluation: one rational product for every fit (ns_fits), read as (beta, kappa, gamma,
# 1 - lambda) by procedural/hart.glsl and as (beta, beta_1, gamma) by microsurface/heightfield.glsl.
_GLSL_FALL = """
// F(rho1) F(rho2) lane by lane for the coefficients (a, b, c, d) of four fits, at the squared axis lengths
// x1 = rho1^2, x2 = rho2^2. x is capped where every F is 0 to float precision, so that neither product
// overflows. Lanes a caller does not read cost nothing: the compiler drops them.
vec4 ns_fits(vec4 a, vec4 b, vec4 c, vec4 d, float x1, float x2) {
    vec2 x = min(vec2(x1, x2), vec2(1e12));
    vec4 nx = 1.0 + a * x.x, ny = 1.0 + a * x.y;
    vec4 dx = nx + x.x * (d + b * sqrt(x.x) + c * x.x);
    vec4 dy = ny + x.y * (d + b * sqrt(x.y) + c * x.y);
    return (nx * ny) / (dx * dy);
}

// (beta, kappa, gamma, 1 - lambda).
vec4 ns_fall(float x1, float x2) {
    return ns_fits(NS_FALL_A, NS_FALL_B, NS_FALL_C, NS_FALL_D, x1, x2);
}

// (beta, beta_1, gamma): the split's fractions with and without the curvature term, and the linear one.
vec3 ns_splitFractions(float x1, float x2) {
    vec4 a = vec4(NS_FALL_A.x, NS_MEAN_FALL.x, NS_FALL_A.z, 0.0);
    vec4 b = vec4(NS_FALL_B.x, NS_MEAN_FALL.y, NS_FALL_B.z, 0.0);
    vec4 c = vec4(NS_FALL_C.x, NS_MEAN_FALL.z, NS_FALL_C.z, 0.0);
    vec4 d = vec4(NS_FALL_D.x, NS_MEAN_FALL.w, NS_FALL_D.z, 0.0);
    return ns_fits(a, b, c, d, x1, x2).xyz;
}
"""


def main() -> int:
    stats = measure()
    DATA.parent.mkdir(parents=True, exist_ok=True)
    tmp = DATA.with_suffix(".tmp.npz")
    np.savez(
        tmp,
        variance=stats.variance,
        grid=stats.grid,
        beta=stats.beta,
        kappa=stats.kappa,
        gamma=stats.gamma,
        lam=stats.lam,
        beta_mean=stats.beta_mean,
    )
    tmp.replace(DATA)
    GLSL.write_text(glsl_source(stats))
    print(f"sigma_n^2 = {stats.variance:.6f}; wrote {DATA} and {GLSL}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
