"""Procedural microsurface height fields and their Gaussian statistics at each scale (Heitz 2014 §5, §9).

A microsurface displaces a macro surface (the xz-plane y = 0 with normal +y, or a sphere of radius R
about the origin, displaced radially) by a fractal sum of Perlin's improved noise:

    h(p) = Σ_k a_k n(f_k R_lat p + o_k),   a_k = amplitude · gain^k,  f_k = frequency · lacunarity^k,

evaluated at the macro-surface point p (object space). R_lat is a fixed rotation that tilts the plane off
the noise lattice's axes, so that the statistics of a plane section equal those of 3D noise. The same
`Fractal` also drives a material's procedural texture (C₀ of §6) and the height perturbation r of §5.1.

Statistics of the noise process (measured over uniform 3D points; `tests/test_microsurface.py` re-measures
them): Var n = NOISE_VARIANCE = 0.0731, and each component of ∇n has variance GRADIENT_VARIANCE = 0.50
(the improved noise's 12 gradient directions make the axes differ by ±4 %; we use the mean). So an octave
contributes a_k² Var n to σ_h² and a_k² f_k² GRADIENT_VARIANCE to each diagonal entry of the slope
covariance Σ (isotropic, zero mean).

Scale split over a pixel footprint (our choice; Heitz et al. leave it to the noise process): with β_k the
fraction of octave k that survives in the mean over the footprint (procedural/noise_stats.py, the box
footprint's axes measured in the octave's lattice units), the *coarse* surface h_c = Σ β_k a_k n_k is
rendered as real geometry (ray-marched), and the rest of each octave's variance, (1 − β_k²), becomes the
microsurface statistics σ_h² and Σ. β_k is β₁, the footprint's mean correlation with its centre: the heights
in the footprint spread about β₁ n(c) with variance (1 − β₁²)Var, so the split conserves each octave's
variance (tests/test_microsurface.py). Where the relief stands out of the pixel, the shader blends towards
the larger β of the split with a curvature term (heightfield.glsl, ms_meanFraction). Close up every
β_k = 1 (all geometry real); far away every β_k = 0 (all statistics), with a continuous transition.

Bounds used by the ray marcher: |n| < 0.99 (measured max 0.988) and |∇n| < 3.2 (measured max 3.17).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prefilter.procedural.noise import perlin_noise, perlin_noise_grad

NOISE_VARIANCE = 0.0731
GRADIENT_VARIANCE = 0.50
NOISE_BOUND = 1.0
MAX_OCTAVES = 8


def _rotation(ax: float, az: float) -> np.ndarray:
    cx, sx, cz, sz = np.cos(ax), np.sin(ax), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rx @ rz


LATTICE_FROM_OBJECT = _rotation(0.61, 0.43)


def octave_offset(k: int) -> np.ndarray:
    """o_k: a fixed, different lattice offset per octave (decorrelates octaves that share lattice points)."""
    return np.array([12.71, 3.37, 5.93]) * (k + 1) + np.array([0.0, 0.5, 0.0])


@dataclass(frozen=True)
class Fractal:
    octaves: int = 4
    amplitude: float = 0.05  # a_0, object units
    frequency: float = 4.0  # f_0, lattice cells per object unit
    gain: float = 0.5
    lacunarity: float = 2.0

    @property
    def amplitudes(self) -> np.ndarray:
        return self.amplitude * self.gain ** np.arange(self.octaves)

    @property
    def frequencies(self) -> np.ndarray:
        return self.frequency * self.lacunarity ** np.arange(self.octaves)

    def scaled(self, factor: float) -> Fractal:
        """The same surface seen `factor` times smaller: frequencies up, heights down (slopes kept)."""
        return Fractal(
            self.octaves, self.amplitude / factor, self.frequency * factor, self.gain, self.lacunarity
        )

    def octave_uniforms(self) -> tuple[np.ndarray, np.ndarray]:
        """(amplitude, frequency) pairs and offsets per octave, padded to MAX_OCTAVES."""
        pairs = np.zeros((MAX_OCTAVES, 2), np.float32)
        offsets = np.zeros((MAX_OCTAVES, 3), np.float32)
        pairs[: self.octaves, 0] = self.amplitudes
        pairs[: self.octaves, 1] = self.frequencies
        for k in range(self.octaves):
            offsets[k] = octave_offset(k)
        return pairs, offsets

    # -- NumPy twins (tests, statistics) ---------------------------------------------------------------
    def lattice_points(self, p: np.ndarray, k: int) -> np.ndarray:
        return self.frequencies[k] * (np.asarray(p, float) @ LATTICE_FROM_OBJECT.T) + octave_offset(k)

    def value(self, p: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
        w = np.ones(self.octaves) if weights is None else weights
        return sum(
            w[k] * self.amplitudes[k] * perlin_noise(self.lattice_points(p, k)) for k in range(self.octaves)
        )

    def gradient(self, p: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
        """∇h in object space (3D; project onto the macro tangent plane for slopes)."""
        w = np.ones(self.octaves) if weights is None else weights
        grad = np.zeros(np.shape(p))
        for k in range(self.octaves):
            _, g = perlin_noise_grad(self.lattice_points(p, k))
            grad += w[k] * self.amplitudes[k] * self.frequencies[k] * (g @ LATTICE_FROM_OBJECT)
        return grad

    def variance(self, residual: np.ndarray | None = None) -> float:
        """σ_h² of the octaves' residual fractions (all of them by default)."""
        r = np.ones(self.octaves) if residual is None else residual
        return float(np.sum(r * self.amplitudes**2) * NOISE_VARIANCE)

    def slope_variance(self, residual: np.ndarray | None = None) -> float:
        """Variance of each tangent slope component (Σ = slope_variance · I)."""
        r = np.ones(self.octaves) if residual is None else residual
        return float(np.sum(r * (self.amplitudes * self.frequencies) ** 2) * GRADIENT_VARIANCE)

    def height_bound(self) -> float:
        return float(np.sum(self.amplitudes) * NOISE_BOUND)
