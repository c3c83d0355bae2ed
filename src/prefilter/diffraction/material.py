"""Diffraction material (type = "diffraction"): Stam's BRDF from a nanostructure's height field.

    structure = "file.npy|png|exr"  pixel_um = 0.05  height_scale_um = 1.0
    [generator] name = "sinusoidal|blazed|cd_grooves|elaphe|xenopeltis", other keys = its parameters
    grooves = "straight" | "circular"   groove_angle = 0 (degrees)   centre = [0.5, 0.5] (uv, circular)
    coherence_um = 16.25 (σ of the Gaussian window)   spectral_step_nm = 5   f0 = 1 (Schlick)
    epsilon = 1e-7 (Taylor truncation)   exposure = 1
    tiles = [Nx, Ny]: Single §2.7's periodic factor for Nx x Ny copies of the patch instead of the window
    dhillon_w0 = -1: the centre of the `dhillon` mode's expansion in w (0 is Dhillon et al.'s own)

Modes: `point` is the accurate path (diffraction/stam.glsl: Taylor/FFT transform, spectral loop), the
reference supersamples it; `fast` reads the spectrally preintegrated 3D table (diffraction/fast_table.py,
`fast_table = [257, 257, 33]` samples of u, v, w); `dhillon` sums Dhillon et al. 2014's 2N + 1 tables of
spectrally integrated cross terms by powers of w (diffraction/dhillon.py, on the same u, v grid); `naive`
is Stam's analytic grating shader with the structure's dominant period; `blinn-phong` is the timing
yardstick. The Taylor terms (diffraction/transform.py) and the tables are baked once and cached by content.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import moderngl
import numpy as np

from prefilter import PrefilterError
from prefilter.bake_cache import cached_arrays
from prefilter.diffraction.fast_table import DEFAULT_SIZE
from prefilter.diffraction.nanostructure import GENERATORS, Nanostructure, read_heightfield
from prefilter.diffraction.spectrum import spectral_weights
from prefilter.gl.uniforms import bind_samplers, set_uniforms
from prefilter.registry import call_from_table
from prefilter.scene import Reader, register_material

SHADER_DIR = Path(__file__).resolve().parent
PACKAGE_ROOT = SHADER_DIR.parent


def dominant_period(structure: Nanostructure) -> float:
    """The period (µm) of the strongest spatial frequency across the grooves (along x)."""
    row = (structure.heights - structure.heights.mean()).mean(axis=0)
    spectrum = np.abs(np.fft.rfft(row))
    spectrum[0] = 0.0
    index = int(np.argmax(spectrum))
    return structure.size_um[0] / max(index, 1)


@dataclass
class DiffractionMaterial:
    structure: Nanostructure
    circular: bool
    groove_angle: float  # radians
    centre: tuple[float, float]
    coherence: float  # µm
    spectral_step: float  # nm
    f0: float
    epsilon: float
    exposure: float
    table_size: tuple[int, int, int] = DEFAULT_SIZE  # the fast paths' u, v, w samples (fast_table.py)
    tiles: tuple[int, int] | None = None  # Single §2.7: the patch repeated (Nx, Ny) times, no window
    dhillon_w0: float = -1.0  # the `dhillon` mode's expansion centre in w (Dhillon et al.: 0)

    kind = "diffraction"

    def modes(self) -> tuple[str, ...]:
        return ("fast",) if self.tiles else ("fast", "dhillon")  # the tables are of the window, not tiles

    def diagnostic_modes(self) -> tuple[str, ...]:
        return ("blinn-phong",)

    def scaled(self, factor: float) -> DiffractionMaterial:
        return self  # a BRDF: nothing is mapped over the surface

    def shader_sources(self) -> tuple[Path, Path]:
        return PACKAGE_ROOT / "glsl/common/tangent_frame.vert", SHADER_DIR / "diffraction.frag"

    def stencil(self) -> int:
        """R of the shader's 2R x 2R bin stencil for this window and patch (transform.stencil_radius)."""
        from prefilter.diffraction.transform import stencil_radius

        h, w = self.structure.heights.shape
        dx, dy = self.structure.pixel
        return stencil_radius(self.coherence, (2 * math.pi / (w * dx), 2 * math.pi / (h * dy)))

    def horner_macro(self) -> str:
        """DF_HORNER(bin, kw) for stam.glsl: the Taylor sum at one bin, unrolled to this structure's order."""
        order = int(self.terms()["order"][0])
        expression = f"df_term(bin, {order})"
        for n in range(order - 1, -1, -1):
            expression = f"({expression} * (kw) + df_term(bin, {n}))"
        return expression

    def defines(self, options) -> dict[str, object]:
        defines: dict[str, object] = {
            "DF_STENCIL": self.stencil(),
            "DF_HORNER(bin, kw)": self.horner_macro(),
        }
        if self.circular:
            defines["DF_CIRCULAR"] = True
        if self.tiles is not None:
            defines["DF_TILING"] = True
        return defines

    def terms(self) -> dict[str, np.ndarray]:
        """The baked Taylor terms: coefficients (N+1, H, W) complex64 and the bin spacing (cached)."""
        from prefilter.diffraction.transform import taylor_terms

        s = self.structure

        def compute() -> dict[str, np.ndarray]:
            t = taylor_terms(s.heights, s.pixel, sigma=self.coherence, epsilon=self.epsilon)
            return {"coefficients": t.coefficients.astype(np.complex64), "order": np.array([t.order])}

        params = {"pixel": list(s.pixel), "sigma": self.coherence, "epsilon": self.epsilon, "version": 1}
        return cached_arrays("df-terms", params, (s.heights,), compute)

    def upload(self, ctx: moderngl.Context, mesh) -> dict:
        terms = self.terms()
        c = terms["coefficients"]
        layers, h, w = c.shape
        data = np.stack([c.real, c.imag], axis=-1).astype(np.float32)
        table = ctx.texture_array((w, h, layers), 2, np.ascontiguousarray(data).tobytes(), dtype="f4")
        table.filter = (moderngl.NEAREST, moderngl.NEAREST)
        wavelengths, weights = spectral_weights(self.spectral_step)
        spectrum = np.concatenate([weights, wavelengths[:, None]], axis=1).astype(np.float32)
        spectrum_tex = ctx.texture((len(wavelengths), 1), 4, spectrum.tobytes(), dtype="f4")
        spectrum_tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        dx, dy = self.structure.pixel
        uniforms = {
            "df_bins": (2 * math.pi / (w * dx), 2 * math.pi / (h * dy), float(w), float(h)),
            "df_sigma": self.coherence,
            "df_order": int(terms["order"][0]),
            "df_wavelengths": len(wavelengths),
            "df_f0": self.f0,
            "df_angle": self.groove_angle,
            "df_centre": self.centre,
            "df_period": dominant_period(self.structure),
            "u_exposure": self.exposure,
            "df_tiles": tuple(float(n) for n in (self.tiles or (1, 1))),
        }
        textures = {"df_terms": table, "df_spectrum": spectrum_tex}
        textures["df_table"] = self.fast_table(ctx)
        uniforms["df_tableSize"] = tuple(float(n) for n in self.table_size)
        if self.tiles is None:
            textures["df_dhillon"] = self.dhillon_tables(ctx)
            uniforms["df_dhillonCount"] = textures["df_dhillon"].size[2]
            uniforms["df_dhillonW0"] = self.dhillon_w0
        return {"textures": textures, "uniforms": uniforms}

    def fast_table(self, ctx: moderngl.Context) -> moderngl.Texture:
        """The fast path's 3D table (diffraction/fast_table.py), baked by FFTs and cached by content."""
        from prefilter.diffraction.fast_table import bake_fast_table

        s = self.structure
        params = {
            "pixel": list(s.pixel),
            "sigma": self.coherence,
            "step": self.spectral_step,
            "size": list(self.table_size),
            "tiles": list(self.tiles) if self.tiles else None,
            # 2: every bin of the window, no Taylor truncation (1: the shader's 2 x 2 bins); 3: the phasors
            # from float32 cosines and sines (the same table to within 1e-7 of each phasor); 4: real gridding
            # products, the DFT's second pass over the bins in reach only (the same to 1.2e-7 of the peak);
            # 5: each w-slice's phasors from the last one's by a float64 product (the same to 1.1e-7)
            "version": 5,
        }
        data = cached_arrays(
            "df-fast",
            params,
            (s.heights,),
            lambda: {
                "xyz": bake_fast_table(
                    s.heights, s.pixel, self.coherence, self.spectral_step, self.table_size, self.tiles
                )
            },
        )["xyz"]
        nu, nv, nw = self.table_size
        table = ctx.texture3d((nu, nv, nw), 4, np.ascontiguousarray(data, np.float32).tobytes(), dtype="f4")
        table.filter = (moderngl.LINEAR, moderngl.LINEAR)
        table.repeat_x = table.repeat_y = table.repeat_z = False
        return table

    def dhillon_tables(self, ctx: moderngl.Context) -> moderngl.TextureArray:
        """The `dhillon` mode's 2N + 1 XYZ tables over (u, v) (diffraction/dhillon.py), cached by content."""
        from prefilter.diffraction.dhillon import bake_dhillon_tables

        s = self.structure
        size = self.table_size[:2]
        params = {
            "pixel": list(s.pixel),
            "sigma": self.coherence,
            "step": self.spectral_step,
            "size": list(size),
            "w0": self.dhillon_w0,
            "epsilon": self.epsilon,
            "version": 1,
        }
        data = cached_arrays(
            "df-dhillon",
            params,
            (s.heights,),
            lambda: {
                "xyz": bake_dhillon_tables(
                    s.heights,
                    s.pixel,
                    self.coherence,
                    self.spectral_step,
                    size,
                    self.dhillon_w0,
                    self.epsilon,
                )
            },
        )["xyz"]
        count = data.shape[0]
        table = ctx.texture_array(
            (*size, count), 4, np.ascontiguousarray(data, np.float32).tobytes(), dtype="f4"
        )
        table.filter = (moderngl.LINEAR, moderngl.LINEAR)
        table.repeat_x = table.repeat_y = False
        return table

    def comparison_figures(self, out_dir: Path) -> list[str]:
        """`prefilter compare` extras: BRDF slices against the direct reference (not for tiled patches)."""
        from prefilter.diffraction.slices import slice_study, write_slice_figure

        study = slice_study(self)
        if study is None:
            return []
        write_slice_figure(study, out_dir / "brdf-slices.png")
        lines = [
            "## BRDF slices against the direct reference",
            "",
            "In-plane slices across the grooves; the reference sums e^(ikwh) under the",
            f"σ = {self.coherence:g} µm window directly, in {study['step_nm']:g} nm steps",
            "(diffraction/slices.py).",
            "",
            "| θ_i | mode | max error ÷ peak | mean ΔE2000 |",
            "|---:|---|---:|---:|",
        ]
        for entry in study["slices"]:
            for mode, err in entry["errors"].items():
                theta, error, delta_e = entry["theta_i"], err["max_relative"], err["mean_delta_e"]
                lines.append(f"| {theta:g}° | {mode} | {error:.4f} | {delta_e:.2f} |")
        return lines + ["", "![BRDF slices](brdf-slices.png)", ""]

    def release(self, resources: dict) -> None:
        for texture in resources["textures"].values():
            texture.release()

    def bind(self, prog, resources: dict, t: float, options) -> None:
        bind_samplers(prog, resources["textures"])
        set_uniforms(prog, resources["uniforms"])


