"""Gaussian-preconvolved colour maps: Heitz, Nowrouzezahrai, Poulin, Neyret 2013 §4 / 2014 §4.2, eq. (9).

    C̄(μ, σ) = ⟨C, N(μ, σ²)⟩ = [C * N(0, σ²)](μ)

for the piecewise-constant colour table C of colormap/table.py (entry i over [i/n, (i+1)/n)),
repeated for modulo tables (periodic convolution) and edge-extended for clamp tables. Sampled with σ,
not σ² (Heitz 2014 footnote 3).

Table layout (`PreconvolvedMap.data`, (n_sigma, n_mu, 4) float32, premultiplied like the table):
  σ_j = sigma_max · j / (n_sigma − 1), j = 0 .. n_sigma − 1 (row 0 is the table itself);
  modulo: μ_i = (i + 0.5) / n_mu over one period (the texture repeats in μ);
  clamp:  μ_i = lo + (i + 0.5) (hi − lo) / n_mu over [lo, hi] = mu_range (clamped beyond: exact to
          Φ(−3) = 0.1 % while the range reaches 3 σ_max past the table's ends).
Lookup (cm_gaussian in colormap.glsl): u = μ (modulo) or (μ − lo)/(hi − lo) (clamp);
v = (σ / sigma_max · (n_sigma − 1) + 0.5) / n_sigma, bilinear. σ > sigma_max uses σ_max: for modulo
tables with sigma_max = 1 the result is the table mean to 1e-8 there; for clamp tables it is an error
that grows with σ (documented limit).

Box-filtered lookups (`PreconvolvedMap.box_data`, cm_gaussianBox): the mean of C̄(·, σ) over a box
[μ − w/2, μ + w/2], i.e. the table convolved with box(w) * N(0, σ²), from the integral of each row over μ
(Hart's summed-area table, eqs. 13-15, applied to the preconvolved rows; C̄ taken as constant over each
μ texel, so the integral is exact at texel edges and linear between them). Layout (n_sigma, 3 n_mu + 1,
4): column c holds S(c − n_mu), S(y) = ∫_0^y C̄ over y μ texels, for y in [−n_mu, 2 n_mu]: three copies
of [lo, hi], the table's periods (modulo) or its edge columns extended (clamp), so a box never needs a
branch. Modulo: widths of a whole period or more give the row mean (Hart's rule for widths over the
table). Clamp: a box reaching beyond the three copies is cut to them (it is then nearly all the edge
colour anyway).

Derivative (`PreconvolvedMap.derivative_data`): ∂C̄/∂μ of each row, in the layout of `data` and read
like it (cm_gaussian on its own texture); surface-filter's slope colours under a light need it.

Bake: modulo tables by the exact Fourier series of the piecewise-constant table times the Gaussian's
transfer function exp(−2π²σ²k²), |k| <= 2 n (exact to 1e-15 for σ >= 1/n); narrower σ and all clamp
tables by the edge form C̄ = c_last + Σ_e (c_{e−1} − c_e) Φ((x_e − μ)/σ) over the entry edges x_e. Where the
μ texel is a simple fraction p/q of an entry (the default grid: 256 texels per table, a power of two
long), a clamp row is that sum as q discrete convolutions of the jumps with Φ on a lattice, by FFT (same
values to 2e-14; a 4096-entry table's 256 rows bake in 0.5 s instead of 17 s).
Defaults: 256 x 256 (modulo), 256 per table period in μ (clamp), sigma_max = 1, mu_range = (-1, 2);
a material's [object.material.preconvolved] table overrides them (size = [n_mu, n_sigma], sigma_max,
mu_range).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import moderngl
import numpy as np
import scipy.fft
from scipy.special import ndtr

from prefilter.bake_cache import cached
from prefilter.colormap.table import ColourTable
from prefilter.gl.textures import float_texture

BAKE_VERSION = 1


@dataclass
class PreconvolvedMap:
    data: np.ndarray  # (n_sigma, n_mu, 4) float32
    wrap: str
    sigma_max: float
    mu_range: tuple[float, float]  # clamp tables; (0, 1) for modulo

    def mu_nodes(self) -> np.ndarray:
        lo, hi = self.mu_range
        n_mu = self.data.shape[1]
        return lo + (np.arange(n_mu) + 0.5) * (hi - lo) / n_mu

    def sigma_nodes(self) -> np.ndarray:
        return self.sigma_max * np.arange(self.data.shape[0]) / (self.data.shape[0] - 1)

    def upload(self, ctx: moderngl.Context) -> moderngl.Texture:
        return self._texture_like_data(ctx, self.data)

    def _texture_like_data(self, ctx: moderngl.Context, values: np.ndarray) -> moderngl.Texture:
        """A texture of `values`, laid out as `data` and read as cm_gaussian reads it (repeating in μ for
        modulo tables)."""
        return float_texture(ctx, values, repeat_x=self.wrap == "modulo")

    def _sigma_rows(self, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The lower σ row of a bilinear read and the weight of the row above (σ clamped to sigma_max)."""
        n_sigma = self.data.shape[0]
        y = np.clip(np.asarray(sigma, np.float64) / self.sigma_max, 0.0, 1.0) * (n_sigma - 1)
        y0 = np.minimum(np.floor(y).astype(int), n_sigma - 2)
        return y0, (y - y0)[..., None]

    def box_data(self) -> np.ndarray:
        """The integrated rows for cm_gaussianBox (layout in the module docstring), float32."""
        d = self.data.astype(np.float64)
        n_sigma, n_mu, _ = d.shape
        if self.wrap == "modulo":
            tiled = np.concatenate([d, d, d], axis=1)
        else:
            edges = [np.repeat(d[:, :1], n_mu, axis=1), d, np.repeat(d[:, -1:], n_mu, axis=1)]
            tiled = np.concatenate(edges, axis=1)
        s = np.concatenate([np.zeros((n_sigma, 1, 4)), np.cumsum(tiled, axis=1)], axis=1)
        return (s - s[:, n_mu : n_mu + 1]).astype(np.float32)  # S(0) = 0: the smallest float32 magnitudes

    def upload_box(self, ctx: moderngl.Context) -> moderngl.Texture:
        return float_texture(ctx, self.box_data())

    def derivative_data(self) -> np.ndarray:
        """∂C̄/∂μ of each row per unit of μ (table periods), float32, laid out and read like `data`: the
        central difference over the neighbouring μ texels (periodic for modulo tables; at a clamp table's
        end columns, over the column and its one neighbour, the map being flat there)."""
        d = self.data.astype(np.float64)
        lo, hi = self.mu_range
        step = (hi - lo) / d.shape[1]
        if self.wrap == "modulo":
            after, before = np.roll(d, -1, axis=1), np.roll(d, 1, axis=1)
        else:
            after = np.concatenate([d[:, 1:], d[:, -1:]], axis=1)
            before = np.concatenate([d[:, :1], d[:, :-1]], axis=1)
        return ((after - before) / (2.0 * step)).astype(np.float32)

    def upload_derivative(self, ctx: moderngl.Context) -> moderngl.Texture:
        return self._texture_like_data(ctx, self.derivative_data())

    def box_lookup(self, mu: np.ndarray, width: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """NumPy float64 twin of cm_gaussianBox over this bake (without the texture unit's rounding)."""
        n_mu = self.data.shape[1]
        lo, hi = self.mu_range
        box = self.box_data().astype(np.float64)
        x = (np.asarray(mu, np.float64) - lo) / (hi - lo) * n_mu
        w = np.maximum(np.abs(np.asarray(width, np.float64)) / (hi - lo) * n_mu, 1.0)
        if self.wrap == "modulo":
            x, w = x - n_mu * np.floor(x / n_mu), np.minimum(w, n_mu)
        a = np.clip(x - 0.5 * w, -n_mu, 2 * n_mu - 1)
        b = np.clip(x + 0.5 * w, -n_mu + 1, 2 * n_mu)
        y0, ty = self._sigma_rows(sigma)

        def integral(at):  # S(at), bilinear like the texture
            col = at + n_mu
            c0 = np.clip(np.floor(col).astype(int), 0, box.shape[1] - 2)
            tc = (col - c0)[..., None]
            row = lambda j: (1 - tc) * box[j, c0] + tc * box[j, c0 + 1]  # noqa: E731
            return (1 - ty) * row(y0) + ty * row(y0 + 1)

        return (integral(b) - integral(a)) / (b - a)[..., None]

    def lookup(self, mu: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """NumPy twin of cm_gaussian (bilinear with the same half-texel remapping), for tests."""
        n_mu = self.data.shape[1]
        lo, hi = self.mu_range
        x = (np.asarray(mu, np.float64) - lo) / (hi - lo) * n_mu - 0.5
        x0 = np.floor(x).astype(int)
        tx = x - x0
        if self.wrap == "modulo":
            xa, xb = x0 % n_mu, (x0 + 1) % n_mu
        else:
            xa, xb = np.clip(x0, 0, n_mu - 1), np.clip(x0 + 1, 0, n_mu - 1)
            tx = np.where(x < 0, 0.0, np.where(x > n_mu - 1, 1.0, tx))
        y0, ty = self._sigma_rows(sigma)
        d = self.data.astype(np.float64)
        row = lambda j: (1 - tx)[..., None] * d[j, xa] + tx[..., None] * d[j, xb]  # noqa: E731
        return (1 - ty) * row(y0) + ty * row(y0 + 1)


def gaussian_average(table: ColourTable, mu: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Exact C̄(μ, σ) by the edge form (any wrap, any σ >= 0), float64; shapes broadcast, result (..., 4)."""
    mu = np.asarray(mu, np.float64)
    sigma = np.asarray(sigma, np.float64)
    entries = table.entries.astype(np.float64)
    n = table.n
    if table.wrap == "modulo":
        reach = int(np.ceil(8.0 * float(np.max(sigma)) + 2.0))
        base = np.floor(mu)
        periods = np.arange(-reach, reach + 1)
        edges = (np.arange(n)[None, :] / n + periods[:, None]).ravel()  # edge e sits before entry e mod n
        jumps = np.tile(np.roll(entries, 1, axis=0) - entries, (len(periods), 1))
        start = entries[-1]  # value below the first edge considered: entry n-1 of the previous period
        x = (
            (edges[None, :] - (mu - base).reshape(-1, 1)).reshape(*mu.shape, -1)
            if mu.ndim
            else edges - (mu - base)
        )
    else:
        edges = np.arange(1, n) / n
        jumps = entries[:-1] - entries[1:]
        start = entries[-1]
        x = edges - mu[..., None] if mu.ndim else edges - mu
    s = sigma[..., None] if sigma.ndim else sigma
    with np.errstate(divide="ignore", invalid="ignore"):
        cdf = np.where(s > 0, ndtr(x / np.where(s > 0, s, 1.0)), (x > 0).astype(np.float64))
    if table.wrap == "modulo":
        # C̄ = c_{n-1} + Σ_e (c_{e-1} - c_e) Φ(...) with the edges of 2 reach + 1 periods around μ; the
        # mass beyond them (< Φ(-8)) is assigned to the value below the first edge, the start entry
        return start + np.tensordot(cdf, jumps, axes=([-1], [0]))
    return start + np.tensordot(cdf, jumps, axes=([-1], [0]))


def _bake_modulo(table: ColourTable, n_mu: int, n_sigma: int, sigma_max: float) -> np.ndarray:
    n = table.n
    entries = table.entries.astype(np.float64)
    mu = (np.arange(n_mu) + 0.5) / n_mu
    sigma = sigma_max * np.arange(n_sigma) / (n_sigma - 1)
    k = np.arange(-2 * n, 2 * n + 1)
    # Fourier coefficients of the piecewise-constant table: c_k = Σ_i c_i (1/n) sinc(k/n) e^{-2πik(i+1/2)/n}
    phase = np.exp(-2j * np.pi * np.outer(k, np.arange(n) + 0.5) / n)
    coefficients = (phase @ entries) * (np.sinc(k / n) / n)[:, None]
    transfer = np.exp(-2.0 * np.pi**2 * np.outer(sigma, k) ** 2)
    basis = np.exp(2j * np.pi * np.outer(k, mu))
    out = np.empty((n_sigma, n_mu, 4))
    for c in range(4):
        out[:, :, c] = np.real((transfer * coefficients[None, :, c]) @ basis)
    narrow = sigma < 1.0 / n  # the series is truncated at |k| = 2n: use the exact edge form there
    if narrow.any():
        out[narrow] = gaussian_average(table, mu[None, :], sigma[narrow, None])
    return out


def _lattice_ratio(ratio: float, n_mu: int) -> Fraction | None:
    """p/q = the μ texel in entry widths, if it is a fraction with q small enough for the lattice bake."""
    fraction = Fraction(ratio).limit_denominator(max(1, n_mu // 16))
    return fraction if abs(float(fraction) - ratio) <= 1e-12 * max(ratio, 1.0) else None


def _edge_form_on_lattice(table: ColourTable, mu: np.ndarray, sigmas: np.ndarray, ratio: Fraction):
    """The edge form C̄(μ_i, σ) = c_last + Σ_e (c_{e−1} − c_e) Φ((e − n μ_i)/(n σ)) over the entry edges e =
    1 .. n − 1, for μ_i in steps of p/q entry widths and every σ > 0 of `sigmas`, as q discrete convolutions
    a row: the μ_i of one residue class i ≡ c (mod q) lie p apart, on a unit lattice shifted by y_c = n μ_c,
    so each sum is the jumps convolved with Φ((d − y_c)/(n σ)) at integer d (a real FFT product, exact to
    rounding; the jumps' transform is made once per class)."""
    n = table.n
    entries = table.entries.astype(np.float64)
    jumps = entries[:-1] - entries[1:]  # a[e'] = c_{e'} - c_{e'+1} at edge e = e' + 1
    p, q = ratio.numerator, ratio.denominator
    out = np.empty((len(sigmas), len(mu), 4))
    for c in range(min(q, len(mu))):
        span = p * (len(range(c, len(mu), q)) - 1)  # lattice points m = 0 .. span, μ at m = p k
        d = np.arange(1 - span, n)[::-1]  # e − m over every edge and lattice point, reversed: the partner
        size = scipy.fft.next_fast_len(n - 1 + len(d) - 1, real=True)
        spectrum = scipy.fft.rfft(jumps, size, axis=0)
        for j, sigma in enumerate(sigmas):
            kernel = scipy.fft.rfft(ndtr((d - n * mu[c]) / (n * sigma)), size)
            full = scipy.fft.irfft(spectrum * kernel[:, None], size, axis=0)
            out[j, c::q] = entries[-1] + full[n - 2 : n - 1 + span : p]  # (a * reversed kernel)[n − 2 + m]
    return out


def _bake_clamp(table: ColourTable, n_mu: int, n_sigma: int, sigma_max: float, lo: float, hi: float):
    mu = lo + (np.arange(n_mu) + 0.5) * (hi - lo) / n_mu
    sigma = sigma_max * np.arange(n_sigma) / (n_sigma - 1)
    ratio = _lattice_ratio(table.n * (hi - lo) / n_mu, n_mu)
    if ratio is not None:  # row 0 (σ = 0) is the table itself
        first = gaussian_average(table, mu, np.zeros(n_mu))
        return np.concatenate([first[None], _edge_form_on_lattice(table, mu, sigma[1:], ratio)])
    out = np.empty((n_sigma, n_mu, 4))
    for j in range(n_sigma):  # row by row keeps memory at n_mu x n edges
        out[j] = gaussian_average(table, mu, np.full(n_mu, sigma[j]))
    return out


def preconvolve(
    table: ColourTable,
    n_mu: int | None = None,
    n_sigma: int = 256,
    sigma_max: float = 1.0,
    mu_range: tuple[float, float] = (-1.0, 2.0),
) -> PreconvolvedMap:
    """Bake C̄(μ, σ) for a (premultiplied) colour table; cached by content hash."""
    if table.wrap == "modulo":
        n_mu = n_mu or 256
        lo, hi = 0.0, 1.0
    else:
        lo, hi = mu_range
        n_mu = n_mu or int(round(256 * (hi - lo)))
    params = {
        "version": BAKE_VERSION,
        "wrap": table.wrap,
        "n_mu": n_mu,
        "n_sigma": n_sigma,
        "sigma_max": sigma_max,
        "mu_range": [lo, hi],
    }

    def compute() -> np.ndarray:
        if table.wrap == "modulo":
            data = _bake_modulo(table, n_mu, n_sigma, sigma_max)
        else:
            data = _bake_clamp(table, n_mu, n_sigma, sigma_max, lo, hi)
        return data.astype(np.float32)

    data = cached("preconvolved", params, (table.entries,), compute)
    return PreconvolvedMap(data, table.wrap, sigma_max, (lo, hi))


def parse_preconvolve_options(r) -> dict:
    """The optional [...preconvolved] table of a material (a scene.Reader or None): size = [n_mu, n_sigma],
    sigma_max, mu_range = [lo, hi] (clamp tables)."""
    if r is None:
        return {}
    options: dict = {}
    if r.has("size"):
        size = r.vector("size", 2)
        if any(v < 2 or v > 4096 or v != int(v) for v in size):
            raise r.fail("size", f"expected two integers in [2, 4096], got {list(size)}")
        options["n_mu"], options["n_sigma"] = int(size[0]), int(size[1])
    if r.has("sigma_max"):
        options["sigma_max"] = r.number("sigma_max", lo=1e-6)
    if r.has("mu_range"):
        lo, hi = r.vector("mu_range", 2)
        if hi <= lo:
            raise r.fail("mu_range", f"expected [lo, hi] with lo < hi, got {[lo, hi]}")
        options["mu_range"] = (float(lo), float(hi))
    r.finish()
    return options
