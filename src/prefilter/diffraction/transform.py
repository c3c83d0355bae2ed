"""Stam's diffraction transform of a height field by Single's Taylor/FFT expansion (bake and references).

Sources
- Stam, "Diffraction Shaders", SIGGRAPH 1999, eqs. (5)-(7): p(x, y) = exp(i k w h(x, y)) and the BRDF is
  proportional to |P(k u, k v)|², P(α, β) = ∫∫ p(x, y) e^{-i(α x + β y)} dx dy, (u, v, w) = k̂1 − k̂2.
- Single, "Diffraction Shader", thesis draft 2013 (/work/shared/papers): §2.4.1-2.4.3 expand p in a Taylor
  series, P = Σ_n (k w)^n F{(i h)^n / n!}, one FFT per term; §2.4.5 bounds the truncation; §2.5 (empty in
  the draft) windows the patch by a Gaussian; §2.7 the gain of a periodically tiled patch.

Errata applied (DESIGN.md, "Single's thesis is an unfinished draft")
- The complex Taylor terms are summed first and |·|² is taken afterwards (not a sum of |term|²).
- The mean height is subtracted before expanding (a height offset only changes the phase of P).
- |e^{iθ}| = 1, so the Lagrange bound has no e^{x_max} factor: N is the smallest integer with
  x_max^{N+1} / (N+1)! ≤ ε, x_max = k_max · |w|_max · max|h − mean h|, k_max = 2π / λ_min.
- Relative reflectance: P̃ is normalised so that a flat mirror gives 1 at α = β = 0 (Stam's constant cancels).
- §2.7: the imaginary part of (p1 + i q1)(p2 + i q2) is p1 q2 + q1 p2 (the draft prints p1 p2 + q1 q2).

Conventions
- Lengths in µm, wavenumbers k = 2π/λ and spatial frequencies α, β in rad/µm, λ in µm (0.38-0.78).
- Heights are (H, W) arrays indexed [row, column] = [y, x]; sample (i, j) lies at (x, y) = (j dx, i dy),
  pixel = (dx, dy). Spatial frequencies of the DFT bins: freq_x = 2π fftfreq(W, dx), freq_y likewise.
- c_n[m, l] = fft2((i h_c)^n / n!)[m, l] / (H W) (NumPy ordering) is the Fourier-series coefficient of the
  periodically tiled (period W dx by H dy) term at (α_l, β_m):
  (i h_c)^n / n! = Σ c_n[m, l] e^{i(α_l x + β_m y)}.
  Bin indices are periodic (l ≡ l + W), as for the GLSL lookup (stam.glsl).
- Windowed transform (relative): the tiled surface seen through the Gaussian coherence window
  exp(−(x² + y²) / (2σ²)), divided by the window's own integral 2πσ²:
      P̃(α, β; k w) = Σ_n (k w)^n Σ_{m,l} c_n[m, l] exp(−σ² ((α − α_l)² + (β − β_m)²) / 2),
  summed over every bin within WINDOW_RADIUS / σ of (α, β) (at least the 2 x 2 nearest); Horner in k w.
  A flat surface gives P̃ = exp(−σ² (α² + β²) / 2), |P̃|² = exp(−σ² (α² + β²)).
- Geometry (grating_peaks): tangent frame +x across the grooves, +z the normal. ω_i = (sin θ_i, 0, cos θ_i)
  points towards the light, ω_o = (sin θ_r, 0, cos θ_r) towards the viewer (angles signed by x). As in
  stam.glsl, k̂1 = −ω_i (propagation direction of the incident light), k̂2 = ω_o, (u, v, w) = k̂1 − k̂2, so
  u = −(sin θ_i + sin θ_r), w = −(cos θ_i + cos θ_r) and the mirror direction is θ_r = −θ_i. The Fourier
  component of p at α = 2π j / d therefore appears at sin θ_r = −j λ/d − sin θ_i; labelling the order
  m = −j, the grating equation reads   sin θ_r = m λ / d − sin θ_i.
  (order_powers takes Fourier indices j; the order m of the grating equation is j = −m.)
- Accuracy: the Taylor sum cancels terms as large as e^{x}/√(2πx) (x = |k w| max|h_c|), so in float64 it
  holds ~1e-16 e^{x} absolute accuracy: fine for heights up to about 0.5 µm at |w| ≤ 2, λ ≥ 0.38 µm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

WINDOW_RADIUS = 6.0  # bins within WINDOW_RADIUS/σ of (α, β) are summed: the Gaussian there is ≤ 1.5e-8
DEFAULT_SIGMA = 65.0 / 4.0  # µm, standard deviation of the coherence window
STENCIL_REACH = 3.5  # σ Δ R of the shader's bin stencil (stencil_radius)
_CHUNK = 1 << 22  # elements per vectorised block


def _order_for(x: float, epsilon: float) -> int:
    """Smallest N ≥ 0 with x^{N+1} / (N+1)! ≤ ε (x ≥ 0)."""
    if not epsilon > 0:
        raise ValueError(f"epsilon must be positive, got {epsilon}")
    x = abs(float(x))
    n, term = 0, x  # term = x^{n+1} / (n+1)!
    while term > epsilon:
        n += 1
        term *= x / (n + 1)
        if n > 10000:
            raise ValueError(f"Taylor order for x = {x:g} exceeds 10000 terms")
    return n


def taylor_order(
    height_range_um: float, lambda_min_um: float = 0.38, w_max: float = 2.0, epsilon: float = 1e-7
) -> int:
    """The number of Taylor terms N (terms 0..N) for a truncation error ≤ ε (Single §2.4.5, corrected).

    height_range_um is max |h − mean h| (µm); x = (2π / λ_min) · w_max · height_range_um and N is the smallest
    integer with x^{N+1} / (N+1)! ≤ ε (no e^{x} factor: |e^{iθ}| = 1).
    """
    if not lambda_min_um > 0:
        raise ValueError(f"lambda_min_um must be positive, got {lambda_min_um}")
    x = 2.0 * math.pi / lambda_min_um * abs(w_max) * abs(height_range_um)
    return _order_for(x, epsilon)


def _pixel(pixel) -> tuple[float, float]:
    dx, dy = (pixel, pixel) if np.isscalar(pixel) else pixel
    dx, dy = float(dx), float(dy)
    if not (dx > 0 and dy > 0):
        raise ValueError(f"pixel sizes must be positive, got {(dx, dy)}")
    return dx, dy


def _centred(heights) -> np.ndarray:
    h = np.asarray(heights, dtype=np.float64)
    if h.ndim == 1:
        h = h[None, :]
    if h.ndim != 2 or h.size == 0:
        raise ValueError(f"heights must be a non-empty (H, W) array, got shape {np.shape(heights)}")
    return h - h.mean()


def _power_terms(h_c: np.ndarray, order: int):
    """Yield (i h_c)^n / n! for n = 0..order."""
    term = np.ones(h_c.shape, dtype=np.complex128)
    ih = 1j * h_c
    for n in range(order + 1):
        yield term
        term = term * ih / (n + 1)


@dataclass
class TaylorTerms:
    """Fourier-series coefficients of the Taylor terms of exp(i k w h_c) for a periodically tiled patch.

    coefficients: complex128 (N+1, H, W), c_n = fft2((i h_c)^n / n!) / (H W); freq_x (W,), freq_y (H,) the
    bin frequencies in rad/µm (2π fftfreq); sigma the coherence window's standard deviation (µm); pixel
    (dx, dy) µm; order N. See the module docstring for P̃.
    """

    coefficients: np.ndarray
    freq_x: np.ndarray
    freq_y: np.ndarray
    sigma: float
    pixel: tuple[float, float]
    order: int

    @property
    def nbytes(self) -> int:
        return int(self.coefficients.nbytes + self.freq_x.nbytes + self.freq_y.nbytes)

    @property
    def spacing(self) -> tuple[float, float]:
        """Bin spacing (Δα, Δβ) = (2π / (W dx), 2π / (H dy)) in rad/µm."""
        _, h, w = self.coefficients.shape
        return 2 * math.pi / (w * self.pixel[0]), 2 * math.pi / (h * self.pixel[1])

    def evaluate(self, alpha, beta, kw, *, stencil: int | None = None) -> np.ndarray:
        """P̃(α, β; k w) (complex, relative: flat → 1 at the origin), broadcast over the arguments.

        Sums every bin within WINDOW_RADIUS / σ of (α, β); stencil = R keeps only the 2R x 2R bins around
        the cell that holds (α, β), as stam.glsl does with DF_STENCIL = R (see `stencil_radius`).
        """
        alpha, beta, kw = np.broadcast_arrays(
            np.asarray(alpha, np.float64), np.asarray(beta, np.float64), np.asarray(kw, np.float64)
        )
        shape = alpha.shape
        a, b, k = alpha.ravel(), beta.ravel(), kw.ravel()
        layers, h, w = self.coefficients.shape
        flat = self.coefficients.reshape(layers, h * w)
        da, db = self.spacing
        s = float(self.sigma)
        rx = stencil - 1 if stencil else math.ceil(WINDOW_RADIUS / (s * da))
        ry = stencil - 1 if stencil else math.ceil(WINDOW_RADIUS / (s * db))
        ox = np.arange(-rx, rx + 2)
        oy = np.arange(-ry, ry + 2)
        chunk = max(1, _CHUNK // (len(ox) * len(oy) * 4))
        out = np.empty(a.shape, dtype=np.complex128)
        for start in range(0, a.size, chunk):
            sl = slice(start, start + chunk)
            ax, by, kk = a[sl], b[sl], k[sl]
            lx = np.floor(ax / da).astype(np.int64)[:, None] + ox  # (M, Sx)
            ly = np.floor(by / db).astype(np.int64)[:, None] + oy  # (M, Sy)
            gx = np.exp(-0.5 * s * s * (ax[:, None] - lx * da) ** 2)
            gy = np.exp(-0.5 * s * s * (by[:, None] - ly * db) ** 2)
            index = (ly % h)[:, :, None] * w + (lx % w)[:, None, :]  # (M, Sy, Sx)
            kb = kk[:, None, None]
            acc = flat[layers - 1].take(index)
            for n in range(layers - 2, -1, -1):  # Horner in k w: sum the complex terms first
                acc = acc * kb + flat[n].take(index)
            out[sl] = np.einsum("myx,my,mx->m", acc, gy, gx)
        return out.reshape(shape)


def stencil_radius(sigma: float, spacing: tuple[float, float]) -> int:
    """R of the 2R x 2R bin stencil that carries the coherence window to within about 0.5 % of a slice's peak.

    Bins R − ½ … R + ½ spacings away are the first left out; their window weight exp(−(σ Δ R)²/2) must be
    small next to the partial sums, which oscillate. Measured on in-plane slices at θ_i = 0°, 30°, 60°
    against the full-window sum (docs/diffraction.md): σ Δ R ≈ 3.0 still leaves 2–8 % of the peak on the
    snake ridges (2D), σ Δ R ≈ 3.6–3.8 leaves ≤ 0.5 %; gratings reach 1e-4 at 3.0. STENCIL_REACH = 3.5
    gives 8 x 8 bins for the grating and CD presets (σ Δ ≈ 1), 12 x 12 for the snakes (σ Δ ≈ 0.6), and
    2 x 2 (R = 1) at the default window (σ Δ ≈ 4).
    """
    return max(1, math.ceil(STENCIL_REACH / (sigma * min(spacing))))


def taylor_terms(
    heights,
    pixel,
    sigma: float = DEFAULT_SIGMA,
    lambda_min: float = 0.38,
    epsilon: float = 1e-7,
    max_order: int | None = None,
) -> TaylorTerms:
    """Bake the Taylor/FFT terms of a height patch (µm): N = taylor_order(max|h_c|, lambda_min, 2, ε).

    max_order caps N (the truncation bound then no longer holds for the largest |k w|).
    """
    dx, dy = _pixel(pixel)
    if not sigma > 0:
        raise ValueError(f"sigma must be positive, got {sigma}")
    h_c = _centred(heights)
    order = taylor_order(float(np.abs(h_c).max()), lambda_min, 2.0, epsilon)
    if max_order is not None:
        order = min(order, int(max_order))
    rows, cols = h_c.shape
    coefficients = np.empty((order + 1, rows, cols), dtype=np.complex128)
    for n, term in enumerate(_power_terms(h_c, order)):
        coefficients[n] = np.fft.fft2(term) / (rows * cols)
    return TaylorTerms(
        coefficients=coefficients,
        freq_x=2 * np.pi * np.fft.fftfreq(cols, dx),
        freq_y=2 * np.pi * np.fft.fftfreq(rows, dy),
        sigma=float(sigma),
        pixel=(dx, dy),
        order=order,
    )


def relative_power(terms: TaylorTerms, alpha, beta, kw) -> np.ndarray:
    """|P̃(α, β; k w)|²: the structure's reflectance relative to a flat mirror (1 at the origin)."""
    return np.abs(terms.evaluate(alpha, beta, kw)) ** 2


