"""Nanostructure height fields for diffraction shading: reading, writing, validating and generating them.

Stam 1999 ("Diffraction shaders") and Single 2013 (diffraction shader thesis draft, §2.3-2.4 and §4) shade
a surface from the Fourier transform of e^{i k w h(x, y)} over an explicitly given height field h: a
measured patch of snake skin or a grating. This module provides those height fields; the Taylor/FFT bake
subtracts the mean height first (DESIGN.md errata), see Nanostructure.centred().

Conventions
- Lengths (pixel sizes, heights, periods) are in micrometres (µm).
- Arrays are indexed [row, column] = [y, x]; sample (i, j) lies at (x, y) = (j·dx, i·dy), so row 0 is
  y = 0. Image files (PNG, EXR) store the top row first: readers flip rows so that the file's BOTTOM row
  becomes row 0, and writers flip them back. .npy arrays are stored as they are (row 0 first).
- Grooves of the gratings run along y: heights vary along x, and light disperses along x (the "across
  the grooves" direction is +x). The shader chooses the groove direction on the surface.
- Every generated field tiles periodically: its size is a whole number of periods (ridges), and the pixel
  is adjusted so that a whole number of pixels makes one period (pixel = period / round(period / pixel)).
- To resolve visible wavelengths (380-780 nm) the pixel must be at most MAX_PIXEL_UM = 0.1 µm.

Sources: Stam, "Diffraction Shaders", SIGGRAPH 1999; Single, "Diffraction Shader", thesis draft 2013
(/work/shared/papers); the generator parameters (blazed 2.5 µm / 0.246 µm, CD 1.6 µm, Elaphe ≈ 1.14 µm,
Xenopeltis ≈ 1.55 µm, ridge height ≈ 0.4 µm) are those of issue 6.
"""

from __future__ import annotations

import math
import os
import secrets
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from prefilter import PrefilterError
from prefilter.image_data import one_line, read_exr, read_png, write_exr
from prefilter.registry import call_registered

MAX_PIXEL_UM = 0.1  # coarsest pixel that resolves visible wavelengths
MIN_SIDE = 8  # smallest field, in pixels along each axis
MAX_SIDE = 8192  # largest generated field, in pixels along each axis
HEIGHTFIELD_EXTENSIONS = (".npy", ".png", ".exr")


@dataclass
class Nanostructure:
    """A height field: heights (H, W) float64 in µm, sampled every pixel = (dx, dy) µm; see the module doc."""

    heights: np.ndarray
    pixel: tuple[float, float]
    name: str

    @property
    def size_um(self) -> tuple[float, float]:
        """(W·dx, H·dy): the extent of one tile in µm."""
        return self.heights.shape[1] * self.pixel[0], self.heights.shape[0] * self.pixel[1]

    @property
    def height_range(self) -> float:
        """max − min of the heights in µm."""
        return float(self.heights.max() - self.heights.min())

    def centred(self) -> Nanostructure:
        """A copy with the mean height subtracted."""
        return replace(self, heights=self.heights - self.heights.mean())


# ------------------------------------------------------------------------------------------- validation


