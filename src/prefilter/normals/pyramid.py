"""Pyramids of normal distributions (Fournier 1992 §2.4) with filtered horizon statistics (§5).

Level l of the pyramid has ceil(W / 2^l) x ceil(H / 2^l) texels; texel (i, j) stands for the block of
base texels [i 2^l, (i+1) 2^l) x [j 2^l, (j+1) 2^l) (clipped at the map's edge, so any size works). Each
texel stores the distribution of the normals of ALL the base texels below it, "computed not from the
preceding level but from the bottom level": either exactly (at most K distinct normals, Fournier §2.3)
or as K Phong peaks fitted to the spread of the base normals (normals/peaks.py). The unfiltered renderer
(and so the reference) interpolates normals bilinearly between texel centres (Fournier §3), so the
spread that is fitted is that of the reconstructed field, not of the texel centres alone: each base
texel contributes the normals of the bilinear field at 2 x 2 points (±1/4 texel) of its area, each a
Phong lobe of the base exponent. (Spreading the centres alone over-weights the extreme normals of a map
whose features span few texels: the pyramid then shows highlights the surface does not have.) The
spread of a block is linear in its texels, so the spread of a texel above a bake tile is the
count-weighted mean of its tiles' spreads — the same numbers as spreading the base texels again; the
fit itself always starts from that bottom-level spread, never from the peaks of the level below.

Horizons (§5, Fig. 12): each base texel has the slopes of its horizon towards +X, -X, +Y, -Y
(normals/horizon.py). Each peak "collects" the mean and standard deviation of these limiting slopes over
the base texels of its block, each texel weighted by the peak's responsibility for its normal,
a_i lobe_i(N_t) / sum_j a_j lobe_j(N_t) (Fournier weights by cos^n alone; the responsibility keeps two
overlapping peaks from counting the same texel twice). Exact peaks take their own texels' statistics.

Baking runs as tiles of T x T base texels on Dask (`scheduler`: None = local processes for maps of
128x128 and more, else in-process; "synchronous" / "threads" / "processes"; or the address of a running
distributed scheduler). Tiles are pure functions of their inputs and are cached one by one (bake_cache),
so an interrupted bake resumes and every scheduler gives the same bytes.

Per texel, level l: peaks (K, 5) float32 = (direction xyz, amplitude, exponent), amplitude 0 = unused,
sorted by decreasing amplitude; horizon (K, 8) float32 = mean (+X, -X, +Y, -Y), std (+X, -X, +Y, -Y).
"""

from __future__ import annotations

import math
import resource
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from prefilter import PrefilterError
from prefilter.bake_cache import cached_arrays
from prefilter.normals.horizon import horizon_slopes
from prefilter.normals.normal_maps import SurfaceMap
from prefilter.normals.peaks import HemisphereGrid, exact_peaks, fit_peaks, lobe

PYRAMID_VERSION = 4  # bump when the bake's results change (4: the compiled Levenberg–Marquardt of peaks.py)


@dataclass(frozen=True)
class PyramidOptions:
    exponent: float = 100.0  # Phong exponent of each base normal's lobe (the spread's reconstruction filter)
    max_peaks: int = 7  # K
    rms_tolerance: float = 0.05  # stop adding peaks when residual RMS < this x data RMS ...
    max_tolerance: float = 0.05  # ... and max |residual| < this x max data
    n_theta: int = 18  # hemisphere sampling of the spread (Fournier: every 5 degrees)
    n_phi: int = 72
    pole_cap_degrees: float = 5.0 / 12.0
    horizon_distance: int | None = None  # horizon search radius in texels (None: horizon.py's default)
    tile: int = 32  # bake tile side in base texels (a power of two)
    # which blocks are stored exactly: "texels" (Fournier: at most K distinct base normals) or "field"
    # (at most K distinct normals of the bilinear field point renders: exact where point is; slower)
    exact: str = "texels"

    def grid(self) -> HemisphereGrid:
        return HemisphereGrid(self.n_theta, self.n_phi, self.pole_cap_degrees)