@register_material("diffraction")
def parse_diffraction(r: Reader, base_dir: Path) -> DiffractionMaterial:
    gen = r.child("generator")
    if gen is not None and r.has("structure"):
        raise r.fail("generator", "give either a generator or a structure file, not both")
    if gen is not None:
        structure = call_from_table(gen, GENERATORS, "nanostructure generator")
    elif r.has("structure"):
        path = Path(r.string("structure"))
        path = path if path.is_absolute() else base_dir / path
        if not path.is_file():
            raise r.fail("structure", f"file not found: {path}")
        try:
            structure = read_heightfield(
                path, r.number("pixel_um", required=True, lo=1e-6), r.number("height_scale_um", 1.0)
            )
        except PrefilterError as exc:
            raise r.fail("structure", str(exc)) from None
    else:
        raise r.fail(None, "needs structure = 'file' (with pixel_um) or a [generator]")
    centre = r.vector("centre", 2, default=[0.5, 0.5])
    return DiffractionMaterial(
        structure=structure,
        circular=r.string("grooves", "straight", choices=("straight", "circular")) == "circular",
        groove_angle=math.radians(r.number("groove_angle", 0.0)),
        centre=(float(centre[0]), float(centre[1])),
        coherence=r.number("coherence_um", 65.0 / 4.0, lo=0.1, hi=1000.0),
        spectral_step=r.number("spectral_step_nm", 5.0, lo=0.1, hi=50.0),
        f0=r.number("f0", 1.0, lo=0.0, hi=1.0),
        epsilon=r.number("epsilon", 1e-7, lo=1e-12, hi=0.1),
        exposure=r.number("exposure", 1.0, lo=0.0),
        table_size=tuple(int(n) for n in r.vector("fast_table", 3, default=list(DEFAULT_SIZE))),
        tiles=_tiles(r),
        dhillon_w0=r.number("dhillon_w0", -1.0, lo=-2.0, hi=0.0),
    )


def _tiles(r: Reader) -> tuple[int, int] | None:
    if not r.has("tiles"):
        return None
    tiles = r.vector("tiles", 2)
    if any(n < 1 or n > 100000 or n != int(n) for n in tiles):
        raise r.fail("tiles", f"expected two whole numbers of copies >= 1, got {list(tiles)}")
    return int(tiles[0]), int(tiles[1])