def _finite_positive(value, source: str, name: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if isinstance(value, bool) or not (math.isfinite(x) and x > 0.0):
        raise PrefilterError(f"{source}: {name} must be a positive number, got {value!r}")
    return x


def _pixel_pair(pixel_um, source: str) -> tuple[float, float]:
    """A pixel size given as one number (square pixels) or as (dx, dy)."""
    if isinstance(pixel_um, list | tuple | np.ndarray):
        if len(pixel_um) != 2:
            raise PrefilterError(f"{source}: pixel size must be one number or two (dx, dy), got {pixel_um!r}")
        dx = _finite_positive(pixel_um[0], source, "pixel dx")
        return dx, _finite_positive(pixel_um[1], source, "pixel dy")
    dx = _finite_positive(pixel_um, source, "pixel size")
    return dx, dx


def validate(structure: Nanostructure, source: str | os.PathLike) -> Nanostructure:
    """Check that the field is usable for diffraction (fine enough pixels, finite, at least 8x8).

    Raises PrefilterError naming `source` (a file or a generator); returns the structure.
    """
    h = structure.heights
    dx, dy = _pixel_pair(structure.pixel, str(source))
    for axis, d in (("", dx), (" (dy)", dy)) if dx != dy else (("", dx),):
        if d > MAX_PIXEL_UM:
            raise PrefilterError(
                f"{source}: pixel size{axis} {d:g} µm is too coarse to resolve visible wavelengths "
                f"(380–780 nm): it must be {MAX_PIXEL_UM:g} µm or finer"
            )
    if not isinstance(h, np.ndarray) or h.ndim != 2:
        raise PrefilterError(f"{source}: heights must be a 2D (H, W) array, got shape {np.shape(h)}")
    if h.shape[0] < MIN_SIDE or h.shape[1] < MIN_SIDE:
        raise PrefilterError(
            f"{source}: height field is {h.shape[1]}x{h.shape[0]} pixels; it must be at least "
            f"{MIN_SIDE}x{MIN_SIDE}"
        )
    bad = ~np.isfinite(h)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise PrefilterError(f"{source}: height field has NaN or Inf at x={col}, y={row} (row 0 is y = 0)")
    return structure


# ---------------------------------------------------------------------------------------- reading / writing


def _check_extension(path: Path, allowed: tuple[str, ...]) -> str:
    ext = path.suffix.lower()
    if ext not in allowed:
        raise PrefilterError(
            f"{path}: unsupported height field extension {ext or '(none)'!r}; use one of {', '.join(allowed)}"
        )
    return ext


def _read_npy(path: Path) -> np.ndarray:
    try:
        data = np.load(path, allow_pickle=False)
    except Exception as exc:  # ValueError, OSError, EOFError, pickle refusal ...
        raise PrefilterError(f"{path}: cannot read .npy ({one_line(exc)})") from None
    if not isinstance(data, np.ndarray):
        raise PrefilterError(f"{path}: expected a single 2D array in the .npy file")
    if data.ndim != 2:
        raise PrefilterError(f"{path}: expected a 2D (H, W) height array, got shape {data.shape}")
    if not (np.issubdtype(data.dtype, np.floating) or np.issubdtype(data.dtype, np.integer)):
        raise PrefilterError(f"{path}: expected a real-valued height array, got dtype {data.dtype}")
    return data.astype(np.float64)


def read_heightfield(path: str | os.PathLike, pixel_um, height_scale_um: float = 1.0) -> Nanostructure:
    """Read a height field: heights = height_scale_um × values, sampled every pixel_um (µm; or (dx, dy)).

    PNG (8/16-bit, first channel, scaled to [0, 1]) and EXR (first channel, as stored) have their rows
    flipped so that the file's bottom row is row 0 (y = 0); .npy holds a 2D array in row order. The result
    is validated (pixel at most 0.1 µm, finite, at least 8x8); all errors are PrefilterError naming the file.
    """
    path = Path(path)
    ext = _check_extension(path, HEIGHTFIELD_EXTENSIONS)
    pixel = _pixel_pair(pixel_um, str(path))
    scale = _finite_positive(height_scale_um, str(path), "height scale (µm)")
    if not path.is_file():
        raise PrefilterError(f"{path}: no such file")
    if ext == ".npy":
        values = _read_npy(path)
    else:
        data = read_png(path)[0] if ext == ".png" else read_exr(path)[0]
        first = data[:, :, 0]
        bad = ~np.isfinite(first)
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise PrefilterError(
                f"{path}: height field has NaN or Inf at pixel x={col}, y={row} (from the top-left corner)"
            )
        values = np.ascontiguousarray(first[::-1])
    structure = Nanostructure(scale * values, pixel, path.name)
    return validate(structure, path)


def write_heightfield(path: str | os.PathLike, structure: Nanostructure) -> Path:
    """Write the heights in µm to .npy (float64, row 0 first) or EXR (float32 channel "Y", bottom row last),
    atomically (a temporary file, then os.replace); read_heightfield(path, structure.pixel) reads it back."""
    path = Path(path)
    ext = _check_extension(path, (".npy", ".exr"))
    h = np.asarray(structure.heights, dtype=np.float64)
    if h.ndim != 2 or h.size == 0 or not np.isfinite(h).all():
        raise PrefilterError(f"{path}: expected finite (H, W) heights, got shape {h.shape}")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp{ext}")
    try:
        if ext == ".npy":
            with open(tmp, "wb") as f:
                np.save(f, np.ascontiguousarray(h), allow_pickle=False)
        else:
            write_exr(tmp, "Y", h[::-1])
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


# ------------------------------------------------------------------------------------------- generators


def _nonnegative(value, generator: str, name: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if isinstance(value, bool) or not (math.isfinite(x) and x >= 0.0):
        raise PrefilterError(f"{generator}: {name} must be a non-negative number, got {value!r}")
    return x


def _positive_int(value, generator: str, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise PrefilterError(f"{generator}: {name} must be a positive integer, got {value!r}")
    return int(value)


def _pixels_per(length: float, pixel: float) -> int:
    """Whole number of pixels closest to length / pixel; finer if rounding would exceed MAX_PIXEL_UM."""
    n = max(1, round(length / pixel))
    if length / n > MAX_PIXEL_UM >= pixel:
        n = math.ceil(length / MAX_PIXEL_UM)
    return n


def _grid(generator: str, side: int, pixel: float) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) of the samples of a square side x side field, each (side, side), in µm."""
    if side > MAX_SIDE:
        raise PrefilterError(
            f"{generator}: the field would be {side}x{side} pixels; at most {MAX_SIDE} per side "
            "(reduce the size or the number of periods)"
        )
    s = np.arange(side) * pixel
    return np.meshgrid(s, s)


def _periodic_profile(generator, period, periods, pixel, profile) -> tuple[np.ndarray, float]:
    """heights = profile(phase) with phase = x / period in [0, periods); a square field; and its pixel."""
    period = _finite_positive(period, generator, "period (µm)")
    periods = _positive_int(periods, generator, "periods")
    n = _pixels_per(period, _finite_positive(pixel, generator, "pixel (µm)"))
    x, _ = _grid(generator, n * periods, period / n)
    phase = np.round(x / (period / n)) / n  # exact multiples of 1/n: no rounding drift across the field
    return profile(phase), period / n


def sinusoidal(
    period: float = 1.6, amplitude: float = 0.1, periods: int = 16, pixel: float = 0.05
) -> Nanostructure:
    """A sinusoidal grating h = amplitude·sin(2πx/period) (peak-to-peak 2·amplitude), constant along y.

    periods × period µm along x, the same number of pixels along y (square pixels)."""
    gen = "sinusoidal"
    a = _nonnegative(amplitude, gen, "amplitude (µm)")
    heights, dx = _periodic_profile(gen, period, periods, pixel, lambda p: a * np.sin(2.0 * np.pi * p))
    name = f"sinusoidal(period={period:g}, amplitude={a:g}, periods={periods})"
    return validate(Nanostructure(heights, (dx, dx), name), gen)


def blazed(
    period: float = 2.5, height: float = 0.246, periods: int = 10, pixel: float = 0.05
) -> Nanostructure:
    """A blazed (sawtooth) grating h = height·frac(x/period): rising along +x, dropping by `height` at
    each groove edge. Sampled at x = j·dx with n pixels per period, the samples run 0 .. height·(n−1)/n."""
    gen = "blazed"
    h = _nonnegative(height, gen, "height (µm)")
    heights, dx = _periodic_profile(gen, period, periods, pixel, lambda p: h * (p - np.floor(p)))
    name = f"blazed(period={period:g}, height={h:g}, periods={periods})"
    return validate(Nanostructure(heights, (dx, dx), name), gen)


def cd_grooves(
    pitch: float = 1.6, depth: float = 0.11, periods: int = 16, pixel: float = 0.05, width: float = 0.5
) -> Nanostructure:
    """Straight CD-like grooves along y: land at h = 0, grooves of width `width`·pitch sunk to h = −depth,
    one per pitch along x, with edges smoothed over about one pixel (a smoothstep ramp)."""
    gen = "cd_grooves"
    d = _nonnegative(depth, gen, "depth (µm)")
    w = _finite_positive(width, gen, "width (fraction of the pitch)")
    if w >= 1.0:
        raise PrefilterError(f"cd_grooves: width (fraction of the pitch) must be below 1, got {width!r}")
    p = _finite_positive(pitch, gen, "pitch (µm)")
    step = p / _pixels_per(p, _finite_positive(pixel, gen, "pixel (µm)"))

    def profile(phase):
        distance = np.abs(phase - np.floor(phase) - 0.5) * p  # from the groove's centre line, µm
        s = np.clip((0.5 * w * p - distance) / step + 0.5, 0.0, 1.0)  # 1-pixel ramp centred on the edge
        return -d * s * s * (3.0 - 2.0 * s)

    heights, dx = _periodic_profile(gen, p, periods, pixel, profile)
    name = f"cd_grooves(pitch={p:g}, depth={d:g}, periods={periods}, width={w:g})"
    return validate(Nanostructure(heights, (dx, dx), name), gen)


def _ridges(gen: str, period, height, size, pixel, seed, waviness: float, wave_count: int) -> Nanostructure:
    """Quasi-periodic ridges running mostly along y (snake-scale nanostructure).

    n = round(size / period) ridges across a square tile of n·period µm; ridge spacings period·(1 + u) with
    u uniform in ±10 % (zero mean, so the tile is exactly n periods); the ridge lines are displaced along x
    by a periodic wave of amplitude `waviness`·period along y; each ridge has its own height, uniform in
    ±15 % of `height`, and a raised-cosine cross-section h = height_k·(1 + cos 2πt)/2, where t runs from
    one ridge centre (t integer) to the next (piecewise linear in x), so troughs are at h = 0 and the field
    is smooth (C¹) and periodic in both x and y.
    """
    period = _finite_positive(period, gen, "period (µm)")
    height = _nonnegative(height, gen, "height (µm)")
    size = _finite_positive(size, gen, "size (µm)")
    pixel = _finite_positive(pixel, gen, "pixel (µm)")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise PrefilterError(f"{gen}: seed must be an integer, got {seed!r}")
    count = max(2, round(size / period))
    tile = count * period
    side = _pixels_per(tile, pixel)
    dx = tile / side
    x, y = _grid(gen, side, dx)

    rng = np.random.default_rng(seed)
    jitter = rng.uniform(-0.1, 0.1, count)
    spacing = period * (1.0 + jitter - jitter.mean())
    centres = np.concatenate([[0.0], np.cumsum(spacing)[:-1]]) + rng.uniform(0.0, period)
    ridge_height = height * rng.uniform(0.85, 1.15, count)
    phases = rng.uniform(0.0, 2.0 * np.pi, 3)

    # Periodic waviness: a main wave along y (wave_count waves per tile) whose phase drifts slowly across x,
    # plus a weaker second harmonic; integer wave numbers keep the tile periodic.
    ty, tx = 2.0 * np.pi * y / tile, 2.0 * np.pi * x / tile
    shift = (
        waviness
        * period
        * (np.sin(wave_count * ty + tx + phases[0]) + 0.3 * np.sin(2 * wave_count * ty - tx + phases[1]))
    )
    xs = np.mod(x - shift - centres[0], tile)  # measured from the first ridge centre
    knots = np.concatenate([centres - centres[0], [tile]])
    t = np.interp(xs, knots, np.arange(count + 1))  # ridge coordinate: integer at ridge centres
    k = np.rint(t).astype(np.int64) % count
    heights = ridge_height[k] * 0.5 * (1.0 + np.cos(2.0 * np.pi * t))
    name = f"{gen}(period={period:g}, height={height:g}, size={tile:g}, seed={int(seed)})"
    return validate(Nanostructure(heights, (dx, dx), name), gen)


def elaphe(
    period: float = 1.14, height: float = 0.4, size: float = 25.6, pixel: float = 0.05, seed: int = 1
) -> Nanostructure:
    """Quasi-periodic ridges like the scales of Elaphe (ridge spacing ≈ 1.14 µm, height ≈ 0.4 µm); the
    tile is round(size / period) ridges wide and as tall (square)."""
    return _ridges("elaphe", period, height, size, pixel, seed, waviness=0.15, wave_count=2)


def xenopeltis(
    period: float = 1.55, height: float = 0.4, size: float = 25.6, pixel: float = 0.05, seed: int = 2
) -> Nanostructure:
    """Quasi-periodic ridges like the scales of Xenopeltis (ridge spacing ≈ 1.55 µm, height ≈ 0.4 µm);
    straighter ridges than elaphe."""
    return _ridges("xenopeltis", period, height, size, pixel, seed, waviness=0.1, wave_count=1)


GENERATORS = {
    "sinusoidal": sinusoidal,
    "blazed": blazed,
    "cd_grooves": cd_grooves,
    "elaphe": elaphe,
    "xenopeltis": xenopeltis,
}


def generate(name: str, **params) -> Nanostructure:
    """Call GENERATORS[name](**params); unknown generators and parameters raise PrefilterError."""
    return call_registered(GENERATORS, "nanostructure generator", name, params)
