"""Colour maps over tabulated drivers: Heitz et al. 2013/2014 §4.2 for an image f (height map, data).

"For precomputed/tabulated f, we need only precompute the first two moments of f, f̄ and f̄², at each
level of detail in a mipmap hierarchy ... σ_f² = E[f²] − E[f]² after linear texture interpolation".
The driver image is uploaded as an RG32F texture of (f, f²) with its MIP pyramid built here by 2x2 box
means (so level L holds exact block moments). The moments over a pixel's footprint are the mean of
`probes` trilinear reads along its longer axis (tabulated.glsl, tb_footprintMoments), or with probes = 0
one read through the GL's 16x anisotropic filter; the colour comes from the preconvolved map C̄(μ, σ) of
colormap/gaussian.py.

Modes: `point` (f reconstructed bilinearly at level 0, then c(f): what the reference supersamples),
`naive` (c of E[f] over the footprint, read as `gaussian` reads it: today's renderers), `gaussian`.

Scene TOML (type = "tabulated"): image = "file.png|.exr" (first channel, PNG 8/16-bit read as [0, 1];
power-of-two sides), uv_scale = [su, sv] (repeats over the mesh's uvs), value_scale, value_offset
(f = offset + scale x image), probes (0-16, default 4: trilinear probes per pixel; 0 = the GL's
anisotropic filter), [object.material.colour_table] and [object.material.preconvolved] as for
Hart's model.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import moderngl
import numpy as np

from prefilter import PrefilterError
from prefilter.colormap.gaussian import parse_preconvolve_options, preconvolve
from prefilter.colormap.table import ColourTable, TableTextures, parse_colour_table
from prefilter.gl.uniforms import bind_samplers, set_uniforms
from prefilter.image_data import one_line, read_exr, read_png
from prefilter.scene import Reader, register_material

SHADER_DIR = Path(__file__).resolve().parent
PACKAGE_ROOT = SHADER_DIR.parent


def read_driver(path: Path) -> np.ndarray:
    """The image's first channel (R of RGB, or its only one) as float64 (H, W): PNG integers scaled to [0, 1]
    (image_data.read_png, 16-bit too), EXR as stored, other formats that Pillow reads (TIFF, JPEG) alike."""
    ext = path.suffix.lower()
    if ext == ".png":
        data = read_png(path)[0]
    elif ext == ".exr":
        data = read_exr(path)[0]
    else:
        import imageio.v3 as iio

        try:
            raw = iio.imread(path, plugin="pillow")
        except Exception as exc:  # Pillow/imageio raise many kinds
            raise PrefilterError(
                f"{path}: cannot read driver image ({one_line(exc)}); use .png, .exr or a format Pillow reads"
            ) from None
        data = raw.astype(np.float64) / (np.iinfo(raw.dtype).max if raw.dtype.kind in "ui" else 1.0)
    if data.ndim == 3:
        data = data[..., 0]
    if data.ndim != 2 or data.size == 0:
        raise PrefilterError(f"{path}: expected a 2D image, got shape {data.shape}")
    h, w = data.shape
    if w & (w - 1) or h & (h - 1):
        raise PrefilterError(f"{path}: driver image sides must be powers of two, got {w}x{h}")
    bad = ~np.isfinite(data)
    if bad.any():  # they had passed into the moment pyramid and the shader's table reads
        y, x = np.argwhere(bad)[0]
        count = int(bad.sum())
        what = "driver value is" if count == 1 else "driver values are"
        raise PrefilterError(f"{path}: {count} {what} not finite (the first at x {x}, y {y})")
    return data


def moment_pyramid(f: np.ndarray) -> list[np.ndarray]:
    """Levels of (f, f²) as (h, w, 2) float64, each the 2x2 box mean of the previous (exact block moments)."""
    level = np.stack([f, f * f], axis=-1)
    levels = [level]
    while level.shape[0] > 1 or level.shape[1] > 1:
        h, w = level.shape[:2]
        if h > 1:
            level = 0.5 * (level[0::2] + level[1::2])
        if w > 1:
            level = 0.5 * (level[:, 0::2] + level[:, 1::2])
        levels.append(level)
    return levels


@dataclass
class TabulatedResources:
    table: TableTextures
    gaussian: moderngl.Texture
    gaussian_range: tuple[float, float, float]
    driver: moderngl.Texture

    def release(self) -> None:
        self.table.release()
        self.gaussian.release()
        self.driver.release()


@dataclass
class TabulatedMaterial:
    driver: np.ndarray  # (H, W) float64, already value_scale * image + value_offset
    table: ColourTable
    uv_scale: np.ndarray
    source: str
    gaussian: dict = field(default_factory=dict)
    probes: int = 4  # trilinear reads along the footprint's longer axis; 0: the GL's 16x anisotropic filter

    kind = "tabulated"

    def modes(self) -> tuple[str, ...]:
        return ("gaussian",)

    def diagnostic_modes(self) -> tuple[str, ...]:
        return ()

    def scaled(self, factor: float) -> TabulatedMaterial:
        return replace(self, uv_scale=self.uv_scale * factor)

    def shader_sources(self) -> tuple[Path, Path]:
        return PACKAGE_ROOT / "glsl/common/surface.vert", SHADER_DIR / "tabulated.frag"

    def defines(self, options) -> dict[str, object]:
        return {"TB_WRAP": self.table.wrap_code, "TB_PROBES": self.probes}

    def upload(self, ctx: moderngl.Context, mesh) -> TabulatedResources:
        table = self.table.premultiplied()
        gaussian = preconvolve(table, **self.gaussian)
        levels = moment_pyramid(self.driver)
        h, w = self.driver.shape
        driver = ctx.texture((w, h), 2, levels[0].astype(np.float32).tobytes(), dtype="f4")
        driver.build_mipmaps(0, len(levels) - 1)  # allocates the chain; every level is overwritten
        for index, level in enumerate(levels[1:], 1):
            driver.write(np.ascontiguousarray(level, dtype=np.float32).tobytes(), level=index)
        driver.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        driver.anisotropy = 1.0 if self.probes else 16.0  # llvmpipe's textureLod follows the anisotropy
        driver.repeat_x = driver.repeat_y = True
        gaussian_range = (*gaussian.mu_range, gaussian.sigma_max)
        return TabulatedResources(table.upload(ctx), gaussian.upload(ctx), gaussian_range, driver)

    def release(self, resources: TabulatedResources) -> None:
        resources.release()

    def bind(self, prog, resources: TabulatedResources, t: float, options) -> None:
        bind_samplers(
            prog,
            {
                "u_tablePoint": resources.table.point,
                "u_tableGaussian": resources.gaussian,
                "u_driver": resources.driver,
            },
        )
        set_uniforms(
            prog,
            {
                "u_gaussianRange": resources.gaussian_range,
                "u_uvScale": tuple(float(v) for v in self.uv_scale),
            },
        )


@register_material("tabulated")
def parse_tabulated(r: Reader, base_dir: Path) -> TabulatedMaterial:
    image = Path(r.string("image", required=True))
    image = image if image.is_absolute() else base_dir / image
    if not image.is_file():
        raise r.fail("image", f"file not found: {image}")
    try:
        data = read_driver(image)
    except PrefilterError as exc:
        raise r.fail("image", str(exc)) from None
    driver = r.number("value_offset", 0.0) + r.number("value_scale", 1.0) * data
    tr = r.child("colour_table", required=True)
    assert tr is not None
    return TabulatedMaterial(
        driver,
        parse_colour_table(tr),
        r.vector("uv_scale", 2, default=[1.0, 1.0]),
        str(image),
        parse_preconvolve_options(r.child("preconvolved")),
        r.integer("probes", 4, lo=0, hi=16),
    )
