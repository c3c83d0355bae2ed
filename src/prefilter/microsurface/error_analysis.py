"""Error of the Gaussian approximation of the slope filtering distribution: Heitz et al. 2014 §8, Fig. 14.

The filtered colour of a colour map on slopes is C̄ = ⟨C, D_s⟩ (eq. 18 / 29), with the view-dependent
distribution of visible slopes (projected-area weighting, §5.2; masking is a height term, factored out)

    D_s(s) ∝ (o_z − s·o_xy)⁺ p_s(s),
    s = ∇h, facet normal ∝ (−s, 1), o = (sin θ_o cos φ_o, sin θ_o sin φ_o, cos θ_o), φ_o = 0 by default
    (the view tilts along x, the colour-mapped slope component).

`exact` is that inner product over every facet (pixel) of a sampled periodic surface (a quadrature over
the surface, i.e. the histogram of D_s with one sample per facet). `gaussian` replaces D_s by the Gaussian
G = N(m, Σ) with the same mean and covariance as the exact D_s (the approximation behind the
preconvolved maps, eq. 30), so only the *shape* of D_s is approximated. The colour maps are 1D cosines on
the x component of the slope,

    C_k(s_x) = ½ + ½ cos(2π k s_x / s_ref),
    ⟨C_k, N(m, v)⟩ = ½ + ½ cos(2π k m / s_ref) exp(−2π² k² v / s_ref²),

with k in cycles per s_ref, s_ref = the standard deviation of s_x over the surface (area-weighted, not
view-weighted). Matching mean and variance makes k = 0 and any affine colour map exact (eq. 31); the
error |exact − gaussian| is relative to the colour range [0, 1] of C_k, as in the paper.

Surfaces (`surface_slopes`; all periodic, sampled at size × size pixel centres, slopes scaled so that
s_ref = slope_std, default 0.25):
  "gaussian"  Gaussian random field: white noise filtered by a Gaussian kernel of correlation_px = 2 px
              (FFT), slopes by exact spectral differentiation — Gaussian slope statistics (Fig. 13, top);
  "bumps"     a regular 8 × 8 grid of rounded bumps h = cos²(π d / 2r), r = 0.4 cell, on a flat floor
              (Fig. 13, bottom): an atom at s = 0 holding 1 − π 0.4² = 49.7 % of the area on a
              flat-topped spread to ±2.8 s_ref; the seed shifts the lattice by a random sub-cell offset;
  "gratings"  h = a (sin 2πx/L + sin 2πy/L), 8 periods: arcsine (bimodal) slope marginals;
              exact at normal view: ½ + ½ J0(2π k √2). The seed shifts the phase.
Frequencies default to 0 and 29 log-spaced values from 1/16 to 8 cycles per s_ref (DEFAULT_FREQUENCIES):
above k ≈ 1 the Gaussian answer is already the map's mean ½, and the interesting range is k ≲ 1.

Measured (max over k; size 1024, seed 0, slope_std 0.25): gaussian 0.14 % / 0.65 % / 4.1 % at θ_o =
0° / 60° / 75° (the infinite-surface limit by quadrature: 0 % / 0.55 % / 4.0 % — at grazing angles the
(o_z − s·o_xy)⁺ weight itself skews D_s away from a Gaussian; the rest is sampling noise, ≲ 0.15 %);
bumps 0.07 % at k = 1/16, 27–29 % at k ≈ 0.35, then ≈ 22–25 % (½ × the flat-floor atom) for k ≥ 1.

Run `python -m prefilter.microsurface.error_analysis out.png` for the table and the plot.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

SURFACES = ("gaussian", "bumps", "gratings")
DEFAULT_FREQUENCIES = np.concatenate([[0.0], 2.0 ** np.linspace(-4.0, 3.0, 29)])
DEFAULT_ANGLES = (0.0, 60.0, 75.0)
SLOPE_STD = 0.25
CORRELATION_PX = 2.0
BUMP_CELLS = 8
BUMP_RADIUS = 0.4  # in cells
GRATING_PERIODS = 8


def _rescale(sx: np.ndarray, sy: np.ndarray, slope_std: float) -> tuple[np.ndarray, np.ndarray]:
    scale = slope_std / float(np.std(sx))
    return sx * scale, sy * scale


def surface_slopes(
    surface: str, size: int = 1024, seed: int = 0, slope_std: float = SLOPE_STD
) -> tuple[np.ndarray, np.ndarray]:
    """Slopes (s_x, s_y) = ∇h, each (size, size) float64, of a periodic surface; std(s_x) = slope_std."""
    rng = np.random.default_rng(seed)
    if surface == "gaussian":
        f = np.fft.fftfreq(size)  # cycles per pixel
        fx, fy = f[None, :], f[:, None]
        spectrum = np.fft.fft2(rng.standard_normal((size, size)))
        spectrum *= np.exp(-2.0 * np.pi**2 * CORRELATION_PX**2 * (fx**2 + fy**2))
        dx = 2j * np.pi * np.where(np.abs(fx) == 0.5, 0.0, fx)  # the Nyquist bin has no derivative
        dy = 2j * np.pi * np.where(np.abs(fy) == 0.5, 0.0, fy)
        sx = np.fft.ifft2(spectrum * dx).real
        sy = np.fft.ifft2(spectrum * dy).real
        return _rescale(sx, sy, slope_std)
    offset = rng.uniform(0.0, 1.0, 2)  # lattice phase, in cells / periods
    t = (np.arange(size) + 0.5) / size
    if surface == "bumps":
        u = t[None, :] * BUMP_CELLS + offset[0]
        v = t[:, None] * BUMP_CELLS + offset[1]
        x, y = u - np.floor(u) - 0.5, v - np.floor(v) - 0.5  # position in the cell, cell units
        d = np.hypot(x, y)
        inside = d < BUMP_RADIUS
        # h = cos²(π d / 2r): dh/dd = −(π / 2r) sin(π d / r); ∇h = dh/dd · (x, y) / d
        dh = np.where(inside, -(np.pi / (2.0 * BUMP_RADIUS)) * np.sin(np.pi * d / BUMP_RADIUS), 0.0)
        safe = np.where(d > 0.0, d, 1.0)
        return _rescale(dh * x / safe, dh * y / safe, slope_std)
    if surface == "gratings":
        u = 2.0 * np.pi * (t * GRATING_PERIODS + offset[0])
        v = 2.0 * np.pi * (t * GRATING_PERIODS + offset[1])
        sx = np.broadcast_to(np.cos(u)[None, :], (size, size))
        sy = np.broadcast_to(np.cos(v)[:, None], (size, size))
        return _rescale(sx, sy, slope_std)
    raise ValueError(f"unknown surface {surface!r}; expected one of {', '.join(SURFACES)}")


def view_weights(sx: np.ndarray, sy: np.ndarray, theta_o_deg: float, phi_o_deg: float = 0.0) -> np.ndarray:
    """Projected area of each facet towards ω_o per unit horizontal area: (o_z − s·o_xy)⁺ (§5.2)."""
    theta, phi = np.radians(theta_o_deg), np.radians(phi_o_deg)
    o = np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)
    return np.maximum(o[2] - sx * o[0] - sy * o[1], 0.0)


def filter_exact(values: np.ndarray, weights: np.ndarray) -> float:
    """⟨C, D_s⟩ over the sampled facets: Σ w C / Σ w."""
    w = np.ravel(weights)
    return float(np.dot(w, np.ravel(values)) / w.sum())


def slope_moments(sx: np.ndarray, sy: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean (2,) and covariance (2, 2) of the exact D_s (the Gaussian approximation's parameters)."""
    w = np.ravel(weights) / np.ravel(weights).sum()
    s = np.stack([np.ravel(sx), np.ravel(sy)])
    mean = s @ w
    c = s - mean[:, None]
    return mean, (c * w) @ c.T


