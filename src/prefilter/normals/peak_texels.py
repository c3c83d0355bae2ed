"""The texel of one Phong peak in the pyramid's atlas (Fournier 1992 §2.4, §5): plain, or bit-packed with
its horizon statistics.

A peak is (d.x, d.y, amplitude, exponent); with shadowing it also carries the mean and standard deviation
of its horizon slopes towards +X, -X, +Y, -Y: 12 numbers. On Mesa llvmpipe the texel fetches of a shaded
peak cost more than its shading: three RGBA32F fetches per peak (peak, means, deviations) took a third of
`multilobe`'s frame on the shadowed denim plane (docs/normals.md). So with shadowing each peak is one
texel of four bit-packed 32-bit words, read once. Without shadowing the texel is the plain float32
(d.x, d.y, amplitude, exponent): unpacking would only cost time there.

Packed: each word holds three unsigned fields, A (bits 0-10), B (bits 11-21) and C (bits 22-28), with bit
29 set and bits 30-31 clear, so its float32 exponent field lies in [64, 127]: every word is a normal,
finite, positive float. The texel survives float32 textures, EXR files and the viewer's Float32Array
uploads bit for bit (the viewer converts only LINEAR tables to half floats; this one is NEAREST), and
the shader reads it with floatBitsToUint.

    word   A (11 bits)        B (11 bits)          C (7 bits)
    0      d.x                d.y                  deviation +X
    1      amplitude          exponent             deviation -X
    2      mean +X            mean -X              deviation +Y
    3      mean +Y            mean -Y              deviation -Y

Codes: d.x, d.y = code / 1023 - 1 (0 exact, step 1e-3 rad at the pole); amplitude = code * a_step,
a_step = max(1, largest amplitude) / 2047; exponent: 1 + n as a float with 4 exponent and 7 mantissa
bits (the float32 bits 16-26 of 1 + n, rounded: integers up to 256 exact, 0.4 % at most, n <= 65534);
horizon means = lo + code * (hi - lo) / 2047 over the atlas' range; deviations = code * s_max / 127.
`decode` is the shader's nd_unpackPeak (normal_pyramid.glsl) in NumPy, for tests.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

A_MAX, B_MAX, C_MAX = 2047, 2047, 127
TAG = np.uint32(1 << 29)
ONE_BITS = 0x3F800000  # float32 1.0


@dataclass(frozen=True)
class PeakScales:
    """The atlas-wide steps of the packed codes: uniform nd_peakScales = (mean lo, mean step, deviation
    step, amplitude step)."""

    mean_lo: float = 0.0
    mean_step: float = 1.0
    std_step: float = 1.0
    amplitude_step: float = 1.0 / A_MAX

    def uniforms(self) -> dict[str, object]:
        return {"nd_peakScales": (self.mean_lo, self.mean_step, self.std_step, self.amplitude_step)}


def scales_for(amplitudes: np.ndarray, horizon: np.ndarray) -> PeakScales:
    """Steps whose codes cover every peak: amplitudes (...,), horizon (..., 8) (means, then deviations)."""
    lo, hi = float(horizon[..., :4].min(initial=0.0)), float(horizon[..., :4].max(initial=0.0))
    std = float(horizon[..., 4:].max(initial=0.0))
    top = max(1.0, float(np.max(amplitudes, initial=0.0)))
    return PeakScales(lo, max(hi - lo, 1e-6) / A_MAX, max(std, 1e-6) / C_MAX, top / A_MAX)


def _code(values: np.ndarray, top: int) -> np.ndarray:
    return np.clip(np.rint(values), 0, top).astype(np.uint32)


def _exponent_code(exponents: np.ndarray) -> np.ndarray:
    one_plus = np.clip(1.0 + np.maximum(np.asarray(exponents, np.float64), 0.0), 1.0, 65535.0)
    bits = one_plus.astype(np.float32).view(np.uint32).astype(np.int64)
    return np.clip((bits - ONE_BITS + (1 << 15)) >> 16, 0, B_MAX).astype(np.uint32)


def encode(
    directions_xy: np.ndarray,
    amplitudes: np.ndarray,
    exponents: np.ndarray,
    horizon: np.ndarray | None = None,
    scales: PeakScales | None = None,
) -> np.ndarray:
    """(..., 4) float32 texels of peaks with directions (..., 2) (x, y of unit vectors), amplitudes and
    exponents (...,). With horizon (..., 8) (means +X -X +Y -Y, then deviations) and its scales: packed."""
    if horizon is None:
        return np.concatenate(
            [directions_xy, np.asarray(amplitudes)[..., None], np.asarray(exponents)[..., None]], axis=-1
        ).astype(np.float32)
    assert scales is not None
    d = _code((np.asarray(directions_xy, np.float64) + 1.0) * 1023.0, A_MAX)
    a = _code(np.asarray(amplitudes, np.float64) / scales.amplitude_step, A_MAX)
    m = _code((np.asarray(horizon[..., :4], np.float64) - scales.mean_lo) / scales.mean_step, A_MAX)
    s = _code(np.asarray(horizon[..., 4:], np.float64) / scales.std_step, C_MAX)
    fields_a = np.stack([d[..., 0], a, m[..., 0], m[..., 2]], axis=-1)
    fields_b = np.stack([d[..., 1], _exponent_code(exponents), m[..., 1], m[..., 3]], axis=-1)
    words = TAG | fields_a | (fields_b << np.uint32(11)) | (s << np.uint32(22))
    return words.astype(np.uint32).view(np.float32)


def decode(texels: np.ndarray, scales: PeakScales | None = None) -> dict[str, np.ndarray]:
    """What nd_unpackPeak reads from texels (..., 4): direction (..., 3), amplitude, exponent and, from
    packed texels (scales given), horizon mean (..., 4) and deviation (..., 4)."""
    texels = np.ascontiguousarray(texels, np.float32)
    if scales is None:
        dxy = texels[..., :2].astype(np.float64)
        out = {"amplitude": texels[..., 2], "exponent": texels[..., 3]}
    else:
        q = texels.view(np.uint32)
        fa = (q & np.uint32(A_MAX)).astype(np.float64)
        fb = (q >> np.uint32(11)) & np.uint32(B_MAX)
        fc = ((q >> np.uint32(22)) & np.uint32(C_MAX)).astype(np.float64)
        fbf = fb.astype(np.float64)
        dxy = np.stack([fa[..., 0], fbf[..., 0]], axis=-1) / 1023.0 - 1.0
        mean = np.stack([fa[..., 2], fbf[..., 2], fa[..., 3], fbf[..., 3]], axis=-1)
        out = {
            "amplitude": fa[..., 1] * scales.amplitude_step,
            "exponent": ((fb[..., 1] << np.uint32(16)) + np.uint32(ONE_BITS)).view(np.float32) - 1.0,
            "mean": scales.mean_lo + mean * scales.mean_step,
            "deviation": fc * scales.std_step,
        }
    dz = np.sqrt(np.maximum(1.0 - (dxy**2).sum(-1), 0.0))
    return {"direction": np.concatenate([dxy, dz[..., None]], axis=-1), **out}
