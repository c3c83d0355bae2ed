"""Colour-mapped microsurfaces: Heitz, Nowrouzezahrai, Poulin, Neyret 2014 §5–§7 (type "microsurface").

A procedural height field (heightfield.py) displaces a macro plane or sphere. Colours are tied to its
heights (C_h(h + ρ r), §5.1), to its slopes along a tangent direction d (C_s(s·d), §5.2), and to an
uncorrelated procedural texture (C₀(r), §4), combined linearly (κ₀C₀ + κ₁C_h + κ₂C_s, §6) or with the
slope layer composited over the rest (a product, §6: the snake skin of Fig. 15). The height may pass
through a transfer function h = g(f) (§7). Light is directional (with shadows) plus unshadowed ambient,
or an environment map's irradiance in 9 SH coefficients (§5.3). microsurface.frag documents the modes.

Scene TOML (under [object.material], type = "microsurface"):
  macro = "plane" | "sphere"; radius = 1.0 (sphere: must match the mesh)
  [height]           octaves = 4, amplitude = 0.05, frequency = 4, gain = 0.5, lacunarity = 2 (Fractal);
                     the finest octave's frequency at most 1e8 (noise.MAX_NOISE_SCALE)
  [texture]          the same keys: the procedural driver r of C₀ and of the perturbation (optional)
  perturb = 0.0      ρ in C(h + ρ r)
  kappa = [κ₀, κ₁, κ₂]  default 1 for each map present
  slope_layer = "add" | "over";  slope_direction = [dx, dy] (tangent frame: +x, −z on the plane)
  height_moments = "table" | "log-fit"   D_h's moments: exact quadrature table, or eqs. (16)/(17)
  footprint = "relief" | "macro"   the pixel footprint that splits the octaves into geometry and
      statistics: on the visible relief, foreshortened by facets facing a grazing eye (heightfield.glsl
      ms_reliefFootprint), or on the macro surface
  shading_samples = 4 | 6 | 9 | 16 | 3 | 2 | 1   surface-filter shades the pixel at N x M sub-pixel points
      (2 x 2, 3 x 2 with 3 along the footprint's longer screen axis, 3 x 3, 4 x 4; 3: a triangle, turned in
      every other pixel; 2: one per marched row, or two along the longer axis) with the octaves split for
      the sub-boxes' footprint and averages them
      (microsurface.frag: the octaves the footprint half resolves are then integrated over the pixel, not
      sampled once), or once, as the paper does
  marched_rows = true | false   surface-filter: where the coarse relief stands out of the pixel, the grid's
      rows are sub-rays spread over the pixel's extent along the macro normal, marched as one column
      (heightfield.glsl ms_marchColumn), each row's samples placed across the column on a plane through its
      own hit; false: the whole grid on the plane through the centre ray's hit
  [height_colour], [slope_colour], [texture_colour]: scale = 1, offset = 0 (argument = scale·x + offset),
      [....colour_table] as for Hart's model, [....preconvolved] as for the gaussian mode; a table with
      one colour throughout is that colour in every mode, with no table and no filtering
  [transfer]         function = "moss" | "sponge" | "linear" (microsurface/transfer.py), its parameters,
                     scale (h = scale · g(f), with f the [height] fractal in driver units; its amplitude
                     must then be > 0), e.g. softness > 0 for moss and sponge
  [irradiance]       environment = "file.exr" (equirectangular, linear; replaces lights and ambient),
                     intensity = 1 (exposure: the radiance of a white Lambertian facing up)
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import moderngl
import numpy as np

from prefilter import PrefilterError
from prefilter.colormap.gaussian import parse_preconvolve_options, preconvolve
from prefilter.colormap.table import ColourTable, parse_colour_table
from prefilter.gl.uniforms import bind_samplers, set_uniforms
from prefilter.microsurface.curved_shadowing import CURVED_DESCENT, CURVED_ELEVATION
from prefilter.microsurface.fractal_masking import SLOPE_LEAN, SLOPE_LEAN_FADE_DEG, masking_uniform
from prefilter.microsurface.heightfield import LATTICE_FROM_OBJECT, MAX_OCTAVES, Fractal
from prefilter.procedural.noise import MAX_NOISE_SCALE
from prefilter.scene import Reader, register_material

SHADER_DIR = Path(__file__).resolve().parent
PACKAGE_ROOT = SHADER_DIR.parent
FILTERED_MODES = ("texture-filter", "surface-filter")
MAPS = ("height", "slope", "texture")
# shading_samples -> the sub-pixel grid (MS_GRID_X, MS_GRID_Y), its longer side along the footprint's longer
# screen axis; MS_GRID_Y is the number of rows the column marches (1 x 2: one sample per row); 3 is a triangle
# (MS_TRIANGLE), marched in one row
SHADING_GRIDS = {1: (1, 1), 2: (1, 2), 3: (3, 1), 4: (2, 2), 6: (3, 2), 9: (3, 3), 16: (4, 4)}


@dataclass
class ColourMap:
    table: ColourTable
    scale: float = 1.0
    offset: float = 0.0
    preconvolved: dict = field(default_factory=dict)

    def is_constant(self) -> bool:
        """One colour throughout, as uploaded (premultiplied): its own filtered value, bound as a constant."""
        return self.table.premultiplied().is_constant()


@dataclass
class MicrosurfaceMaterial:
    height: Fractal
    texture: Fractal | None
    maps: dict[str, ColourMap]
    macro: str = "plane"
    radius: float = 1.0
    perturb: float = 0.0
    kappa: tuple[float, float, float] = (1.0, 1.0, 1.0)
    slope_over: bool = False
    slope_direction: tuple[float, float] = (1.0, 0.0)
    height_moments: str = "table"
    footprint: str = "relief"
    shading_samples: int = 4
    marched_rows: bool = True
    transfer: object | None = None  # microsurface.transfer.TransferFunction
    transfer_scale: float = 1.0  # h = transfer_scale · g(f)
    environment: Path | None = None
    environment_intensity: float = 1.0  # radiance of a white Lambertian facing up
    # the environment's SH9 projection (9, 3), made once where the scene is read and exposed there so that a
    # white Lambertian facing up reflects radiance 1 (E_up = π); upload() scales it by the intensity
    environment_sh: np.ndarray | None = field(default=None, compare=False, repr=False)

    kind = "microsurface"

    def modes(self) -> tuple[str, ...]:
        return FILTERED_MODES

    def diagnostic_modes(self) -> tuple[str, ...]:
        return ("march-steps",)

    def scaled(self, factor: float) -> MicrosurfaceMaterial:
        texture = self.texture.scaled(factor) if self.texture else None
        return replace(self, height=self.height.scaled(factor), texture=texture)

    def shader_sources(self) -> tuple[Path, Path]:
        return PACKAGE_ROOT / "glsl/common/surface.vert", SHADER_DIR / "microsurface.frag"

    def defines(self, options) -> dict[str, object]:
        # a constant colour map is its own filtered value under any distribution: no table, no filtering
        defines: dict[str, object] = {
            f"MS_{name.upper()}_{'CONSTANT' if cmap.is_constant() else 'MAP'}": True
            for name, cmap in self.maps.items()
        }
        if self.texture is not None:
            defines["MS_TEXTURE_FRACTAL"] = True
        if self.macro == "sphere":
            defines["MS_SPHERE"] = True
        if self.height_moments == "log-fit":
            defines["MS_HEIGHT_FIT"] = True
        if self.footprint == "macro":
            defines["MS_MACRO_FOOTPRINT"] = True
        if self.transfer is not None:
            defines["MS_TRANSFER"] = True
            if self._driver_colour():
                defines["MS_DRIVER_COLOUR"] = True
                defines["MS_DRIVER_NODES"] = True
        defines["MS_GRID_X"], defines["MS_GRID_Y"] = SHADING_GRIDS[self.shading_samples]
        if self.shading_samples == 3:
            defines["MS_TRIANGLE"] = True
        # the column's sub-rays: the grid's rows
        defines["MS_RELIEF_RAYS"] = SHADING_GRIDS[self.shading_samples][1] if self.marched_rows else 1
        defines["MS_SLOPE_LEAN"] = SLOPE_LEAN  # the fBm's visible slopes (fractal_masking.slope_lean)
        defines["MS_SLOPE_LEAN_FADE"] = float(np.sin(np.radians(SLOPE_LEAN_FADE_DEG)))
        defines["MS_CURVED_ELEVATION"] = CURVED_ELEVATION  # Smith over a sphere (curved_shadowing.py)
        defines["MS_CURVED_DESCENT"] = CURVED_DESCENT
        if self.environment is not None:
            defines["MS_IRRADIANCE"] = True
        return defines

    def _driver_colour(self) -> bool:
        """surface-filter reads the height colour of a transfer function over its driver (driver_colour.py);
        not with a perturbation C(h + ρ r), which moves h, not f."""
        height = self.maps.get("height")
        return (
            self.transfer is not None
            and height is not None
            and not height.is_constant()
            and self.perturb == 0
        )

    def upload(self, ctx: moderngl.Context, mesh) -> dict:
        from prefilter.microsurface.height_filtering import height_filtering_table

        textures: dict[str, moderngl.Texture] = {}
        uniforms: dict[str, object] = {}
        owned: list = []  # everything with a release() that this material created
        for name, cmap in self.maps.items():
            table = cmap.table.premultiplied()
            if table.is_constant():  # as the defines judge it (ColourMap.is_constant)
                uniforms[f"u_{name}Constant"] = tuple(float(v) for v in table.entries[0])
                continue
            pre = preconvolve(table, **cmap.preconvolved)
            point = table.upload(ctx)
            owned.append(point)
            textures[f"u_{name}Point"] = point.point
            textures[f"u_{name}Gaussian"] = pre.upload(ctx)
            owned.append(textures[f"u_{name}Gaussian"])
            if name == "height":  # surface-filter reads it box-filtered too (ms_heightColour)
                textures["u_heightGaussianBox"] = pre.upload_box(ctx)
                owned.append(textures["u_heightGaussianBox"])
            if name == "slope":  # and the slope colour's derivative (ms_slopeColourDerivative)
                textures["u_slopeGaussianDerivative"] = pre.upload_derivative(ctx)
                owned.append(textures["u_slopeGaussianDerivative"])
            uniforms[f"u_{name}Range"] = (*pre.mu_range, pre.sigma_max)
            uniforms[f"u_{name}Wrap"] = point.wrap_code
            uniforms[f"u_{name}Map"] = (cmap.scale, cmap.offset)
        textures["u_heightFilteringTable"] = height_filtering_table().upload(ctx)
        owned.append(textures["u_heightFilteringTable"])
        if self.transfer is not None:
            from prefilter.microsurface.transfer import preconvolve_transfer

            pre = preconvolve_transfer(self.transfer)
            textures["u_transferTable"] = pre.upload(ctx)
            owned.append(textures["u_transferTable"])
            uniforms["u_transferRange"] = (*pre.mu_range, pre.sigma_max)
            uniforms["u_transferScale"] = self.transfer_scale
            v = np.linspace(*pre.mu_range, 4097)
            heights = self.transfer_scale * self.transfer.g(v)  # the relief's range, 0 included
            uniforms["u_transferHeights"] = (min(float(heights.min()), 0.0), max(float(heights.max()), 0.0))
            if self._driver_colour():
                from prefilter.microsurface.driver_colour import (
                    preconvolve_driver_colour,
                    preconvolve_driver_slopes,
                )

                cmap = self.maps["height"]
                args = (
                    cmap.table.premultiplied(),
                    cmap.scale,
                    cmap.offset,
                    self.transfer,
                    self.transfer_scale,
                    float(np.sqrt(self.height.variance())),
                )
                driver, driver_map = preconvolve_driver_colour(*args)
                slopes, unit = preconvolve_driver_slopes(*args)  # the shading samples' slope nodes
                textures["u_driverColour"] = driver.upload(ctx)
                textures["u_driverSlopeColour"] = slopes.upload(ctx)
                owned += [textures["u_driverColour"], textures["u_driverSlopeColour"]]
                uniforms["u_driverMap"] = driver_map
                uniforms["u_driverRange"] = (*driver.mu_range, driver.sigma_max)
                uniforms["u_driverSlopeUnit"] = unit
            uniforms["u_transferSlopes"] = (
                self.transfer_scale * float(np.max(np.abs(self.transfer.g_prime(v)))),
                self.transfer_scale * self.transfer.slope_gain(np.sqrt(self.height.variance())),
            )
        if self.environment is not None:
            from prefilter.microsurface.irradiance import sh_uniform

            uniforms["u_sh"] = sh_uniform(self.environment_sh * self.environment_intensity)
        return {"textures": textures, "uniforms": uniforms, "owned": owned}

    def release(self, resources: dict) -> None:
        for item in resources["owned"]:
            item.release()

    def octave_uniforms(self) -> dict[str, object]:
        pairs = np.zeros((2 * MAX_OCTAVES, 2), np.float32)
        offsets = np.zeros((2 * MAX_OCTAVES, 3), np.float32)
        pairs[:MAX_OCTAVES], offsets[:MAX_OCTAVES] = self.height.octave_uniforms()
        if self.texture is not None:
            pairs[MAX_OCTAVES:], offsets[MAX_OCTAVES:] = self.texture.octave_uniforms()
            offsets[MAX_OCTAVES:] += 101.0  # the texture is not the height field
        return {
            "ms_octave": pairs,
            "ms_octaveOffset": offsets,
            "ms_octaveMasking": masking_uniform(self.height),
            "ms_heightOctaves": self.height.octaves,
            "ms_textureOctaves": self.texture.octaves if self.texture else 0,
            "ms_latticeFromObject": LATTICE_FROM_OBJECT.T,
            "ms_radius": self.radius,
        }

    def bind(self, prog, resources: dict, t: float, options) -> None:
        bind_samplers(prog, resources["textures"])
        direction = np.asarray(self.slope_direction, float)
        set_uniforms(
            prog,
            {
                **self.octave_uniforms(),
                **resources["uniforms"],
                "u_solidFromObject": np.eye(4),
                "u_perturb": self.perturb,
                "u_kappa": tuple(float(k) for k in self.kappa),
                "u_slopeOver": int(self.slope_over),
                "u_slopeDirection": tuple(direction / np.linalg.norm(direction)),
            },
        )


def _fractal(r: Reader, defaults: Fractal) -> Fractal:
    fractal = Fractal(
        octaves=r.integer("octaves", defaults.octaves, lo=1, hi=MAX_OCTAVES),
        amplitude=r.number("amplitude", defaults.amplitude, lo=0.0),
        frequency=r.number("frequency", defaults.frequency, lo=1e-6),
        gain=r.number("gain", defaults.gain, lo=0.0, hi=1.0),
        lacunarity=r.number("lacunarity", defaults.lacunarity, lo=1.0, hi=8.0),
    )
    finest = fractal.frequency * fractal.lacunarity ** (fractal.octaves - 1)
    if finest > MAX_NOISE_SCALE:
        raise r.fail("frequency", f"the finest octave's frequency {finest:.3g} exceeds {MAX_NOISE_SCALE:.0e}")
    r.finish()
    return fractal


def _colour_map(r: Reader) -> ColourMap:
    tr = r.child("colour_table", required=True)
    assert tr is not None
    cmap = ColourMap(
        parse_colour_table(tr),
        r.number("scale", 1.0),
        r.number("offset", 0.0),
        parse_preconvolve_options(r.child("preconvolved")),
    )
    r.finish()
    return cmap


@register_material("microsurface")
def parse_microsurface(r: Reader, base_dir: Path) -> MicrosurfaceMaterial:
    macro = r.string("macro", "plane", choices=("plane", "sphere"))
    radius = r.number("radius", 1.0, lo=1e-6)
    hr = r.child("height", required=True)
    assert hr is not None
    height = _fractal(hr, Fractal())
    tr = r.child("texture")
    texture = _fractal(tr, Fractal(4, 0.5, 4.0)) if tr is not None else None
    maps: dict[str, ColourMap] = {}
    for name in MAPS:
        mr = r.child(f"{name}_colour")
        if mr is not None:
            maps[name] = _colour_map(mr)
    if not maps:
        raise r.fail(
            "height_colour",
            "a microsurface needs at least one of height_colour, slope_colour, texture_colour",
        )
    if "texture" in maps and texture is None:
        raise r.fail("texture", "texture_colour needs a [texture] fractal to drive it")
    perturb = r.number("perturb", 0.0)
    if perturb != 0.0 and texture is None:
        raise r.fail("perturb", "a height perturbation needs a [texture] fractal")
    default_kappa = [1.0 if name in maps else 0.0 for name in ("texture", "height", "slope")]
    kappa = tuple(float(k) for k in r.vector("kappa", 3, default=default_kappa))
    slope_over = r.string("slope_layer", "add", choices=("add", "over")) == "over"
    direction = r.vector("slope_direction", 2, default=[1.0, 0.0])
    if np.linalg.norm(direction) == 0:
        raise r.fail("slope_direction", "must be non-zero")
    moments = r.string("height_moments", "table", choices=("table", "log-fit"))
    footprint = r.string("footprint", "relief", choices=("relief", "macro"))
    shading_samples = r.integer("shading_samples", 4)
    if shading_samples not in SHADING_GRIDS:
        raise r.fail("shading_samples", f"must be 1, 2, 3, 4, 6, 9 or 16, got {shading_samples}")
    marched_rows = r.boolean("marched_rows", True)
    transfer, transfer_scale = None, 1.0
    xr = r.child("transfer")
    if xr is not None:
        from prefilter.microsurface.transfer import TRANSFER_FUNCTIONS

        name = xr.string("function", required=True, choices=tuple(TRANSFER_FUNCTIONS))
        if height.amplitude <= 0.0:
            raise hr.fail("amplitude", "must be > 0 with a [transfer] function (the driver f of h = g(f))")
        transfer_scale = xr.number("scale", 1.0, lo=0.0)
        params = {key: xr.number(key) for key in xr.table if key not in ("function", "scale")}
        try:
            transfer = TRANSFER_FUNCTIONS[name](**params)
        except (TypeError, ValueError) as exc:  # an unknown parameter, or a value out of its range
            raise xr.fail(None, str(exc)) from None
        xr.finish()
    environment, intensity, environment_sh = None, 1.0, None
    er = r.child("irradiance")
    if er is not None:
        environment = Path(er.string("environment", required=True))
        environment = environment if environment.is_absolute() else base_dir / environment
        if not environment.is_file():
            raise er.fail("environment", f"file not found: {environment}")
        from prefilter.microsurface.irradiance import irradiance_sh, read_environment, sh9_project

        try:  # read here, once, so that a bad map is named by its key
            environment_sh = sh9_project(read_environment(environment))
        except PrefilterError as exc:
            raise er.fail("environment", str(exc)) from None
        # exposure: a white Lambertian facing up reflects radiance 1 (E_up = π); a black map has none to scale
        up = float(np.mean(irradiance_sh(environment_sh, np.array([0.0, 0.0, 1.0]))))
        if not up > 0.0:
            raise er.fail(
                "environment",
                f"{environment}: no light reaches a surface facing up (z), which sets its exposure",
            )
        environment_sh = environment_sh * (np.pi / up)
        intensity = er.number("intensity", 1.0, lo=0.0)
        er.finish()
    return MicrosurfaceMaterial(
        height,
        texture,
        maps,
        macro,
        radius,
        perturb,
        kappa,  # type: ignore[arg-type]
        slope_over,
        (float(direction[0]), float(direction[1])),
        moments,
        footprint,
        shading_samples,
        marched_rows,
        transfer,
        transfer_scale,
        environment,
        intensity,
        environment_sh,
    )