def colour_cosine(sx: np.ndarray, k: float, s_ref: float) -> np.ndarray:
    """C_k(s_x) = ½ + ½ cos(2π k s_x / s_ref): range [0, 1]."""
    return 0.5 + 0.5 * np.cos(2.0 * np.pi * k * np.asarray(sx) / s_ref)


def gaussian_cosine(k, mean: float, var: float, s_ref: float):
    """⟨C_k, N(mean, var)⟩ in closed form (the Gaussian's characteristic function)."""
    k = np.asarray(k, np.float64)
    a = 2.0 * np.pi * k / s_ref
    return 0.5 + 0.5 * np.cos(a * mean) * np.exp(-0.5 * a**2 * var)


def error_vs_frequency(
    surface: str,
    theta_o_deg: float,
    frequencies: np.ndarray = DEFAULT_FREQUENCIES,
    size: int = 1024,
    seed: int = 0,
    slope_std: float = SLOPE_STD,
    phi_o_deg: float = 0.0,
) -> dict:
    """Exact and Gaussian-approximated filtered C_k per frequency k (cycles per s_ref), and their error.

    Returns a dict of arrays over `frequencies`: "frequency", "exact", "gaussian", "error" (= |exact −
    gaussian|, relative to the colour range 1); and the scalars/arrays "mean" (2,), "covariance" (2, 2)
    of D_s, "s_ref", plus the inputs. Deterministic in (surface, size, seed, angles).
    """
    sx, sy = surface_slopes(surface, size, seed, slope_std)
    s_ref = float(np.std(sx))
    w = view_weights(sx, sy, theta_o_deg, phi_o_deg)
    mean, cov = slope_moments(sx, sy, w)
    freqs = np.asarray(frequencies, np.float64).ravel()
    exact = np.array([filter_exact(colour_cosine(sx, k, s_ref), w) for k in freqs])
    gaussian = gaussian_cosine(freqs, mean[0], cov[0, 0], s_ref)
    return {
        "surface": surface,
        "theta_o_deg": float(theta_o_deg),
        "phi_o_deg": float(phi_o_deg),
        "size": size,
        "seed": seed,
        "s_ref": s_ref,
        "mean": mean,
        "covariance": cov,
        "frequency": freqs,
        "exact": exact,
        "gaussian": gaussian,
        "error": np.abs(exact - gaussian),
    }


