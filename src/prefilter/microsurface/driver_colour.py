"""Height colours under a transfer function, filtered over the driver (beyond Heitz et al. 2014 §7).

Heitz et al. §7 take the heights h = g(f) of a transfer function as Gaussian, p_h ≈ N(E[g], E[g²] − E[g]²),
and filter the height colour C(h) over D_h of that Gaussian. The moss's and sponge's heights are far from it
(a flat ground or top holding a third to half of the surface, and tufts or pits beside it), and the colour
of that Gaussian misses the colour of the heights: for the sponge's driver N(0, 0.28²) the mean colour is
(0.52, 0.30, 0.065) and the Gaussian's (0.48, 0.24, 0.049), green 20 % low.

But g is increasing (g′ > 0 for every transfer function of transfer.py), so a height's rank among the
heights is its driver's rank among the drivers:
P_h(g(f)) = Φ((f − f̄)/σ_f). Smith's visibility V(h) = P_h(h)^Λ (eq. 2) holds for any height distribution,
so the heights that are seen and lit are g of the drivers that are seen and lit, and those are distributed
as D_h of the Gaussian driver: N(f̄ + μ_d(Λ) σ_f, σ_d(Λ)² σ_f²) with the μ_d, σ_d of §5.1 (the tables of
height_filtering.py; the coarse-and-micro split as for Gaussian reliefs, in driver units). Only Λ, from the
slopes of h, keeps §7's moments. The colour is then the composite K(f) = C(a · s · g(f) + b) (a, b the
height colour's scale and offset, s the transfer's scale) averaged over that Gaussian: a colour map over
the driver, preconvolved as any other (colormap/gaussian.py), read once (microsurface.frag,
ms_heightColour with MS_DRIVER_COLOUR). Measured there: far away the sponge's FLIP goes 0.214 -> 0.147
(24 units), the moss's 0.111 -> 0.096; at the presets' distances nothing changes.

The slopes are a mixture too (driver_slope_table; microsurface.frag, ms_driverNodes). ∇h = s g′(f) ∇f with
g′(f) and ∇f independent (transfer.py), so for one driver value the slopes are Gaussian, N(s g′(f) ∇f̄,
s² g′(f)² Σ_∇f) (∇f̄ the resolved driver gradient, Σ_∇f the unresolved one's covariance), and over the
driver a scale mixture of them: the sponge's flat top (g′ = 0) beside its steep walls. §7's one Gaussian
of the whole covariance gives every facet the average spread, and Lambert's cosine averaged over it is too
low under a high sun (flat facets keep n·l) and too high under a low one. A sample's slopes are taken as
two nodes of g′, g′± = E[g′] ± sd(g′) under its driver N(f̄, σ_f²) (the transfer table's moments: E[g′] and
E[g′²] are kept), each a Gaussian with its own visible slopes D_s (visible_slopes.py) and projected area
towards the eye, which weights it. The height colour goes with the nodes: K± = K̄ ± Cov(K, g′)/sd(g′) keeps
E[K] and Cov(K, g′) (the flat top is the sponge's yellow, the walls its red), with Cov(K, g′) = E[K g′] −
E[K] E[g′] over the same D_h as K̄ from a second table over the driver, (K(f) q(f), q(f)), q = g′/G,
preconvolved as K is. Each node's colour is lit by its own Lambert average, so the flat top's colour goes
with the flat top's share of the view and of the light. Measured (256 px, 64-spp references, FLIP of
surface-filter without -> with the nodes) on the sponge: 0.1473 -> 0.1018 at 24 units, 0.1372 -> 0.0968 at
14, 0.1320 -> 0.0978 at 11, 0.1084 -> 0.1005 at 8, 0.0982 -> 0.0966 at 6, 0.0839 -> 0.0838 at the preset's
4.28; on the moss 0.0958 -> 0.0970, 0.1020 -> 0.1057, 0.1020 -> 0.1041, 0.0993 -> 0.0994, 0.0930 ->
0.0930, 0.0792 -> 0.0793 (its flat ground is low, hidden and shadowed, and two nodes of g′ put it with the
tufts' flat tops). They cost 0.04 (moss) to 0.09 (sponge) × `naive`'s frame.

K is sampled into a clamp colour table over f in [−L, L], L = DRIVER_SPAN driver deviations of the whole
fractal (K is constant beyond: the flat ground or top on one side, the tallest tufts or deepest pits on the
other), entry i at f_i = −L + (i + 0.5) 2L / n (n = DRIVER_ENTRIES); the table's index u = (f + L) / 2L.
"""