def _points(alpha, beta, kw):
    alpha, beta, kw = np.broadcast_arrays(
        np.asarray(alpha, np.float64), np.asarray(beta, np.float64), np.asarray(kw, np.float64)
    )
    return alpha.shape, alpha.ravel(), beta.ravel(), kw.ravel()


def _phasors(a, b, rows, cols, dx, dy):
    ex = np.exp(-1j * a[:, None] * (np.arange(cols) * dx))  # (M, W)
    ey = np.exp(-1j * b[:, None] * (np.arange(rows) * dy))  # (M, H)
    return ex, ey


def direct_transform(heights, pixel, alpha, beta, kw) -> np.ndarray:
    """Reference: (1/(H W)) Σ_{x,y} exp(i k w h_c) exp(−i(α x + β y)) over one patch (no window, no tiling).

    A direct non-uniform DFT at arbitrary (α, β, k w), broadcast over the arguments.
    """
    dx, dy = _pixel(pixel)
    h_c = _centred(heights)
    rows, cols = h_c.shape
    shape, a, b, k = _points(alpha, beta, kw)
    out = np.empty(a.shape, dtype=np.complex128)
    chunk = max(1, _CHUNK // h_c.size)
    for start in range(0, a.size, chunk):
        sl = slice(start, start + chunk)
        ex, ey = _phasors(a[sl], b[sl], rows, cols, dx, dy)
        p = np.exp(1j * k[sl, None, None] * h_c)  # (M, H, W)
        out[sl] = np.einsum("mh,mhw,mw->m", ey, p, ex) / h_c.size
    return out.reshape(shape)


def taylor_direct(source, alpha, beta, kw, *, pixel=None, epsilon: float = 1e-7) -> np.ndarray:
    """The single-patch NUDFT of direct_transform, from the Taylor sum Σ_n (k w)^n NUDFT{(i h_c)^n / n!}.

    source is a TaylorTerms (its terms are recovered from the coefficients by an inverse FFT, so this checks
    the bake) or a height array (then pixel is required and the terms are baked with ε).
    """
    if isinstance(source, TaylorTerms):
        terms = source
    else:
        if pixel is None:
            raise ValueError("taylor_direct: pixel is required with a height array")
        terms = taylor_terms(source, pixel, epsilon=epsilon)
    dx, dy = terms.pixel
    layers, rows, cols = terms.coefficients.shape
    spatial = np.fft.ifft2(terms.coefficients) * (rows * cols)  # (i h_c)^n / n!
    shape, a, b, k = _points(alpha, beta, kw)
    out = np.empty(a.shape, dtype=np.complex128)
    chunk = max(1, _CHUNK // (rows * cols + layers * (rows + cols)))
    for start in range(0, a.size, chunk):
        sl = slice(start, start + chunk)
        ex, ey = _phasors(a[sl], b[sl], rows, cols, dx, dy)
        t = np.einsum("mh,nhw,mw->mn", ey, spatial, ex, optimize=True) / (rows * cols)  # (M, N+1)
        acc = t[:, -1]
        for n in range(layers - 2, -1, -1):
            acc = acc * k[sl] + t[:, n]
        out[sl] = acc
    return out.reshape(shape)


def order_powers(heights, pixel, kw: float, orders, period: float | None = None, epsilon: float = 1e-12):
    """Power |c_j|² of the Fourier-series coefficient of exp(i k w h_c(x)) at α = 2π j / period, j in orders.

    The structure repeats along x with the given period (default: the patch width W dx, which must be a whole
    number of periods). Computed from the Taylor terms at the DFT bin of each order, β = 0 (row 0 of the 2D
    series: for a field varying along y as well this is the y-averaged coefficient). The order count follows
    from x = |k w| max|h_c| and ε. Over all bins the powers sum to 1 (Parseval). j is a Fourier index: the
    grating-equation order of the module docstring is m = −j.
    """
    dx, _ = _pixel(pixel)
    h_c = _centred(heights)
    rows, cols = h_c.shape
    width = cols * dx
    period = width if period is None else float(period)
    step = width / period
    if abs(step - round(step)) > 1e-6 * max(1.0, step) or round(step) < 1:
        raise ValueError(f"the patch width {width:g} µm is not a whole number of periods {period:g} µm")
    step = int(round(step))
    order = _order_for(abs(kw) * float(np.abs(h_c).max()), epsilon)
    bins = (np.asarray(orders, dtype=np.int64) * step) % cols
    total = np.zeros(bins.shape, dtype=np.complex128)
    factor = 1.0
    for term in _power_terms(h_c, order):
        series = np.fft.fft(term.mean(axis=0)) / cols  # row 0 of fft2(term) / (H W)
        total = total + factor * series[bins]
        factor *= kw
    return np.abs(total) ** 2


def in_plane_uvw(theta_i_deg, theta_r_deg):
    """(u, v, w) = k̂1 − k̂2 for light towards θ_i and viewer towards θ_r in the xz-plane (module docstring)."""
    ti, tr = np.radians(theta_i_deg), np.radians(theta_r_deg)
    u = -(np.sin(ti) + np.sin(tr))
    w = -(np.cos(ti) + np.cos(tr))
    return u, np.zeros_like(u), w


def grating_peaks(
    terms: TaylorTerms,
    wavelength_um: float,
    theta_i_deg: float,
    *,
    theta_r_deg=None,
    threshold: float = 1e-6,
) -> tuple[np.ndarray, np.ndarray]:
    """Angles θ_r (degrees) and powers of the local maxima of relative_power along the xz-plane (v = 0).

    Geometry of the module docstring: peaks satisfy sin θ_r = m λ / d − sin θ_i. theta_r_deg is the
    sampling grid (default −89.9°..89.9° every 0.01°); maxima above threshold are refined by a parabola
    through the log power of the three samples around them (exact for a Gaussian peak).
    """
    grid = np.arange(-89.9, 89.9 + 1e-9, 0.01) if theta_r_deg is None else np.asarray(theta_r_deg, float)
    k = 2 * math.pi / wavelength_um
    u, v, w = in_plane_uvw(theta_i_deg, grid)
    power = relative_power(terms, k * u, k * v, k * w)
    inner = (power[1:-1] > power[:-2]) & (power[1:-1] >= power[2:]) & (power[1:-1] > threshold)
    idx = np.nonzero(inner)[0] + 1
    lo, mid, hi = (np.log(np.maximum(power[j], 1e-300)) for j in (idx - 1, idx, idx + 1))
    denom = lo - 2 * mid + hi
    shift = np.where(denom < 0, 0.5 * (lo - hi) / np.where(denom < 0, denom, -1.0), 0.0)
    shift = np.clip(shift, -0.5, 0.5)
    step = np.interp(idx + 0.5, np.arange(len(grid)), grid) - np.interp(idx - 0.5, np.arange(len(grid)), grid)
    angles = grid[idx] + shift * step
    return angles, power[idx]


def _reduced_phase(alpha, period):
    phase = np.asarray(alpha, np.float64) * float(period)
    return np.remainder(phase + np.pi, 2 * np.pi) - np.pi  # in [−π, π)


def _dirichlet(phase, count):
    """D = sin(N φ/2) / sin(φ/2) for reduced phases φ, with the series N(1 − (N²−1) φ²/24) near φ = 0."""
    n = float(count)
    small = np.abs(phase) * n < 1e-4
    safe = np.where(small, 1.0, phase)
    d = np.sin(n * safe / 2) / np.sin(safe / 2)
    return np.where(small, n * (1 - (n * n - 1) * phase * phase / 24), d)


def periodic_sum(alpha, period: float, count: int) -> np.ndarray:
    """Σ_{n=0}^{N-1} e^{−i α n T} = p + i q in closed form (Single §2.7, N = count copies of period T)."""
    if count < 1:
        raise ValueError(f"count must be at least 1, got {count}")
    phase = _reduced_phase(alpha, period)
    d = _dirichlet(phase, count)
    half = (count - 1) * phase / 2
    return d * np.cos(half) - 1j * d * np.sin(half)


def periodic_factor(alpha, period: float, count: int) -> np.ndarray:
    """The tiling gain |Σ_{n=0}^{N-1} e^{−i α n T}|² = sin²(N α T / 2) / sin²(α T / 2); N² at α T = 2π j."""
    if count < 1:
        raise ValueError(f"count must be at least 1, got {count}")
    return _dirichlet(_reduced_phase(alpha, period), count) ** 2


def periodic_factor_2d(alpha, beta, period_x: float, period_y: float, count_x: int, count_y: int):
    """|(p1 + i q1)(p2 + i q2)|² with the corrected product (p1 p2 − q1 q2) + i (p1 q2 + q1 p2) (§2.7)."""
    s1 = periodic_sum(alpha, period_x, count_x)
    s2 = periodic_sum(beta, period_y, count_y)
    p1, q1, p2, q2 = s1.real, s1.imag, s2.real, s2.imag
    re = p1 * p2 - q1 * q2
    im = p1 * q2 + q1 * p2
    return re * re + im * im