def _histogram_panel(ax, surface: str, angles, size: int, seed: int, slope_std: float) -> None:
    sx, sy = surface_slopes(surface, size, seed, slope_std)
    s_ref = float(np.std(sx))
    edges = np.linspace(-4.0, 4.0, 161)
    centres = 0.5 * (edges[1:] + edges[:-1])
    grid = np.linspace(-4.0, 4.0, 801)
    peak, spike, atom = 0.0, 0.0, 0.0
    for i, theta in enumerate(angles):
        w = view_weights(sx, sy, theta)
        mean, cov = slope_moments(sx, sy, w)
        hist, _ = np.histogram(sx.ravel() / s_ref, edges, weights=w.ravel(), density=True)
        m, sd = mean[0] / s_ref, np.sqrt(cov[0, 0]) / s_ref
        fit = np.exp(-0.5 * ((grid - m) / sd) ** 2) / (sd * np.sqrt(2.0 * np.pi))
        colour = f"C{i}"
        ax.step(centres, hist, where="mid", color=colour, lw=1.0, label=f"exact $D_s$, θ_o = {theta:g}°")
        ax.plot(grid, fit, color=colour, lw=1.2, ls="--", label=f"Gaussian fit, θ_o = {theta:g}°")
        peak = max(peak, fit.max())
        spike = max(spike, hist.max())
        atom = max(atom, float(w.ravel()[sx.ravel() == 0.0].sum() / w.sum()))
    top = 1.6 * peak
    ax.set_ylim(0.0, top)
    if spike > top:
        ax.annotate(
            f"flat floor: atom at $s_x$ = 0\nholding {100 * atom:.0f} % of $D_s$ (clipped)",
            xy=(0.0, top),
            xytext=(0.6, 0.85 * top),
            fontsize=7,
            arrowprops={"arrowstyle": "->", "lw": 0.7},
        )
    ax.set_xlim(-4.0, 4.0)
    ax.set_xlabel("$s_x$ / $s_{ref}$")
    ax.set_ylabel("density of $s_x$ under $D_s$")
    ax.legend(fontsize=6.5, loc="upper left")
    ax.grid(True, alpha=0.3)


