"""Height transfer functions h = g(f) and their preconvolved moments: Heitz et al. 2014 §7, eqs. (19)–(28).

A microsurface height is h(x) = g(f(x)), with f a driver of Gaussian statistics (a Perlin-noise sum) and
g a non-linear 1D transfer function (Figs. 11–12). Over a pixel footprint the driver's values are taken
as N(f̄, σ_f²) and its gradient ∇f has mean ∇f̄ (resolved) and covariance Σ_∇f (unresolved).

Transfer functions (`TransferFunction(name, params)`, vectorised `g(v)` and analytic `g_prime(v)`; heights
in driver units, a material's height scale multiplies them). Figs. 11–12 are not available; moss and
sponge are our designs, C^∞, for drivers with f̄ ≈ 0 and σ_f ≈ 0.25–0.35. With the soft ramp
e(z) = s·softplus(z) = s·ln(1 + eᶻ) (≈ max(s z, 0), smooth over a width ≈ s):
  "linear"  g(v) = v (no parameters): every moment has a closed form (tests).
  "moss"    rounded tufts/cushions rising from a flat ground:
            g(v) = √e((v − t)/s),  g′(v) = sigmoid((v − t)/s) / (2 g(v)).
            Where the driver exceeds the threshold t, each noise maximum f ≈ f_max − κ r² becomes an
            ellipsoidal cap √(f_max − t − κ r²) (a cushion: steep sides, round top); below t the ground is
            flat (g ≈ √s e^{(v−t)/2s} → 0). Max g′ ≈ 0.32/√s (1.6 at the defaults).
            threshold t (driver units, default 0.1: tufts cover ≈ 37 % of a N(0, 0.3²) driver),
            softness s (driver units, default 0.04: the width of the foot where a tuft meets the ground).
  "sponge"  rounded pits/holes in a flat top: the mirror image,
            g(v) = −√e((t − v)/s),  g′(v) = sigmoid((t − v)/s) / (2 |g(v)|)  (> 0).
            Each driver minimum below t becomes an ellipsoidal bowl; above t the top is flat (h ≈ 0).
            threshold t (default 0.05: pits cover ≈ 57 %, the flat top is a thin connected network),
            softness s (default 0.04).
`TRANSFER_FUNCTIONS[name](**overrides)` builds one with the defaults above.

Moments (eqs. 21, 22, 27, 28) against D_f = N(μ, σ²):
    E[g], E[g²], E[g′], E[g′²] = ∫ (g, g², g′, g′²)(v) N(v; μ, σ²) dv.
Footprint statistics (`transfer_stats`, GLSL ms_transferStats), eqs. (23)–(26): ∇h = g′(f) ∇f, and for a
Gaussian process f and ∇f at one point are uncorrelated, hence (jointly Gaussian) independent; the
resolved part ∇f̄ is deterministic over the footprint and the footprint's linear spread of f is
independent of the residual's gradient. So E[∇h] = E[g′] ∇f̄ and E[∇h ∇hᵀ] = E[g′²] (∇f̄ ∇f̄ᵀ + Σ_∇f):
    p_h ≈ N(E[g], E[g²] − E[g]²),
    p_s ≈ N(E[g′] ∇f̄,  E[g′²] Σ_∇f + (E[g′²] − E[g′]²) ∇f̄ ∇f̄ᵀ),
the second form of the covariance is the task's E[g′²](∇f̄∇f̄ᵀ + Σ_∇f) − E[g′]²∇f̄∇f̄ᵀ, rearranged so that
it stays positive semi-definite under float32 rounding (both variances are clamped at 0). Covariances
are packed as (xx, xy, yy).

Table layout (`PreconvolvedTransfer.data`, (n_sigma, n_mu, 4) float32 = (E[g], E[g²], E[g′], E[g′²])),
the clamp layout of colormap/gaussian.py:
  μ_i = lo + (i + 0.5)(hi − lo)/n_mu, i = 0 .. n_mu − 1, [lo, hi] = mu_range (default (−2, 2), 256 texels);
  σ_j = sigma_max · j/(n_sigma − 1), j = 0 .. n_sigma − 1 (default 64 rows, sigma_max = 1; row 0 holds
  the functions themselves).
Lookup (ms_transferMoments in transfer.glsl, `.lookup` here), bilinear with half-texel remapping:
  u = (μ − lo)/(hi − lo), v = (clamp(σ/sigma_max, 0, 1)(n_sigma − 1) + 0.5)/n_sigma, clamp-to-edge: μ
  beyond [lo, hi] reads the edge column, σ > sigma_max reads sigma_max (documented limits: choose the
  range to hold the driver's μ ± 3σ).
Bake: the four functions sampled on a uniform grid aligned with the μ nodes (step dv = Δμ/k, at most a
third of the first σ row and a quarter of the function's feature width) and convolved with the sampled
Gaussian truncated at ±8σ and normalised (trapezoid rule: spectrally accurate for these smooth
functions; measured ≤ 1e-7 of the function's range against SciPy quadrature, i.e. float32 storage).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import fftconvolve
from scipy.special import expit

from prefilter.bake_cache import cached
from prefilter.colormap.gaussian import PreconvolvedMap

BAKE_VERSION = 1

# name -> (GLSL code, default parameters); codes are the MS_TRANSFER_* constants of transfer.glsl
_KINDS: dict[str, tuple[int, dict[str, float]]] = {
    "linear": (0, {}),
    "moss": (1, {"threshold": 0.1, "softness": 0.04}),
    "sponge": (2, {"threshold": 0.05, "softness": 0.04}),
}


def _soft_ramp(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """softplus(z) = ln(1 + eᶻ) > 0 and its derivative sigmoid(z), stable for any z."""
    return np.logaddexp(0.0, z), expit(z)


@dataclass
class TransferFunction:
    """A 1D height transfer function g of a driver value v (driver units), with analytic g′."""

    name: str
    params: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.name not in _KINDS:
            raise ValueError(f"unknown transfer function {self.name!r}; expected one of {', '.join(_KINDS)}")
        defaults = _KINDS[self.name][1]
        unknown = set(self.params) - set(defaults)
        if unknown:
            raise ValueError(
                f"transfer function {self.name!r} has no parameter {', '.join(sorted(unknown))}"
                f" (parameters: {', '.join(defaults) or 'none'})"
            )
        self.params = {**defaults, **{k: float(v) for k, v in self.params.items()}}
        if "softness" in self.params and not self.params["softness"] > 0:
            raise ValueError(f"transfer function {self.name!r}: softness must be > 0")

    @property
    def code(self) -> int:
        """The MS_TRANSFER_* kind of transfer.glsl."""
        return _KINDS[self.name][0]

    @property
    def param_vector(self) -> tuple[float, float]:
        """The vec2 params of ms_transferValue / ms_transferDerivative: (threshold, softness)."""
        return (self.params.get("threshold", 0.0), self.params.get("softness", 1.0))

    @property
    def feature_width(self) -> float:
        """The smallest scale (driver units) over which g changes shape; sets the bake's grid step."""
        return self.params.get("softness", math.inf)

    def _ramp(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t, s = self.params["threshold"], self.params["softness"]
        z = (v - t) / s if self.name == "moss" else (t - v) / s
        softplus, sigmoid = _soft_ramp(z)
        return s * softplus, sigmoid, z

    def g(self, v) -> np.ndarray:
        v = np.asarray(v, np.float64)
        if self.name == "linear":
            return v.copy()
        e, _, _ = self._ramp(v)
        return np.sqrt(e) if self.name == "moss" else -np.sqrt(e)

    def g_prime(self, v) -> np.ndarray:
        v = np.asarray(v, np.float64)
        if self.name == "linear":
            return np.ones_like(v)
        e, sigmoid, z = self._ramp(v)
        # sigmoid / (2 √e); far below the foot (z < −30) e and the sigmoid both underflow towards
        # s eᶻ and eᶻ, so use the limit √(eᶻ / s) / 2 there
        far = z < -30.0
        with np.errstate(divide="ignore", invalid="ignore"):
            near = sigmoid / (2.0 * np.sqrt(e))
        return np.where(far, 0.5 * np.exp(0.5 * np.minimum(z, 0.0)) / np.sqrt(self.params["softness"]), near)

    def slope_gain(self, sigma: float) -> float:
        """sqrt(E[g′(f)²]) for a driver f ~ N(0, σ²) (trapezoids over ±8σ, 20 001 nodes: g′ changes over
        the softness, which polynomial rules do not resolve): at a point of a Gaussian field f and ∇f are
        independent, so ∇h = g′(f) ∇f has this times ∇f's deviation."""
        z = np.linspace(-8.0, 8.0, 20001)
        density = np.exp(-0.5 * z * z) / np.sqrt(2.0 * np.pi)
        return float(np.sqrt(np.trapezoid(self.g_prime(sigma * z) ** 2 * density, z)))

    def moments_integrand(self, v) -> np.ndarray:
        """(g, g², g′, g′²) at v, shape (..., 4): what the table convolves with N(μ, σ²)."""
        g, gp = self.g(v), self.g_prime(v)
        return np.stack([g, g * g, gp, gp * gp], axis=-1)


def _constructor(name: str) -> Callable[..., TransferFunction]:
    def make(**params: float) -> TransferFunction:
        return TransferFunction(name, params)

    make.__name__ = name
    return make


TRANSFER_FUNCTIONS: dict[str, Callable[..., TransferFunction]] = {name: _constructor(name) for name in _KINDS}


class PreconvolvedTransfer(PreconvolvedMap):
    """(n_sigma, n_mu, 4) float32: E[g], E[g²], E[g′], E[g′²] under N(μ_i, σ_j²); the layout, texture and
    NumPy lookup of a clamp-table PreconvolvedMap (colormap/gaussian.py)."""

    def __init__(self, data: np.ndarray, sigma_max: float, mu_range: tuple[float, float]):
        super().__init__(data, "clamp", sigma_max, mu_range)

    @property
    def range_uniform(self) -> tuple[float, float, float]:
        """The `range` argument of ms_transferMoments: (lo, hi, sigma_max)."""
        return (*self.mu_range, self.sigma_max)


def _bake(
    tf: TransferFunction, n_mu: int, n_sigma: int, sigma_max: float, lo: float, hi: float
) -> np.ndarray:
    dmu = (hi - lo) / n_mu
    sigmas = sigma_max * np.arange(n_sigma) / (n_sigma - 1)
    step = min(sigmas[1] / 3.0, tf.feature_width / 4.0)
    k = max(1, math.ceil(dmu / step))
    dv = dmu / k  # the μ nodes are every k-th grid point
    reach = math.ceil(8.0 * sigma_max / dv)
    mu0 = lo + 0.5 * dmu
    grid = mu0 + dv * np.arange(-reach, (n_mu - 1) * k + reach + 1)
    values = tf.moments_integrand(grid)  # (len, 4)
    nodes = reach + k * np.arange(n_mu)
    out = np.empty((n_sigma, n_mu, 4))
    out[0] = values[nodes]
    for j in range(1, n_sigma):
        m = math.ceil(8.0 * sigmas[j] / dv)
        kernel = np.exp(-0.5 * (dv * np.arange(-m, m + 1) / sigmas[j]) ** 2)
        kernel /= kernel.sum()
        window = values[nodes[0] - m : nodes[-1] + m + 1]
        smoothed = fftconvolve(window, kernel[:, None], mode="valid", axes=0)  # centre of output q: q + m
        out[j] = smoothed[nodes - nodes[0]]
    return out


def preconvolve_transfer(
    tf: TransferFunction,
    n_mu: int = 256,
    n_sigma: int = 64,
    sigma_max: float = 1.0,
    mu_range: tuple[float, float] = (-2.0, 2.0),
) -> PreconvolvedTransfer:
    """Bake (E[g], E[g²], E[g′], E[g′²]) under N(μ, σ²) over the grid above; cached by content hash."""
    lo, hi = float(mu_range[0]), float(mu_range[1])
    if not (hi > lo and sigma_max > 0 and n_mu >= 2 and n_sigma >= 2):
        raise ValueError(
            f"preconvolve_transfer: need lo < hi, sigma_max > 0, n_mu, n_sigma >= 2; "
            f"got mu_range={mu_range}, sigma_max={sigma_max}, n_mu={n_mu}, n_sigma={n_sigma}"
        )
    params = {
        "version": BAKE_VERSION,
        "transfer": tf.name,
        "params": tf.params,
        "n_mu": n_mu,
        "n_sigma": n_sigma,
        "sigma_max": sigma_max,
        "mu_range": [lo, hi],
    }

    def compute() -> np.ndarray:
        return _bake(tf, n_mu, n_sigma, sigma_max, lo, hi).astype(np.float32)

    data = cached("transfer-moments", params, (), compute)
    return PreconvolvedTransfer(data, sigma_max, (lo, hi))


def transfer_stats(moments, grad_mean, grad_cov) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Python twin of ms_transferStats. moments (..., 4) = (E[g], E[g²], E[g′], E[g′²]); grad_mean (..., 2)
    = ∇f̄; grad_cov (..., 3) = Σ_∇f as (xx, xy, yy). Returns h_mean (...), h_var (...), slope_mean (..., 2),
    slope_cov (..., 3) (eqs. 19–28, see the header)."""
    m = np.asarray(moments, np.float64)
    gm = np.asarray(grad_mean, np.float64)
    gc = np.asarray(grad_cov, np.float64)
    h_mean = m[..., 0]
    h_var = np.maximum(m[..., 1] - m[..., 0] ** 2, 0.0)
    slope_mean = m[..., 2, None] * gm
    outer = np.stack([gm[..., 0] ** 2, gm[..., 0] * gm[..., 1], gm[..., 1] ** 2], axis=-1)
    spread = np.maximum(m[..., 3] - m[..., 2] ** 2, 0.0)
    slope_cov = m[..., 3, None] * gc + spread[..., None] * outer
    return h_mean, h_var, slope_mean, slope_cov