from __future__ import annotations

import numpy as np

from prefilter.colormap.gaussian import PreconvolvedMap, preconvolve
from prefilter.colormap.table import ColourTable

DRIVER_SPAN = 6.0  # L in driver deviations σ_f of the whole fractal
DRIVER_ENTRIES = 4096
# the preconvolved rows: σ up to 3 σ_f (u units: 3 / 2·DRIVER_SPAN), stored over u in [-0.25, 1.25]
SIGMA_MAX = 3.0 / (2.0 * DRIVER_SPAN)
MU_RANGE = (-0.25, 1.25)


def _driver_grid(sigma_f: float) -> np.ndarray:
    """The tables' driver values f_i = −L + (i + 0.5) 2L / n, L = DRIVER_SPAN σ_f."""
    span = DRIVER_SPAN * sigma_f
    return -span + (np.arange(DRIVER_ENTRIES) + 0.5) * (2.0 * span / DRIVER_ENTRIES)


def driver_colour_table(
    colours: ColourTable, scale: float, offset: float, transfer, transfer_scale: float, sigma_f: float
) -> tuple[ColourTable, tuple[float, float]]:
    """K(f) = C(scale · transfer_scale · g(f) + offset) as a clamp table over f in [−L, L] (premultiplied as
    `colours` is given), and the affine map (a, b) from the driver f to the table's index u = a f + b."""
    f = _driver_grid(sigma_f)
    entries = colours.point(scale * transfer_scale * transfer.g(f) + offset)
    return ColourTable(entries.astype(np.float32), "clamp"), (1.0 / (2.0 * DRIVER_SPAN * sigma_f), 0.5)


def preconvolve_driver_colour(
    colours: ColourTable, scale: float, offset: float, transfer, transfer_scale: float, sigma_f: float
) -> tuple[PreconvolvedMap, tuple[float, float]]:
    """K̄(u, σ_u) baked (colormap/gaussian.py's clamp layout) and the map f -> u."""
    table, driver_map = driver_colour_table(colours, scale, offset, transfer, transfer_scale, sigma_f)
    return _bake(table), driver_map


def _bake(table: ColourTable) -> PreconvolvedMap:
    n_mu = int(round(2048 * (MU_RANGE[1] - MU_RANGE[0])))
    return preconvolve(table, n_mu=n_mu, n_sigma=128, sigma_max=SIGMA_MAX, mu_range=MU_RANGE)


def driver_slope_table(
    colours: ColourTable, scale: float, offset: float, transfer, transfer_scale: float, sigma_f: float
) -> tuple[ColourTable, float]:
    """(K(f).rgb q(f), q(f)) over driver_colour_table's grid, q = g′/G with G the largest g′ on the grid (so
    the entries stay within [0, 1]), and G · transfer_scale: q's unit in dh/df."""
    table, _ = driver_colour_table(colours, scale, offset, transfer, transfer_scale, sigma_f)
    slope = transfer.g_prime(_driver_grid(sigma_f))
    unit = float(np.max(slope))
    q = slope / unit
    entries = np.concatenate([table.entries[:, :3] * q[:, None], q[:, None]], axis=1)
    return ColourTable(entries.astype(np.float32), "clamp"), unit * transfer_scale


def preconvolve_driver_slopes(
    colours: ColourTable, scale: float, offset: float, transfer, transfer_scale: float, sigma_f: float
) -> tuple[PreconvolvedMap, float]:
    """driver_slope_table baked as preconvolve_driver_colour bakes K, and q's unit."""
    table, unit = driver_slope_table(colours, scale, offset, transfer, transfer_scale, sigma_f)
    return _bake(table), unit