def plot_error_vs_frequency(
    path,
    frequencies: np.ndarray = DEFAULT_FREQUENCIES,
    angles=DEFAULT_ANGLES,
    surfaces=("gaussian", "bumps"),
    size: int = 1024,
    seed: int = 0,
    slope_std: float = SLOPE_STD,
) -> dict:
    """Write Fig. 14 as a PNG (atomically): per surface, the x-slope marginal of D_s against its Gaussian
    fit (top) and the error |exact − gaussian| against k for each θ_o (bottom, log–log, k > 0).
    Returns {(surface, theta_o_deg): error_vs_frequency(...)}."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    results = {
        (surface, float(theta)): error_vs_frequency(surface, theta, frequencies, size, seed, slope_std)
        for surface in surfaces
        for theta in angles
    }
    titles = {
        "gaussian": "Gaussian surface (Gaussian slopes)",
        "bumps": "grid of rounded bumps (non-Gaussian slopes)",
        "gratings": "two sinusoid gratings (arcsine slopes)",
    }
    fig, axes = plt.subplots(2, len(surfaces), figsize=(5.2 * len(surfaces), 8.2), dpi=120, squeeze=False)
    for col, surface in enumerate(surfaces):
        _histogram_panel(axes[0, col], surface, (angles[0], angles[-1]), size, seed, slope_std)
        axes[0, col].set_title(titles.get(surface, surface), fontsize=10)
        ax = axes[1, col]
        for i, theta in enumerate(angles):
            r = results[(surface, float(theta))]
            keep = r["frequency"] > 0
            err = np.maximum(r["error"][keep], 1e-7) * 100.0
            label = f"θ_o = {theta:g}° (max {100 * r['error'].max():.2g} %)"
            ax.plot(r["frequency"][keep], err, marker="o", ms=2.5, color=f"C{i}", label=label)
        ax.axhline(1.0, color="0.4", ls=":", lw=1.0)
        ax.axhline(5.0, color="0.4", ls="--", lw=1.0)
        ax.text(r["frequency"][keep][0], 1.15, "1 %", fontsize=7, color="0.3")
        ax.text(r["frequency"][keep][0], 5.75, "5 %", fontsize=7, color="0.3")
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_ylim(1e-4, 100.0)
        ax.set_xlabel("colour-map frequency k (cycles per $s_{ref}$)")
        ax.set_ylabel("|exact − Gaussian| (% of colour range)")
        ax.set_title(f"error of $C_k$ = ½ + ½ cos(2πk $s_x$/$s_{{ref}}$), {size}² facets", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle(
        f"Gaussian approximation of the visible-slope distribution (Heitz et al. 2014 Fig. 14), "
        f"$s_{{ref}}$ = {slope_std:g}",
        fontsize=11,
    )
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp.png")
    try:
        fig.savefig(tmp)
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        tmp.unlink(missing_ok=True)
    return results


TABLE_FREQUENCIES = (1 / 16, 1 / 8, 1 / 4, 1 / 2, 1, 2, 8)


def main(argv: list[str] | None = None) -> int:
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m prefilter.microsurface.error_analysis", description=__doc__.split("\n")[0]
    )
    parser.add_argument("png", nargs="?", help="write the plot here")
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--slope-std", type=float, default=SLOPE_STD)
    args = parser.parse_args(argv)
    freqs = np.unique(np.concatenate([DEFAULT_FREQUENCIES, TABLE_FREQUENCIES]))
    surfaces = ("gaussian", "bumps")
    if args.png:
        results = plot_error_vs_frequency(
            args.png, freqs, DEFAULT_ANGLES, surfaces, args.size, args.seed, args.slope_std
        )
    else:
        results = {
            (s, t): error_vs_frequency(s, t, freqs, args.size, args.seed, args.slope_std)
            for s in surfaces
            for t in DEFAULT_ANGLES
        }
    head = "".join(f"{'k=' + (f'{k:g}' if k >= 1 else f'1/{round(1 / k)}'):>9}" for k in TABLE_FREQUENCIES)
    print(
        f"|exact - gaussian| in % of the colour range ({args.size}^2 facets, seed {args.seed}, "
        f"s_ref {args.slope_std:g})"
    )
    print(f"{'surface':<10}{'theta_o':>8}{head}{'max':>9}")
    for (surface, theta), r in results.items():
        cols = "".join(
            f"{100 * r['error'][np.argmin(np.abs(r['frequency'] - k))]:9.3f}" for k in TABLE_FREQUENCIES
        )
        print(f"{surface:<10}{theta:8g}{cols}{100 * r['error'].max():9.3f}")
    if args.png:
        print(f"wrote {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