@dataclass
class LevelReport:
    level: int
    size: tuple[int, int]
    texels: int
    exact: int
    fitted: int
    peaks_mean: float
    peaks_max: int
    rms_ratio_mean: float
    rms_ratio_max: float
    max_ratio_max: float
    over_tolerance: int  # fitted texels that reached K peaks without meeting both tolerances


@dataclass
class BakeReport:
    seconds: float = 0.0
    scheduler: str = ""
    tiles: int = 0
    tiles_from_cache: int = 0
    peak_rss_mb: float = 0.0
    pyramid_mb: float = 0.0
    levels: list[LevelReport] = field(default_factory=list)

    def as_dict(self) -> dict:
        return asdict(self)

    def lines(self) -> list[str]:
        out = [
            f"built in {self.seconds:.1f} s on {self.scheduler} ({self.tiles} tiles, "
            f"{self.tiles_from_cache} from cache); pyramid {self.pyramid_mb:.1f} MB, "
            f"peak memory {self.peak_rss_mb:.0f} MB",
            "level  size        texels   exact  fitted  peaks mean/max  rms ratio mean/max  max ratio"
            "  over tol",
        ]
        for r in self.levels:
            out.append(
                f"{r.level:5d}  {r.size[0]:4d}x{r.size[1]:<5d} {r.texels:7d} {r.exact:7d} {r.fitted:7d}"
                f"  {r.peaks_mean:6.2f} / {r.peaks_max:d}     "
                f"{r.rms_ratio_mean:7.3f} / {r.rms_ratio_max:5.3f}"
                f"      {r.max_ratio_max:6.3f}  {r.over_tolerance:6d}"
            )
        return out


@dataclass
class NormalPyramid:
    sizes: list[tuple[int, int]]  # (w, h) per level
    peaks: list[np.ndarray]  # (h, w, K, 5) float32 per level
    horizon: list[np.ndarray] | None  # (h, w, K, 8) float32 per level, or None without a height map
    rms_ratio: list[np.ndarray]  # (h, w) float32: 0 where exact
    max_ratio: list[np.ndarray]
    options: PyramidOptions
    report: BakeReport = field(default_factory=BakeReport)
    # per level: every texel holds the same peaks (the map tiles with a period of the level's block)
    alike: list[bool] = field(default_factory=list)

    @property
    def max_peaks(self) -> int:
        return self.options.max_peaks

    def nbytes(self) -> int:
        arrays = self.peaks + (self.horizon or [])
        return sum(a.nbytes for a in arrays)


