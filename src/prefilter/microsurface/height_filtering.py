"""Height filtering distribution of a Gaussian microsurface: Heitz, Nowrouzezahrai, Poulin, Neyret 2014
§5.1, eqs. (14)–(17) (DESIGN.md errata: σ_d is a central moment; the log fits are rough).

    D_h(h) ∝ P_h(h)^L p_h(h),   L = Λ(ω_o) + Λ(ω_i) >= 0,   p_h = N(0, σ_h²), P_h its CDF    (eq. 15)

the distribution of the heights that are seen and lit. Its mean μ_d(L) and standard deviation σ_d(L)
(eqs. 16, 17) scale with σ_h, so everything here is in units of σ_h. In u = P_h(h), D_h is Beta(L+1, 1):
E_Dh[P_h] = (L+1)/(L+2), which gives Heitz and Neyret's eq. (3). μ_d(0) = 0, σ_d(0) = 1; μ_d grows and
σ_d shrinks with L (μ_d = 0.344, σ_d = 0.891 at L = 0.5; 3.852, 0.304 at L = 1e4).

Exact moments (`height_filtering_moments`): trapezoid rule on h/σ_h in [−10, 10] with step 1/128 of
exp(L log Φ(h) − h²/2) (spectrally accurate for these smooth, fast-decaying integrands; it agrees with
adaptive quadrature to 1e-10, see the tests).

Table layout (`HeightFilteringTable.data`, (n, 2) float32 = (μ_d/σ_h, σ_d/σ_h)), default n = 256,
L_max = 1e4:  entry i at L_i = (1 + L_max)^(i/(n−1)) − 1, i.e. t = log(1 + L)/log(1 + L_max) = i/(n−1).
Lookup (ms_heightFiltering in height_filtering.glsl, NumPy twin `.lookup`): texture coordinate
u = (t (n − 1) + 0.5)/n (half-texel remapping) of an n x 1 RG32F texture, LINEAR, clamp-to-edge, so the
result is linear in t between entries. Measured linear-interpolation error against quadrature over
L in [0, 100] and over all of [0, L_max] (n = 256, L_max = 1e4): 4.7e-5 σ_h for μ_d, 2.4e-5 σ_h for σ_d
(the bar is 1e-3 σ_h), largest near L = 0.02 where μ_d rises fastest in t.
Beyond L_max the lookup returns the L_max entry (3.852, 0.304) while the truth at L = 1e5 is
(4.384, 0.272): an error of 0.53 σ_h in μ_d (μ_d keeps growing, roughly like √(2 ln L)). Smith's Λ as
computed by smith.py is at most 3989 (grazing clamp), so L = Λ_o + Λ_i <= 7979 never leaves the table.

The paper's log fit, eqs. (16)/(17), kept to compare against (`height_filtering_fit`,
ms_heightFilteringFit):  μ_d ≈ α_μ σ_h log(β_μ L + 1),  σ_d ≈ σ_h / (1 + α_σ log(β_σ L + 1)),
α_μ = 0.39, β_μ = 4.75, α_σ = 0.26, β_σ = 1.13. At L = 0.5 it gives μ_d = 0.474 σ_h where the truth is
0.344 σ_h; its max error over L in [0, 100] is 0.131 σ_h for μ_d (at L ≈ 0.56) and 0.028 σ_h for σ_d
(at L ≈ 13).
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np
from scipy.special import log_ndtr

from prefilter.bake_cache import cached
from prefilter.gl.textures import float_texture

BAKE_VERSION = 1
L_MAX = 1e4
TABLE_SIZE = 256
FIT_ALPHA_MU, FIT_BETA_MU = 0.39, 4.75
FIT_ALPHA_SIGMA, FIT_BETA_SIGMA = 0.26, 1.13

_STEP = 1.0 / 128.0
_GRID = np.arange(-10.0, 10.0 + 0.5 * _STEP, _STEP)


def height_filtering_moments(L) -> tuple[np.ndarray, np.ndarray]:
    """(μ_d/σ_h, σ_d/σ_h) of D_h ∝ P_h^L p_h for L >= 0 (any shape), by quadrature in float64."""
    L = np.asarray(L, np.float64)
    flat = np.maximum(L.reshape(-1), 0.0)
    mean = np.empty_like(flat)
    std = np.empty_like(flat)
    log_cdf = log_ndtr(_GRID)
    log_pdf = -0.5 * _GRID * _GRID
    for start in range(0, flat.size, 64):  # blocks of 64 rows keep memory small
        block = flat[start : start + 64, None]
        logw = block * log_cdf[None, :] + log_pdf[None, :]
        w = np.exp(logw - logw.max(axis=1, keepdims=True))
        w /= w.sum(axis=1, keepdims=True)
        mu = w @ _GRID
        mean[start : start + 64] = mu
        std[start : start + 64] = np.sqrt(np.sum(w * (_GRID[None, :] - mu[:, None]) ** 2, axis=1))
    return mean.reshape(L.shape), std.reshape(L.shape)


def height_filtering_fit(L, sigma_h: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(μ_d, σ_d) from the paper's log fits, eqs. (16)/(17); in units of σ_h times sigma_h."""
    L = np.maximum(np.asarray(L, np.float64), 0.0)
    mu = FIT_ALPHA_MU * sigma_h * np.log(FIT_BETA_MU * L + 1.0)
    sigma = sigma_h / (1.0 + FIT_ALPHA_SIGMA * np.log(FIT_BETA_SIGMA * L + 1.0))
    return mu, sigma


