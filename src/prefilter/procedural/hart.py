"""Hart, Carr, Kameya, Tibbitts, Coleman 1999, "Antialiased parameterized solid texturing".

The model (eq. 1): p(s) = c(q(s) + sum_i a_i n(T_i s + o_i)), with
  q(s)  = s^T Q s, Q the symmetric 4x4 matrix of the 10 coefficients A..J of eq. (3)/(4)
          (q = As^2 + 2Bst + 2Csr + 2Ds + Et^2 + 2Ftr + 2Gt + Hr^2 + 2Ir + J);
  n     = Perlin's 2002 improved noise (glsl/common/noise.glsl), T_i a 3x3 matrix, o_i an offset that
          may move with animation time t (o_i + t v_i: the fire phase of eq. 8);
  c     = a colour table of n entries with a modulo or clamp flag (eq. 2, colormap/table.py).
Solid coordinates s are the object-space position mapped by `solidFromObject` (scale, offset).
Gradient (eqs. 10-12): df/ds = 2 (Q s)_xyz + sum_i a_i T_i^T dn(T_i s + o_i); the shader multiplies it by
the screen Jacobian ds/dx (dFdx/dFdy of s) to get the colour-table filter width |grad f| (section 3).
Beyond the paper, the filters are centred on an estimate of the pixel mean of f rather than on f at the
pixel centre (procedural/hart.glsl, pt_driverGradMean: the quadric's exact second-order shift, and per
noise term β n + κ τ with τ its analytic Taylor shift and β, κ from procedural/noise_stats.py).

Scene TOML (under [object.material], type = "hart"):
  quadric = [A, B, C, D, E, F, G, H, I, J]            default all zero
  solid_scale = 1.0 or [sx, sy, sz]; solid_offset = [x, y, z]
  [[object.material.noise]]  amplitude, scale (number or 3), matrix (3x3, overrides scale), offset, velocity
  [object.material.fractal]  octaves, first = 1, lacunarity = 2, gain = 0.5, amplitude = 1, scale, offset,
                             velocity: expands to terms amplitude*gain^i n(lacunarity^i scale*s + offset),
                             i = first .. first+octaves-1 (eqs. 6-8); each term's frequency scale and
                             amplitude at most 1e8 (noise.MAX_NOISE_SCALE)
  [object.material.colour_table]  wrap = "modulo"|"clamp", size = 256, interpolation = "linear"|"step",
                             stops = [[position, "#rrggbb" or "#rrggbbaa"], ...]
  [object.material.preconvolved]  size = [n_mu, n_sigma], sigma_max, mu_range (the gaussian mode's bake)
At most 8 noise terms (the paper's hardware limit).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import moderngl
import numpy as np

from prefilter.colormap.gaussian import parse_preconvolve_options, preconvolve
from prefilter.colormap.table import ColourTable, TableTextures, parse_colour_table
from prefilter.gl.uniforms import bind_samplers, set_uniforms
from prefilter.procedural.noise import (
    MAX_NOISE_SCALE,
    footprint_curvature,
    linear_noise_grad,
    perlin_noise_grad,
)
from prefilter.scene import Reader, register_material

MAX_TERMS = 8
REDUCED_TERMS = 4  # Hart §4.2: the reduced variant keeps the first (lowest-frequency) four terms
PACKAGE_ROOT = Path(__file__).resolve().parent.parent
SHADER_DIR = Path(__file__).resolve().parent

# Filtered modes of this technique, in the order reports list them. "hart-width" (Fig. 9c) is a
# visualisation of the filter width, not an appearance, so it is rendered but never scored.
FILTERED_MODES = ("hart-mip", "hart-sat", "hart-mip-aniso", "hart-sat-aniso", "gaussian")
DIAGNOSTIC_MODES = ("hart-width", "gaussian-sigma")


@dataclass
class NoiseTerm:
    amplitude: float
    matrix: np.ndarray  # T_i, 3x3
    offset: np.ndarray  # o_i
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # d o_i / dt

    def offset_at(self, t: float) -> np.ndarray:
        return self.offset + t * self.velocity


@dataclass
class HartResources:
    table: TableTextures
    gaussian_box: moderngl.Texture  # the preconvolved map, its rows integrated over μ (box-filtered reads)
    gaussian_range: tuple[float, float, float]  # (μ lo, μ hi, σ max) of the preconvolved map
    solid_extent: float  # max |s| over the mesh's bounding box (scale of the §4.3 quantisation)

    def release(self) -> None:
        self.table.release()
        self.gaussian_box.release()


@dataclass
class HartMaterial:
    quadric: np.ndarray  # Q, symmetric 4x4
    terms: list[NoiseTerm]
    table: ColourTable
    solid_from_object: np.ndarray  # 4x4 affine
    gaussian: dict = field(default_factory=dict)  # preconvolve() options (sigma_max, mu_range, sizes)

    kind = "hart"

    def modes(self) -> tuple[str, ...]:
        return FILTERED_MODES

    def diagnostic_modes(self) -> tuple[str, ...]:
        return DIAGNOSTIC_MODES

    # -- GPU -------------------------------------------------------------------------------------
    def shader_sources(self) -> tuple[Path, Path]:
        return PACKAGE_ROOT / "glsl/common/surface.vert", SHADER_DIR / "hart.frag"

    def defines(self, options) -> dict[str, object]:
        count = min(len(self.terms), REDUCED_TERMS) if options.reduced else len(self.terms)
        defines: dict[str, object] = {"PT_TERM_COUNT": count, "PT_WRAP": self.table.wrap_code}
        if options.reduced:
            defines["PT_REDUCED"] = True
        if options.first_order:
            defines["PT_FIRST_ORDER"] = True
        return defines

    def scaled(self, factor: float) -> HartMaterial:
        """The same material with its solid texture `factor` times finer (as if seen from that far)."""
        solid = self.solid_from_object.copy()
        solid[:3, :] *= factor
        return replace(self, solid_from_object=solid)

    def upload(self, ctx, mesh) -> HartResources:
        """Colour tables go up premultiplied: filtering must average premultiplied colour."""
        table = self.table.premultiplied()
        gaussian = preconvolve(table, **self.gaussian)
        lo, hi = mesh.bounds()
        corners = np.array(
            [[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        )
        extent = float(np.abs(corners @ self.solid_from_object.T)[:, :3].max())
        return HartResources(
            table.upload(ctx),
            gaussian.upload_box(ctx),
            (*gaussian.mu_range, gaussian.sigma_max),
            extent,
        )

    def release(self, resources: HartResources) -> None:
        resources.release()

    def bind(self, prog, resources: HartResources, t: float, options) -> None:
        textures = resources.table
        bind_samplers(
            prog,
            {
                "u_tablePoint": textures.point,
                "u_tableMip": textures.mip,
                "u_tableSat": textures.sat,
                "u_tableGaussianBox": resources.gaussian_box,
            },
        )
        bits = options.quant_bits  # Hart §4.3: B bits over the object's solid-coordinate extent
        terms = self.terms[: self.defines(options)["PT_TERM_COUNT"]]
        values: dict[str, object] = {
            "u_gaussianRange": resources.gaussian_range,
            "u_solidFromObject": self.solid_from_object.T,
            "u_quantStep": 2.0 * resources.solid_extent / 2.0**bits if bits else 0.0,
            "pt_quadric": self.quadric.T,
        }
        if terms:
            values["pt_noiseMatrix"] = np.stack([term.matrix.T for term in terms])
            values["pt_noiseOffset"] = np.stack([term.offset_at(t) for term in terms])
            values["pt_noiseAmplitude"] = np.array([term.amplitude for term in terms])
        set_uniforms(prog, values)

    def driver(self, s: np.ndarray, t: float = 0.0, reduced_terms: int | None = None, linear: bool = False):
        """NumPy float64 reference of f(s) and df/ds (eqs. 1, 10-12); s has shape (..., 3)."""
        s = np.asarray(s, dtype=np.float64)
        s4 = np.concatenate([s, np.ones(s.shape[:-1] + (1,))], axis=-1)
        qs = s4 @ self.quadric  # Q symmetric
        f = np.einsum("...i,...i->...", s4, qs)
        grad = 2.0 * qs[..., :3]
        noise_grad = linear_noise_grad if linear else perlin_noise_grad
        for term in self.terms[: reduced_terms or len(self.terms)]:
            p = s @ term.matrix.T + term.offset_at(t)
            value, dn = noise_grad(p)
            f = f + term.amplitude * value
            grad = grad + term.amplitude * (dn @ term.matrix)
        return f, grad


def driver_gaussian(
    material: HartMaterial, s: np.ndarray, dsdx: np.ndarray, dsdy: np.ndarray, t: float = 0.0
):
    """NumPy twin of pt_driverGaussian: (μ, σ_lin², σ_res²) of f over box footprints spanned by dsdx, dsdy
    (the shader returns the gradient (g_x, g_y) whose box variance is σ_lin²)."""
    from prefilter.procedural.noise_stats import noise_stats, split_fit, split_fits

    stats = noise_stats()
    fits = split_fits()
    s = np.asarray(s, np.float64)
    s4 = np.concatenate([s, np.ones(s.shape[:-1] + (1,))], axis=-1)
    qs = s4 @ material.quadric
    q = material.quadric[:3, :3]
    shift = sum(np.einsum("...i,ij,...j->...", d, q, d) for d in (dsdx, dsdy)) / 12.0
    mu = np.einsum("...i,...i->...", s4, qs) + shift
    grad = 2.0 * qs[..., :3]
    residual = np.zeros(s.shape[:-1])
    for term in material.terms:
        jx, jy = dsdx @ term.matrix.T, dsdy @ term.matrix.T
        beta, kappa, gamma, lam = split_fit(fits, np.linalg.norm(jx, axis=-1), np.linalg.norm(jy, axis=-1))
        p = s @ term.matrix.T + term.offset_at(t)
        value, dn = perlin_noise_grad(p)
        tau = footprint_curvature(p, jx, jy) / 24.0
        mu = mu + term.amplitude * (beta * value + kappa * tau)
        grad = grad + term.amplitude * gamma[..., None] * (dn @ term.matrix)
        residual = residual + term.amplitude**2 * lam
    gx = np.einsum("...i,...i->...", grad, dsdx)
    gy = np.einsum("...i,...i->...", grad, dsdy)
    return mu, (gx**2 + gy**2) / 12.0, residual * stats.variance


def quadric_matrix(coefficients: np.ndarray) -> np.ndarray:
    """Eq. (4): the symmetric matrix of q = As^2 + 2Bst + 2Csr + 2Ds + Et^2 + 2Ftr + 2Gt + Hr^2 + 2Ir + J."""
    a, b, c, d, e, f, g, h, i, j = coefficients
    return np.array([[a, b, c, d], [b, e, f, g], [c, f, h, i], [d, g, i, j]], dtype=np.float64)


def _matrix_from(r: Reader) -> np.ndarray:
    if r.has("matrix"):
        return r.matrix("matrix", 3, 3)
    return np.diag(r.vector("scale", 3, default=[1.0, 1.0, 1.0]))


@register_material("hart")
def parse_hart(r: Reader, base_dir: Path) -> HartMaterial:
    quadric = quadric_matrix(r.vector("quadric", 10, default=[0.0] * 10))
    solid = np.eye(4)
    solid[:3, :3] = np.diag(r.vector("solid_scale", 3, default=[1.0, 1.0, 1.0]))
    solid[:3, 3] = r.vector("solid_offset", 3, default=[0.0, 0.0, 0.0])
    terms: list[NoiseTerm] = []
    for nr in r.children("noise"):
        terms.append(
            NoiseTerm(
                amplitude=nr.number("amplitude", 1.0),
                matrix=_matrix_from(nr),
                offset=nr.vector("offset", 3, default=[0.0, 0.0, 0.0]),
                velocity=nr.vector("velocity", 3, default=[0.0, 0.0, 0.0]),
            )
        )
        nr.finish()
    fr = r.child("fractal")
    if fr is not None:
        octaves = fr.integer("octaves", 4, lo=1, hi=MAX_TERMS)
        first = fr.integer("first", 1, lo=-16, hi=16)
        lacunarity = fr.number("lacunarity", 2.0, lo=1e-3)
        gain = fr.number("gain", 0.5)
        amplitude = fr.number("amplitude", 1.0)
        base = _matrix_from(fr)
        offset = fr.vector("offset", 3, default=[0.0, 0.0, 0.0])
        velocity = fr.vector("velocity", 3, default=[0.0, 0.0, 0.0])
        for i in range(first, first + octaves):
            terms.append(NoiseTerm(amplitude * gain**i, lacunarity**i * base, offset.copy(), velocity.copy()))
            if not lacunarity**i * np.abs(base).max() <= MAX_NOISE_SCALE:
                raise fr.fail("lacunarity", f"octave {i}'s frequency scale exceeds {MAX_NOISE_SCALE:.0e}")
            if not abs(amplitude * gain**i) <= MAX_NOISE_SCALE:
                raise fr.fail("gain", f"octave {i}'s amplitude exceeds {MAX_NOISE_SCALE:.0e}")
        fr.finish()
    if len(terms) > MAX_TERMS:
        raise r.fail("noise", f"at most {MAX_TERMS} noise terms (noise + fractal octaves), got {len(terms)}")
    tr = r.child("colour_table", required=True)
    assert tr is not None
    table = parse_colour_table(tr)
    return HartMaterial(quadric, terms, table, solid, parse_preconvolve_options(r.child("preconvolved")))