def level_sizes(width: int, height: int) -> list[tuple[int, int]]:
    sizes = [(width, height)]
    while sizes[-1] != (1, 1):
        w, h = sizes[-1]
        sizes.append(((w + 1) // 2, (h + 1) // 2))
    return sizes


# -- one texel -------------------------------------------------------------------------------------------
def _horizon_stats(horizons: np.ndarray, responsibility: np.ndarray) -> np.ndarray:
    """(K, 8): responsibility-weighted mean and std of the base horizons for each peak."""
    total = responsibility.sum(axis=0)  # (K,)
    safe = np.where(total > 0, total, 1.0)
    mean = (responsibility.T @ horizons) / safe[:, None]  # (K, 4)
    var = (responsibility.T @ horizons**2) / safe[:, None] - mean**2
    out = np.zeros((responsibility.shape[1], 8))
    out[:, :4] = mean
    out[:, 4:] = np.sqrt(np.maximum(var, 0.0))
    out[total <= 0] = 0.0
    return out


def _pack(found, horizons_stats, options: PyramidOptions) -> tuple[np.ndarray, np.ndarray]:
    k = options.max_peaks
    order = np.argsort(-np.asarray(found.amplitudes), kind="stable")
    peaks = np.zeros((k, 5), np.float32)
    n = len(order)
    peaks[:n, :3] = np.asarray(found.directions)[order]
    peaks[:n, 3] = np.asarray(found.amplitudes)[order]
    peaks[:n, 4] = np.asarray(found.exponents)[order]
    horizon = np.zeros((k, 8), np.float32)
    if horizons_stats is not None:
        horizon[:n] = horizons_stats[order]
    return peaks, horizon


def texel_peaks(
    normals: np.ndarray,
    horizons: np.ndarray | None,
    options: PyramidOptions,
    grid: HemisphereGrid,
    values: np.ndarray,
    candidates: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Peaks (K, 5), horizon statistics (K, 8), rms and max residual ratios for one block of base normals.

    `values` is the block's spread on `grid` (of the reconstructed field; see the module header). When at
    most K of the `candidates` normals (equally weighted) are distinct they are the exact answer;
    otherwise the spread is fitted.
    """
    m = len(normals)
    weights = np.full(m, 1.0 / m)
    c = len(candidates)
    found = exact_peaks(candidates, np.full(c, 1.0 / c), options.exponent, options.max_peaks)
    if found is not None:
        stats = None
        if horizons is not None:  # each exact peak owns the base texels with its normal
            dirs = np.asarray(found.directions)
            owner = np.argmax(normals @ dirs.T, axis=1)
            responsibility = np.zeros((m, len(dirs)))
            responsibility[np.arange(m), owner] = weights
            stats = _horizon_stats(horizons, responsibility)
        peaks, horizon = _pack(found, stats, options)
        return peaks, horizon, 0.0, 0.0
    found = fit_peaks(
        values,
        grid,
        max_peaks=options.max_peaks,
        rms_tolerance=options.rms_tolerance,
        max_tolerance=options.max_tolerance,
    )
    stats = None
    if horizons is not None:
        dirs = np.asarray(found.directions)
        density = np.asarray(found.amplitudes)[None, :] * lobe(normals @ dirs.T, np.asarray(found.exponents))
        total = density.sum(axis=1, keepdims=True)
        nearest = np.zeros_like(density)
        nearest[np.arange(m), np.argmax(normals @ dirs.T, axis=1)] = 1.0
        responsibility = np.where(total > 0, density / np.where(total > 0, total, 1.0), nearest)
        stats = _horizon_stats(horizons, responsibility * weights[:, None])
    peaks, horizon = _pack(found, stats, options)
    return peaks, horizon, float(found.rms_ratio), float(found.max_ratio)


# -- tiles -----------------------------------------------------------------------------------------------
def _tile_levels(options: PyramidOptions) -> int:
    return int(round(math.log2(options.tile)))


def bake_tile(padded: np.ndarray, horizons: np.ndarray | None, options: PyramidOptions) -> dict:
    """Levels 0 .. log2(T) of one tile and the tile's spread. `padded` is the tile's (h + 2, w + 2, 3)
    block of base normals with a one-texel periodic border (for the bilinear reconstruction).

    Pure and cached: the same block and options give the same arrays on any scheduler.
    """
    arrays = (padded,) if horizons is None else (padded, horizons)
    params = {"version": PYRAMID_VERSION, **asdict(options)}
    return cached_arrays("nd-tile", params, arrays, lambda: _bake_tile(padded, horizons, options))


def reconstructed_normals(padded: np.ndarray) -> np.ndarray:
    """(h, w, 4, 3): the bilinear normal field at (±1/4, ±1/4) texel around each centre, normalised.

    `padded` is the (h + 2, w + 2, 3) block with a one-texel (periodic) border.
    """
    h, w = padded.shape[0] - 2, padded.shape[1] - 2
    centre = padded[1:-1, 1:-1]
    out = []
    for dy in (-1, 1):
        for dx in (-1, 1):
            across = padded[1 : 1 + h, 1 + dx : 1 + dx + w]
            along = padded[1 + dy : 1 + dy + h, 1 : 1 + w]
            diagonal = padded[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
            v = 0.5625 * centre + 0.1875 * (across + along) + 0.0625 * diagonal
            out.append(v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12))
    return np.stack(out, axis=2)


def texel_spreads(field: np.ndarray, exponent: float, grid: HemisphereGrid) -> np.ndarray:
    """(h, w, S): the spread over each base texel's area of the reconstructed field (h, w, 4, 3)."""
    h, w = field.shape[:2]
    out = np.empty((h, w, grid.size))
    for row in range(h):  # a row at a time bounds the memory
        c = field[row].reshape(-1, 3) @ grid.directions.T
        out[row] = lobe(c, exponent).reshape(w, 4, -1).mean(axis=1)
    return out


def _bake_tile(padded: np.ndarray, horizons: np.ndarray | None, options: PyramidOptions) -> dict:
    grid = options.grid()
    normals = padded[1:-1, 1:-1]
    h, w = normals.shape[:2]
    k = options.max_peaks
    reconstructed = reconstructed_normals(padded)
    spreads = texel_spreads(reconstructed, options.exponent, grid)
    out: dict[str, np.ndarray] = {}
    for level in range(_tile_levels(options) + 1):
        step = 1 << level
        lh, lw = -(-h // step), -(-w // step)
        peaks = np.zeros((lh, lw, k, 5), np.float32)
        horizon = np.zeros((lh, lw, k, 8), np.float32)
        ratios = np.zeros((lh, lw, 2), np.float32)
        if level == 0:  # one normal per texel: its own exact peak
            peaks[..., 0, :3] = normals
            peaks[..., 0, 3] = 1.0
            peaks[..., 0, 4] = options.exponent
            if horizons is not None:
                horizon[..., 0, :4] = horizons
        else:
            for j in range(lh):
                for i in range(lw):
                    rows, cols = slice(j * step, (j + 1) * step), slice(i * step, (i + 1) * step)
                    block = normals[rows, cols].reshape(-1, 3)
                    hblock = None if horizons is None else horizons[rows, cols].reshape(-1, 4)
                    values = spreads[rows, cols].mean(axis=(0, 1))
                    candidates = block
                    if options.exact == "field":
                        candidates = reconstructed[rows, cols].reshape(-1, 3)
                    p, hz, rms, mx = texel_peaks(block, hblock, options, grid, values, candidates)
                    peaks[j, i], horizon[j, i], ratios[j, i] = p, hz, (rms, mx)
        out[f"peaks{level}"] = peaks
        out[f"horizon{level}"] = horizon
        out[f"ratios{level}"] = ratios
    out["spread"] = spreads.mean(axis=(0, 1))
    out["count"] = np.array([h * w])
    return out


def bake_upper_texel(
    normals: np.ndarray,
    horizons: np.ndarray | None,
    tile_spreads: np.ndarray,
    tile_counts: np.ndarray,
    options: PyramidOptions,
) -> dict:
    """One texel above the tiles: its spread is the count-weighted mean of its tiles' spreads (cached)."""

    def compute() -> dict:
        values = (tile_counts[:, None] * tile_spreads).sum(axis=0) / tile_counts.sum()
        flat = normals.reshape(-1, 3)
        hflat = None if horizons is None else horizons.reshape(-1, 4)
        peaks, horizon, rms, mx = texel_peaks(flat, hflat, options, options.grid(), values, flat)
        return {"peaks": peaks, "horizon": horizon, "ratios": np.array([rms, mx], np.float32)}

    arrays = (normals, tile_spreads, tile_counts) + (() if horizons is None else (horizons,))
    params = {"version": PYRAMID_VERSION, **asdict(options)}
    return cached_arrays("nd-upper", params, arrays, compute)


# -- the whole pyramid -----------------------------------------------------------------------------------
def _can_spawn() -> bool:
    """Spawned worker processes re-import __main__: impossible from stdin or an interactive session."""
    import sys

    main = getattr(sys.modules.get("__main__"), "__file__", None)
    return main is not None and Path(main).is_file()


def _compute(tasks: list, scheduler: str | None, progress: bool, n_texels: int) -> tuple[list, str]:
    import dask

    if scheduler is not None and "://" in scheduler:
        try:
            from distributed import Client
            from distributed import progress as cluster_progress
        except ImportError as exc:
            raise PrefilterError(
                f"--scheduler {scheduler}: dask.distributed is not installed ({exc})"
            ) from None
        try:
            client = Client(scheduler, timeout=10)
        except OSError as exc:
            raise PrefilterError(
                f"--scheduler {scheduler}: cannot reach the Dask scheduler ({exc})"
            ) from None
        with client:
            futures = client.compute(tasks)
            if progress:
                cluster_progress(futures)
            return client.gather(futures), f"distributed {scheduler}"
    if scheduler is None:
        scheduler = "processes" if n_texels >= 128 * 128 and _can_spawn() else "synchronous"
    if scheduler not in ("synchronous", "threads", "processes"):
        raise PrefilterError(
            f"scheduler {scheduler!r}: expected synchronous, threads, processes or a tcp:// address"
        )
    kwargs = {"scheduler": scheduler}
    if scheduler != "synchronous":
        kwargs["num_workers"] = 2
    if progress:
        from dask.diagnostics import ProgressBar

        with ProgressBar():
            return list(dask.compute(*tasks, **kwargs)), f"local {scheduler}"
    return list(dask.compute(*tasks, **kwargs)), f"local {scheduler}"


def _is_cached(normals: np.ndarray, horizons: np.ndarray | None, options: PyramidOptions) -> bool:
    from prefilter.bake_cache import cache_dir, input_hash

    arrays = (normals,) if horizons is None else (normals, horizons)
    params = {"version": PYRAMID_VERSION, **asdict(options)}
    return (cache_dir() / f"nd-tile-{input_hash('nd-tile', params, arrays)}.npz").is_file()


def build_pyramid(
    surface: SurfaceMap,
    options: PyramidOptions | None = None,
    scheduler: str | None = None,
    progress: bool = False,
) -> NormalPyramid:
    """Bake the pyramid of `surface` (normals, and horizons when it has heights); see the module header."""
    import dask

    options = options or PyramidOptions()
    if options.tile < 2 or options.tile & (options.tile - 1):
        raise PrefilterError(f"tile = {options.tile}: must be a power of two >= 2")
    start = time.perf_counter()
    normals = np.ascontiguousarray(surface.normals, dtype=np.float64)
    horizons = None
    if surface.heights is not None:
        horizons = horizon_slopes(surface.heights, options.horizon_distance)
    h, w = normals.shape[:2]
    sizes = level_sizes(w, h)
    t = options.tile
    tiles_y, tiles_x = -(-h // t), -(-w // t)
    blocks = [(ty, tx) for ty in range(tiles_y) for tx in range(tiles_x)]

    def tile_slice(a, ty, tx):
        return None if a is None else np.ascontiguousarray(a[ty * t : (ty + 1) * t, tx * t : (tx + 1) * t])

    def padded_slice(ty, tx):  # the tile and a one-texel border, wrapping around the map's edges
        rows = np.arange(ty * t - 1, min((ty + 1) * t, h) + 1) % h
        cols = np.arange(tx * t - 1, min((tx + 1) * t, w) + 1) % w
        return np.ascontiguousarray(normals[np.ix_(rows, cols)])

    from_cache = sum(
        _is_cached(padded_slice(ty, tx), tile_slice(horizons, ty, tx), options) for ty, tx in blocks
    )
    tile_tasks = [
        dask.delayed(bake_tile, pure=True)(padded_slice(ty, tx), tile_slice(horizons, ty, tx), options)
        for ty, tx in blocks
    ]
    pending = (len(blocks) - from_cache) * t * t  # texels still to bake
    tiles, used = _compute(tile_tasks, scheduler, progress, pending)

    k = options.max_peaks
    tile_levels = min(_tile_levels(options), len(sizes) - 1)
    peaks, horizon, rms, mxr = [], [], [], []
    for lw, lh in sizes:
        peaks.append(np.zeros((lh, lw, k, 5), np.float32))
        horizon.append(np.zeros((lh, lw, k, 8), np.float32))
        rms.append(np.zeros((lh, lw), np.float32))
        mxr.append(np.zeros((lh, lw), np.float32))
    for (ty, tx), tile in zip(blocks, tiles, strict=True):
        for level in range(tile_levels + 1):
            step = t >> level
            p = tile[f"peaks{level}"]
            y0, x0 = ty * step, tx * step
            peaks[level][y0 : y0 + p.shape[0], x0 : x0 + p.shape[1]] = p
            horizon[level][y0 : y0 + p.shape[0], x0 : x0 + p.shape[1]] = tile[f"horizon{level}"]
            r = tile[f"ratios{level}"]
            rms[level][y0 : y0 + p.shape[0], x0 : x0 + p.shape[1]] = r[..., 0]
            mxr[level][y0 : y0 + p.shape[0], x0 : x0 + p.shape[1]] = r[..., 1]

    spreads = np.stack([tile["spread"] for tile in tiles]).reshape(tiles_y, tiles_x, -1)
    counts = np.array([tile["count"][0] for tile in tiles], float).reshape(tiles_y, tiles_x)
    upper, where = [], []
    for level in range(tile_levels + 1, len(sizes)):
        lw, lh = sizes[level]
        span = (1 << level) // t  # tiles per texel side at this level
        step = 1 << level
        for j in range(lh):
            for i in range(lw):
                ys, xs = slice(j * span, (j + 1) * span), slice(i * span, (i + 1) * span)
                block = (slice(j * step, (j + 1) * step), slice(i * step, (i + 1) * step))
                upper.append(
                    dask.delayed(bake_upper_texel, pure=True)(
                        np.ascontiguousarray(normals[block]),
                        None if horizons is None else np.ascontiguousarray(horizons[block]),
                        spreads[ys, xs].reshape(-1, spreads.shape[-1]),
                        counts[ys, xs].reshape(-1),
                        options,
                    )
                )
                where.append((level, j, i))
    if upper:
        results, _ = _compute(upper, scheduler, False, 0 if from_cache == len(blocks) else w * h)
        for (level, j, i), result in zip(where, results, strict=True):
            peaks[level][j, i] = result["peaks"]
            horizon[level][j, i] = result["horizon"]
            rms[level][j, i], mxr[level][j, i] = result["ratios"]

    alike = [False] * len(sizes)
    for level in range(1, len(sizes)):
        if _tiles_with_period(normals, horizons, 1 << level):
            alike[level] = True  # every block holds the same base texels: one fit serves them all
            peaks[level][:] = peaks[level][:1, :1]
            horizon[level][:] = horizon[level][:1, :1]
            rms[level][:], mxr[level][:] = rms[level][0, 0], mxr[level][0, 0]
    alike[-1] = True
    pyramid = NormalPyramid(sizes, peaks, horizon if horizons is not None else None, rms, mxr, options)
    pyramid.alike = alike
    usage = max(
        resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
        resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss,
    )
    pyramid.report = BakeReport(
        seconds=time.perf_counter() - start,
        scheduler=used,
        tiles=len(blocks),
        tiles_from_cache=int(from_cache),
        peak_rss_mb=usage / 1024.0,
        pyramid_mb=pyramid.nbytes() / 2**20,
        levels=[_level_report(level, pyramid) for level in range(len(sizes))],
    )
    return pyramid


def _tiles_with_period(normals: np.ndarray, horizons: np.ndarray | None, period: int) -> bool:
    """Whether the map repeats every `period` texels along both axes (so all blocks of that size match)."""
    h, w = normals.shape[:2]
    if h % period or w % period:
        return False
    for a in (normals, horizons):
        if a is None:
            continue
        for axis in (0, 1):
            if not np.allclose(np.roll(a, period, axis=axis), a, rtol=0.0, atol=1e-9):
                return False
    return True


def _level_report(level: int, pyramid: NormalPyramid) -> LevelReport:
    count = (pyramid.peaks[level][..., 3] > 0).sum(axis=-1)
    rms, mx = pyramid.rms_ratio[level], pyramid.max_ratio[level]
    fitted = (rms > 0) | (mx > 0)
    k = pyramid.max_peaks
    tol = pyramid.options
    over = fitted & (count >= k) & ((rms >= tol.rms_tolerance) | (mx >= tol.max_tolerance))
    w, h = pyramid.sizes[level]
    return LevelReport(
        level=level,
        size=(w, h),
        texels=w * h,
        exact=int((~fitted).sum()),
        fitted=int(fitted.sum()),
        peaks_mean=float(count.mean()),
        peaks_max=int(count.max()),
        rms_ratio_mean=float(rms[fitted].mean()) if fitted.any() else 0.0,
        rms_ratio_max=float(rms.max()),
        max_ratio_max=float(mx.max()),
        over_tolerance=int(over.sum()),
    )