@dataclass
class HeightFilteringTable:
    data: np.ndarray  # (n, 2) float32: (μ_d/σ_h, σ_d/σ_h) at L_i = (1 + l_max)^(i/(n-1)) - 1
    l_max: float

    def l_nodes(self) -> np.ndarray:
        n = self.data.shape[0]
        return np.expm1(np.arange(n) / (n - 1) * np.log1p(self.l_max))

    def lookup(self, L) -> np.ndarray:
        """NumPy twin of ms_heightFiltering: (..., 2) = (μ_d/σ_h, σ_d/σ_h), linear in t between entries."""
        n = self.data.shape[0]
        t = np.clip(np.log1p(np.maximum(np.asarray(L, np.float64), 0.0)) / np.log1p(self.l_max), 0.0, 1.0)
        x = t * (n - 1)
        i0 = np.minimum(np.floor(x).astype(int), n - 2)
        f = (x - i0)[..., None]
        d = self.data.astype(np.float64)
        return (1.0 - f) * d[i0] + f * d[i0 + 1]

    def upload(self, ctx: moderngl.Context) -> moderngl.Texture:
        """An n x 1 RG32F texture, LINEAR, clamp-to-edge (for ms_heightFiltering)."""
        return float_texture(ctx, self.data)


def height_filtering_table(n: int = TABLE_SIZE, l_max: float = L_MAX) -> HeightFilteringTable:
    """Bake (μ_d/σ_h, σ_d/σ_h) over L in [0, l_max] (layout in the module header); cached by content hash.

    A table with another l_max needs `#define MS_HF_LMAX <l_max>` in the shader that looks it up.
    """
    if n < 2 or l_max <= 0:
        raise ValueError(f"height filtering table needs n >= 2 and l_max > 0, got n={n}, l_max={l_max}")
    params = {"version": BAKE_VERSION, "n": int(n), "l_max": float(l_max)}

    def compute() -> np.ndarray:
        L = np.expm1(np.arange(n) / (n - 1) * np.log1p(l_max))
        mean, std = height_filtering_moments(L)
        return np.stack([mean, std], axis=1).astype(np.float32)

    return HeightFilteringTable(cached("height-filtering", params, (), compute), float(l_max))
