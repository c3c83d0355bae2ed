"""Colour tables (Hart et al. 1999 §2.1.1) and their prefiltered forms (§3.3): MIP map and summed-area table.

What it computes
  A colour table c(f) maps a scalar index f (the output of a procedural texture) to linear RGB plus
  straight alpha. `ColourTable` bakes it from sRGB stops, builds Hart's colour-table MIP map (§3.3.1) and
  summed-area colour table (eqs. 13-15), uploads them as textures for colormap.glsl, and gives float64
  oracles (`point`, `box_average`, `trapezoid_average`) that the shader tests compare against.

Convention (the one parameterisation every lookup here and in colormap.glsl shares)
  - n entries (a power of two >= 2); entry i covers the index interval f in [i/n, (i+1)/n), so the
    table is a piecewise-constant function of f with one period per unit of f.
  - Point lookup, Hart eq. (2) `clut[round(n * wrap(f))]`: "round" is read as "nearest texel" with texel
    centres at (i + 0.5)/n, i.e.  c(f) = entries[floor(n * wrap(f))]  with wrap = fract (modulo) or a
    clamp to [0, 1] (clamp), and the index clamped to n - 1.
  - Outside [0, 1] the table repeats (modulo) or holds its edge entries clut[0] / clut[n-1] (clamp).
  - Filter widths w are in the same units as f: w = 1 is one whole table; w * n is the width in texels.
  - Colours are linear RGB; sRGB inputs are decoded once, here, with the IEC 61966-2-1 curve. Alpha is
    straight (not premultiplied) and is never gamma-decoded.

Premultiplied alpha
  Filtering must average premultiplied colour (rgb * alpha), otherwise transparent entries bleed their
  colour into their neighbours. Renderers upload `table.premultiplied()`, never the straight table.

Baked forms (parameters documented beside each method)
  - `mip_levels()`: level 0 is the table; level L+1 averages neighbour pairs of level L; the last level
    holds one entry, the mean of the table (Hart §3.3.1).
  - `summed_area()`: S with a leading zero, S[0] = 0, S[i+1] = S[i] + clut[i] (eq. 13, shifted by one
    so that S[i] is the integral of the table over [0, i] texels and no case needs csat[-1]).
  - `upload(ctx)` -> `TableTextures` with three textures (see that class for their layout).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import moderngl
import numpy as np

from prefilter import PrefilterError
from prefilter.gl.textures import float_texture
from prefilter.images import srgb_to_linear

WRAPS = ("modulo", "clamp")
WRAP_CODES = {"modulo": 0, "clamp": 1}  # the `wrapMode` argument of the cm_ functions in colormap.glsl
INTERPOLATIONS = ("linear", "step")

_HEX = re.compile(r"^#([0-9a-fA-F]{6}|[0-9a-fA-F]{8})$")


# --- sRGB --------------------------------------------------------------------------------------------


def parse_srgb(value: object) -> np.ndarray:
    """An sRGB colour '#rrggbb' / '#rrggbbaa' or a 3/4-sequence of floats in [0, 1] -> linear RGBA (4,).

    RGB is decoded to linear; alpha (default 1) is taken as is. Raises PrefilterError with one line.
    """
    expected = "expected an sRGB colour '#rrggbb', '#rrggbbaa' or [r, g, b(, a)] in [0, 1]"
    if isinstance(value, str):
        match = _HEX.match(value.strip())
        if not match:
            raise PrefilterError(f"{expected}, got {value!r}")
        digits = match.group(1)
        srgba = [int(digits[i : i + 2], 16) / 255.0 for i in range(0, len(digits), 2)]
    elif isinstance(value, Sequence | np.ndarray) and not isinstance(value, bytes):
        items = list(value)
        if len(items) not in (3, 4) or not all(
            isinstance(x, int | float | np.integer | np.floating) and not isinstance(x, bool) for x in items
        ):
            raise PrefilterError(f"{expected}, got {value!r}")
        srgba = [float(x) for x in items]
        if not all(0.0 <= x <= 1.0 for x in srgba):  # also rejects NaN
            raise PrefilterError(f"{expected}; a component of {value!r} is outside [0, 1]")
    else:
        raise PrefilterError(f"{expected}, got {value!r}")
    if len(srgba) == 3:
        srgba.append(1.0)
    rgba = np.empty(4, dtype=np.float64)
    rgba[:3] = srgb_to_linear(np.array(srgba[:3]))
    rgba[3] = srgba[3]
    return rgba


# --- the table ---------------------------------------------------------------------------------------


@dataclass
class TableTextures:
    """A colour table on the GPU, for colormap.glsl.

    point: n x 1 RGBA32F, NEAREST, no mips             -> cm_point (texelFetch)
    mip:   n x 1 RGBA32F, levels 0..log2(n) uploaded from `ColourTable.mip_levels()`,
           LINEAR_MIPMAP_LINEAR / LINEAR, repeat_x for modulo, clamp-to-edge for clamp
                                                      -> cm_mip, cm_mip2 (texelFetch, trilinear)
    sat:   (n+3) x 1 RGBA32F, LINEAR: texels 0..n hold the summed-area table S (leading zero), so the
           texture unit's linear filter at texel position x + 1/2 returns S(x), the exact integral of
           the piecewise-constant table over [0, x] texels; texels n+1 and n+2 hold clut[0] and clut[n-1]
           (the edge entries a clamp table extends with). One filtered fetch per footprint end keeps
           the lookup branch-free; float32 S gives ~3e-5 absolute error in sums of a 256-entry table,
           which cm_sat keeps small by never dividing by less than one texel.
                                                      -> cm_sat, cm_sat2 (textureLod, texelFetch)
    n: table size; wrap_code: 0 modulo, 1 clamp (the `wrapMode` argument of the cm_ functions).
    """

    point: moderngl.Texture
    mip: moderngl.Texture
    sat: moderngl.Texture
    n: int
    wrap_code: int

    def release(self) -> None:
        for texture in (self.point, self.mip, self.sat):
            texture.release()


@dataclass
class ColourTable:
    """n RGBA entries (float32, linear RGB + straight alpha) and a wrap mode, "modulo" or "clamp"."""

    entries: np.ndarray
    wrap: str = "modulo"

    def __post_init__(self) -> None:
        entries = np.ascontiguousarray(self.entries, dtype=np.float32)
        if entries.ndim != 2 or entries.shape[1] != 4:
            raise PrefilterError(f"colour table entries must have shape (n, 4), got {entries.shape}")
        _check_size(entries.shape[0])
        if not np.all(np.isfinite(entries)):
            raise PrefilterError("colour table entries must be finite")
        if self.wrap not in WRAPS:
            raise PrefilterError(f"wrap must be one of {', '.join(WRAPS)}, got {self.wrap!r}")
        self.entries = entries

    @property
    def n(self) -> int:
        return int(self.entries.shape[0])

    @property
    def wrap_code(self) -> int:
        return WRAP_CODES[self.wrap]

    # -- baking ---------------------------------------------------------------------------------------

    @classmethod
    def from_stops(
        cls,
        stops: Sequence[tuple[float, object]],
        n: int = 256,
        wrap: str = "modulo",
        interpolation: str = "linear",
    ) -> ColourTable:
        """Bake a table from (position in [0, 1], sRGB colour) stops, sampled at texel centres (i+0.5)/n.

        Colours are '#rrggbb', '#rrggbbaa' or 3/4-tuples of sRGB floats in [0, 1], decoded to linear
        once. "linear" interpolates linearly in linear RGB (and alpha) between neighbouring stops;
        "step" holds each stop's colour up to the next stop. Before the first stop and after the last
        the end colours hold. Equal positions are allowed and make a hard edge.
        """
        if wrap not in WRAPS:
            raise PrefilterError(f"wrap must be one of {', '.join(WRAPS)}, got {wrap!r}")
        if interpolation not in INTERPOLATIONS:
            raise PrefilterError(
                f"interpolation must be one of {', '.join(INTERPOLATIONS)}, got {interpolation!r}"
            )
        _check_size(n)
        try:
            stops = list(stops)
        except TypeError:
            raise PrefilterError(f"stops must be a list of (position, colour) pairs, got {stops!r}") from None
        if not stops:
            raise PrefilterError("at least one colour stop is needed")
        positions = np.empty(len(stops))
        colours = np.empty((len(stops), 4))
        for i, stop in enumerate(stops):
            if isinstance(stop, str | bytes) or not isinstance(stop, Sequence) or len(stop) != 2:
                raise PrefilterError(f"stops[{i}]: expected (position, colour), got {stop!r}")
            position, colour = stop
            if isinstance(position, bool) or not isinstance(position, int | float | np.integer | np.floating):
                raise PrefilterError(f"stops[{i}]: position must be a number, got {position!r}")
            if not 0.0 <= float(position) <= 1.0:
                raise PrefilterError(f"stops[{i}]: position {position} is outside [0, 1]")
            if i and float(position) < positions[i - 1]:
                raise PrefilterError(
                    f"stops[{i}]: positions must be sorted, {position} comes after {positions[i - 1]:g}"
                )
            positions[i] = float(position)
            try:
                colours[i] = parse_srgb(colour)
            except PrefilterError as exc:
                raise PrefilterError(f"stops[{i}]: {exc}") from None

        centres = (np.arange(n) + 0.5) / n
        upper = np.searchsorted(positions, centres, side="right")  # first stop strictly after the centre
        lower = np.clip(upper - 1, 0, len(stops) - 1)
        if interpolation == "step":
            entries = colours[lower]
        else:
            inside = (upper > 0) & (upper < len(stops))
            hi = np.clip(upper, 0, len(stops) - 1)
            span = np.where(inside, positions[hi] - positions[lower], 1.0)  # > 0 where inside
            t = np.where(inside, (centres - positions[lower]) / span, 0.0)
            entries = colours[lower] + t[:, None] * (colours[hi] - colours[lower])
        return cls(entries.astype(np.float32), wrap)

    def is_constant(self) -> bool:
        """Whether every entry is the same colour (any filter of the table returns that colour)."""
        return bool(np.all(self.entries == self.entries[0]))

    def premultiplied(self) -> ColourTable:
        """The same table with rgb * alpha (what renderers upload; filters average premultiplied colour)."""
        entries = self.entries.astype(np.float64)
        entries[:, :3] *= entries[:, 3:4]
        return ColourTable(entries.astype(np.float32), self.wrap)

    def mip_levels(self) -> list[np.ndarray]:
        """Hart's colour-table MIP map (§3.3.1): [level 0 (n,4), level 1 (n/2,4), ..., (1,4)], float64.

        Level L entry j is the mean of entries j*2^L .. (j+1)*2^L - 1: the box average of the table of
        width 2^L texels centred on that level's texel centre (j + 0.5) * 2^L / n.
        """
        levels = [self.entries.astype(np.float64)]
        while len(levels[-1]) > 1:
            prev = levels[-1]
            levels.append(0.5 * (prev[0::2] + prev[1::2]))
        return levels

    def summed_area(self) -> np.ndarray:
        """Hart's summed-area colour table (eq. 13) with a leading zero: (n+1, 4) float64.

        S[0] = 0, S[i+1] = S[i] + clut[i]; S[i] is the integral of the table over [0, i] texels and,
        the table being piecewise constant, linear interpolation of S is its exact integral anywhere.
        """
        sums = np.zeros((self.n + 1, 4), dtype=np.float64)
        np.cumsum(self.entries.astype(np.float64), axis=0, out=sums[1:])
        return sums

    def upload(self, ctx: moderngl.Context) -> TableTextures:
        """Upload the point, MIP and summed-area textures (layout in `TableTextures`)."""
        n = self.n
        limit = int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 0) or 0)
        if limit and n + 3 > limit:
            raise PrefilterError(
                f"colour table of {n} entries is too large for this GL (max texture {limit})"
            )
        point = float_texture(ctx, self.entries, filter=moderngl.NEAREST)

        levels = self.mip_levels()
        mip = ctx.texture((n, 1), 4, levels[0].astype(np.float32).tobytes(), dtype="f4")
        mip.build_mipmaps(0, len(levels) - 1)  # allocates every level; each is overwritten below
        for level, data in enumerate(levels[1:], 1):
            mip.write(np.ascontiguousarray(data, dtype=np.float32).tobytes(), level=level)
        mip.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        mip.repeat_x = self.wrap == "modulo"
        mip.repeat_y = False

        sat_texels = np.concatenate([self.summed_area(), self.entries[:1], self.entries[-1:]]).astype(
            np.float32
        )
        sat = float_texture(ctx, sat_texels)
        return TableTextures(point, mip, sat, n, self.wrap_code)

    # -- float64 oracles ------------------------------------------------------------------------------

    def point(self, f: np.ndarray | float) -> np.ndarray:
        """Hart eq. (2): entries[floor(n * wrap(f))], index clamped to n-1. Shape f.shape + (4,)."""
        f = np.asarray(f, dtype=np.float64)
        if self.wrap == "modulo":  # floor(n fract(f)) computed as floor(n f) mod n: exact, like the GLSL
            index = np.mod(np.floor(self.n * f), self.n).astype(np.int64)
        else:
            index = np.minimum(np.floor(self.n * np.clip(f, 0.0, 1.0)), self.n - 1).astype(np.int64)
        return self.entries[index].astype(np.float64)

    def integral(self, x: np.ndarray | float) -> np.ndarray:
        """Exact integral of the (wrapped) piecewise-constant table over [0, x], x in texels (x = n f)."""
        x = np.asarray(x, dtype=np.float64)
        n, sums = self.n, self.summed_area()
        entries = self.entries.astype(np.float64)
        if self.wrap == "modulo":
            periods = np.floor(x / n)
            r = x - periods * n
            k = np.minimum(np.floor(r), n - 1).astype(np.int64)
            return periods[..., None] * sums[n] + sums[k] + (r - k)[..., None] * entries[k]
        inside = np.clip(x, 0.0, float(n))
        k = np.minimum(np.floor(inside), n - 1).astype(np.int64)
        return (
            sums[k]
            + (inside - k)[..., None] * entries[k]
            + np.minimum(x, 0.0)[..., None] * entries[0]
            + np.maximum(x - n, 0.0)[..., None] * entries[n - 1]
        )

    def box_average(self, f: np.ndarray | float, w: np.ndarray | float) -> np.ndarray:
        """Exact mean of the wrapped table over [f - w/2, f + w/2] (w > 0, any size, any f): eq. (9)."""
        f, w = np.broadcast_arrays(np.asarray(f, np.float64), np.asarray(w, np.float64))
        if not np.all(w > 0.0):
            raise ValueError("box_average needs widths w > 0")
        if self.wrap == "modulo":
            f = f - np.floor(f)  # exact; keeps the sums small
        x, h = self.n * f, 0.5 * self.n * w
        return (self.integral(x + h) - self.integral(x - h)) / (2.0 * h)[..., None]

    def trapezoid_average(self, f: np.ndarray | float, wa: np.ndarray | float, wb: np.ndarray | float):
        """Exact mean of the table under the distribution of f + wa*u + wb*v, u, v ~ U(-1/2, 1/2).

        That distribution is box(|wa|) convolved with box(|wb|), a trapezoid; each texel is weighted by
        the trapezoid's probability mass over it (differences of its piecewise-quadratic CDF), so the
        result is exact up to float64 rounding. One NumPy pass per sample: for tests, not for images.
        """
        f, wa, wb = np.broadcast_arrays(*(np.asarray(v, np.float64) for v in (f, wa, wb)))
        n, entries = self.n, self.entries.astype(np.float64)
        out = np.empty(f.shape + (4,))
        for idx in np.ndindex(f.shape):
            a = 0.5 * n * max(abs(wa[idx]), abs(wb[idx]))  # half-widths in texels, a >= b
            b = 0.5 * n * min(abs(wa[idx]), abs(wb[idx]))
            if a == 0.0:
                out[idx] = self.point(f[idx])
                continue
            if self.wrap == "modulo":
                x = n * (f[idx] - np.floor(f[idx]))
                cells = np.arange(np.floor(x - a - b), np.floor(x + a + b) + 1.0)
                mass = _trapezoid_cdf(cells + 1.0 - x, a, b) - _trapezoid_cdf(cells - x, a, b)
                folded = np.bincount(np.mod(cells, n).astype(np.int64), weights=mass, minlength=n)
                out[idx] = folded @ entries
            else:
                x = n * f[idx]
                cells = np.arange(n, dtype=np.float64)
                mass = _trapezoid_cdf(cells + 1.0 - x, a, b) - _trapezoid_cdf(cells - x, a, b)
                mass[0] += _trapezoid_cdf(np.array([-x]), a, b)[0]
                mass[-1] += 1.0 - _trapezoid_cdf(np.array([n - x]), a, b)[0]
                out[idx] = mass @ entries
        return out


def _trapezoid_cdf(u: np.ndarray, a: float, b: float) -> np.ndarray:
    """CDF at u of U(-a, a) + U(-b, b), a >= b >= 0, a > 0 (piecewise quadratic, in [0, 1])."""
    v = -np.abs(u)  # evaluate on the left half, mirror for u > 0
    left = np.clip(0.5 + v / (2.0 * a), 0.0, 0.5)  # the flat top (and the whole CDF when b = 0)
    if b > 0.0:
        ramp = np.clip(v + a + b, 0.0, None) ** 2 / (8.0 * a * b)
        left = np.where(v < -(a - b), np.minimum(ramp, 0.5), left)
    return np.where(u > 0.0, 1.0 - left, left)


def _check_size(n: object) -> None:
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 2 or (int(n) & (int(n) - 1)):
        raise PrefilterError(f"colour table size must be a power of two >= 2, got {n!r}")


def parse_colour_table(r) -> ColourTable:
    """A [colour_table] scene table (a scene.Reader): wrap, size, interpolation, stops."""
    stops = r.raw("stops")
    if not isinstance(stops, list) or not stops:
        raise r.fail("stops", "expected a list of [position, colour] pairs")
    pairs = []
    for i, stop in enumerate(stops):
        if not (isinstance(stop, list) and len(stop) == 2 and isinstance(stop[0], int | float)):
            raise r.fail(f"stops[{i}]", f"expected [position, colour], got {stop!r}")
        pairs.append((float(stop[0]), stop[1]))
    # the keys' own errors name them; only what from_stops finds wrong is the stops'
    n = r.integer("size", 256, lo=2, hi=4096)
    try:
        _check_size(n)
    except PrefilterError as exc:
        raise r.fail("size", str(exc)) from None
    wrap = r.string("wrap", "modulo", choices=("modulo", "clamp"))
    interpolation = r.string("interpolation", "linear", choices=("linear", "step"))
    try:
        table = ColourTable.from_stops(pairs, n=n, wrap=wrap, interpolation=interpolation)
    except PrefilterError as exc:
        raise r.fail("stops", str(exc)) from None
    r.finish()
    return table
