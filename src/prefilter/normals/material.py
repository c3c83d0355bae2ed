"""Normal-mapped surfaces filtered by pyramids of Phong peaks, and multiple surfaces (Fournier 1992).

Two material types share normals.frag:

type = "normal-map": a tangent-space normal map and/or a height map (files, or one of the paper's
generators), tiled `uv_scale` times over the mesh's uvs, shaded with Phong lobes of exponent `exponent`
(n0) per base normal; modes `point`, `naive`, `toksvig`, `lean`, `multilobe` (Fournier's pyramid, §2.4)
and the diagnostic `peak-count`. With `shadowing = true` (needs heights) the horizon maps of §5 shadow
and mask every mode.

    normal_map = "file.png|.exr"     height_map = "file.png|.exr"     height_scale = 1.0
    [generator] name = "hemispheres|cylinders|twill|stochastic", other keys = its parameters
    uv_scale = [1, 1]   albedo = "#rrggbb"   specular = 0.3 (k_s)   exponent = 100 (n0)   shadowing = false
    anisotropy = 1 (multilobe's footprint samples, 1-16)   lod_bias = 0 (levels added to multilobe's level)
    [pyramid] max_peaks = 7, rms_tolerance = 0.05, max_tolerance = 0.05, n_theta = 18, n_phi = 72,
              pole_cap_degrees = 5/12, tile = 32, horizon_distance, exact = "texels" | "field"

type = "multiple-surface" (§4): one set of peaks everywhere. `preset = "velvet" | "silk" | "three-normal"`
(the paper's table and Fig. 9) or [[peak]] tables (amplitude, direction in the tangent frame with z the
normal, exponent, optional horizon = [+X, -X, +Y, -Y] slopes and horizon_std); `horizon`/`horizon_std`
at the material level apply to every peak; shadowing = true turns them on. Peaks pointing below the
surface (z < 0: half of the paper's velvet and silk rings) cannot be seen (Fournier's footnote 3) and
are dropped. `point` and `multilobe` are the peaks themselves; the baselines see the moments of their
distribution.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import moderngl
import numpy as np

from prefilter import PrefilterError
from prefilter.gl.uniforms import bind_samplers, set_uniforms
from prefilter.normals import peak_texels
from prefilter.normals.normal_maps import GENERATORS, SurfaceMap, load_surface
from prefilter.normals.peaks import lobe
from prefilter.normals.pyramid import NormalPyramid, PyramidOptions, build_pyramid
from prefilter.registry import call_from_table
from prefilter.scene import Reader, register_material

SHADER_DIR = Path(__file__).resolve().parent
PACKAGE_ROOT = SHADER_DIR.parent
MAX_LEVELS = 16
MAX_CONSTANT_PEAKS = 16

# Fournier 1992, §4 table (amplitude, vector, exponent) and Fig. 9 (the third exponent is not printed).
MULTIPLE_SURFACES: dict[str, list[tuple[float, tuple[float, float, float], float]]] = {
    "velvet": [
        (0.1, (0, 0, 1), 1.0),
        (0.6, (0.01, 1, 0), 20),
        (0.6, (0.01, 0.5, 0.866), 20),
        (0.6, (0.01, -0.5, 0.866), 20),
        (0.6, (0.01, -1, 0), 20),
        (0.6, (0.01, -0.5, -0.866), 20),
        (0.6, (0.01, 0.5, -0.866), 20),
    ],
    "silk": [
        (0.6, (0, 0, 1), 1.0),
        (0.1, (0.1, 1, 0), 32),
        (0.6, (0.8, 1, 0), 32),
        (0.4, (0.5, 1, 0), 32),
        (0.1, (0.1, 0, 1), 32),
        (0.6, (0.8, 0, 1), 32),
        (0.4, (0.5, 0, 1), 32),
        (0.1, (0.1, -1, 0), 32),
        (0.6, (0.8, -1, 0), 32),
        (0.4, (0.5, -1, 0), 32),
        (0.1, (0.1, 0, -1), 32),
        (0.4, (0.8, 0, -1), 32),
        (0.6, (0.5, 0, -1), 32),
    ],
    "three-normal": [
        (0.4, (0.6, 0, 0.8), 100),
        (0.4, (-0.6, 0, 0.8), 100),
        (0.4, (0, 0, 1), 100),
    ],
}


@dataclass
class NormalsMaterial:
    surface: SurfaceMap | None  # None for a multiple surface
    constant: NormalPyramid | None  # a multiple surface as a one-texel pyramid
    uv_scale: np.ndarray
    albedo: np.ndarray
    specular: float
    exponent: float
    shadowing: bool
    options: PyramidOptions
    anisotropy: int = 1  # samples along the footprint's longer axis in `multilobe` (1: isotropic)
    lod_bias: float = 0.0  # levels added to `multilobe`'s level choice
    scheduler: str | None = None
    _pyramid: NormalPyramid | None = field(default=None, repr=False, compare=False)

    kind = "normals"

    def modes(self) -> tuple[str, ...]:
        return ("toksvig", "lean", "multilobe")

    def diagnostic_modes(self) -> tuple[str, ...]:
        return ("peak-count", "flat")

    def scaled(self, factor: float) -> NormalsMaterial:
        return replace(self, uv_scale=self.uv_scale * factor)

    def shader_sources(self) -> tuple[Path, Path]:
        return PACKAGE_ROOT / "glsl/common/tangent_frame.vert", SHADER_DIR / "normals.frag"

    def defines(self, options) -> dict[str, object]:
        defines: dict[str, object] = {"ND_ANISOTROPY": self.anisotropy}
        if self.shadowing:
            defines["ND_SHADOWING"] = True
        if self.constant is not None:
            defines["ND_CONSTANT"] = True
        return defines

    def pyramid(self, progress: bool = False) -> NormalPyramid:
        if self.constant is not None:
            return self.constant
        if self._pyramid is None:
            assert self.surface is not None
            self._pyramid = build_pyramid(self.surface, self.options, self.scheduler, progress)
        return self._pyramid

    # -- GPU ------------------------------------------------------------------------------------------
    def upload(self, ctx: moderngl.Context, mesh) -> dict:
        pyramid = self.pyramid()
        atlas, boxes, scales = pack_atlas(pyramid, self.shadowing)
        h, w, layers = atlas.shape[0], atlas.shape[1], atlas.shape[2]
        peaks = ctx.texture_array(
            (w, h, layers), 4, np.ascontiguousarray(atlas.transpose(2, 0, 1, 3)), dtype="f4"
        )
        peaks.filter = (moderngl.NEAREST, moderngl.NEAREST)
        textures = {"nd_peaks": peaks}
        for name, data in self.baseline_maps(pyramid).items():
            textures[name] = _mipmapped(ctx, data)
        level = np.zeros((MAX_LEVELS, 4), np.float32)
        level[: len(boxes)] = boxes
        alike = np.zeros(MAX_LEVELS, np.float32)
        alike[: len(boxes)] = pyramid.alike or [1.0] * len(boxes)
        uniforms = {
            "nd_level": level,
            "nd_levelAlike": alike,
            "nd_levelCount": len(boxes),
            "nd_maxPeaks": pyramid.max_peaks,
            **scales.uniforms(),
        }
        return {"textures": textures, "uniforms": uniforms}

    def baseline_maps(self, pyramid: NormalPyramid) -> dict[str, np.ndarray]:
        """(h, w, 4) float32 base images whose MIP maps the single-lobe baselines read."""
        if self.surface is not None:
            stats = None
            if self.shadowing and pyramid.horizon is not None:
                horizon = pyramid.horizon[0][..., 0, :4]
                stats = np.stack([horizon, horizon**2], axis=-2)
            return _baseline_images(self.surface.normals, None, stats)
        # a multiple surface: the moments of its distribution, by quadrature on the hemisphere grid
        grid = self.options.grid()
        p = pyramid.peaks[0][0, 0]
        density = (p[:, 3][None, :] * lobe(grid.directions @ p[:, :3].T, p[:, 4][None, :])).sum(axis=1)
        stats = None
        if self.shadowing and pyramid.horizon is not None:
            hz = pyramid.horizon[0][0, 0]
            a = p[:, 3] / max(float(p[:, 3].sum()), 1e-12)
            stats = np.stack([a @ hz[:, :4], a @ (hz[:, 4:] ** 2 + hz[:, :4] ** 2)])[None, None]
        return _baseline_images(grid.directions[None], (density * grid.solid_angles)[None], stats)

    def release(self, resources: dict) -> None:
        for texture in resources["textures"].values():
            texture.release()

    def bind(self, prog, resources: dict, t: float, options) -> None:
        bind_samplers(prog, resources["textures"])
        set_uniforms(
            prog,
            {
                **resources["uniforms"],
                "u_uvScale": tuple(float(v) for v in self.uv_scale),
                "u_albedo": tuple(float(v) for v in self.albedo),
                "u_specular": float(self.specular),
                "u_exponent": float(self.exponent),
                "nd_lodBias": float(self.lod_bias),
            },
        )


def _baseline_images(normals: np.ndarray, weights: np.ndarray | None, horizon: np.ndarray | None) -> dict:
    """Per-texel (or, with weights, one averaged texel) images of N, slope moments and horizon moments."""
    slopes = normals[..., :2] / np.maximum(normals[..., 2:3], 1e-3)
    images = {
        "nd_meanNormal": np.concatenate([normals, np.zeros_like(normals[..., :1])], axis=-1),
        "nd_slopeMoments": np.concatenate([slopes, slopes**2], axis=-1),
        "nd_slopeCross": np.concatenate(
            [slopes[..., :1] * slopes[..., 1:2], np.zeros_like(normals)], axis=-1
        ),
    }
    if weights is not None:  # one texel: the weighted means
        total = weights.sum()
        images = {
            k: (v * weights[..., None]).sum(axis=(0, 1), keepdims=True) / total for k, v in images.items()
        }
    if horizon is not None:
        images["nd_horizonMean"] = horizon[..., 0, :]
        images["nd_horizonSquare"] = horizon[..., 1, :]
    return {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in images.items()}


def _mipmapped(ctx: moderngl.Context, data: np.ndarray) -> moderngl.Texture:
    """What engines do: a trilinear, 16x anisotropic, repeating MIP map built by the driver."""
    h, w = data.shape[:2]
    texture = ctx.texture((w, h), 4, data.tobytes(), dtype="f4")
    texture.build_mipmaps()
    texture.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    texture.anisotropy = 16.0
    texture.repeat_x = texture.repeat_y = True
    return texture


def pack_atlas(
    pyramid: NormalPyramid, shadowing: bool
) -> tuple[np.ndarray, np.ndarray, peak_texels.PeakScales]:
    """(H, W, K, 4) float32 atlas of every level, one texel per peak (normal_pyramid.glsl, packed with its
    horizon statistics when shadowing: peak_texels.py); level boxes (x, y, w, h); the packed codes' steps."""
    sizes = pyramid.sizes
    k = pyramid.max_peaks
    width = sizes[0][0] + (sizes[1][0] if len(sizes) > 1 else 0)
    height = max(sizes[0][1], sum(h for _, h in sizes[1:]))
    horizon = pyramid.horizon if shadowing else None
    if shadowing:
        assert horizon is not None
    scales = peak_texels.PeakScales()
    if horizon is not None:
        amplitudes = np.concatenate([p[..., 3].ravel() for p in pyramid.peaks])
        scales = peak_texels.scales_for(amplitudes, np.concatenate([h.reshape(-1, 8) for h in horizon]))
    empty = np.zeros((height, width, k))
    no_horizon = None if horizon is None else np.zeros((height, width, k, 8))
    atlas = peak_texels.encode(np.zeros((height, width, k, 2)), empty, empty, no_horizon, scales)
    boxes = []
    y = 0
    for level, (lw, lh) in enumerate(sizes):
        x0, y0 = (0, 0) if level == 0 else (sizes[0][0], y)
        if level > 0:
            y += lh
        p = pyramid.peaks[level]
        d = p[..., :3].copy()
        below = d[..., 2] < 0  # fitted directions are kept on or above the surface
        d[..., 2] = np.where(below, 0.0, d[..., 2])
        d /= np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
        atlas[y0 : y0 + lh, x0 : x0 + lw] = peak_texels.encode(
            d[..., :2], p[..., 3], p[..., 4], None if horizon is None else horizon[level], scales
        )
        boxes.append((x0, y0, lw, lh))
    if len(boxes) > MAX_LEVELS:
        raise PrefilterError(f"normal map of {sizes[0][0]}x{sizes[0][1]} has more than {MAX_LEVELS} levels")
    return atlas, np.array(boxes, np.float32), scales


def constant_pyramid(
    peaks: list[tuple[float, np.ndarray, float, np.ndarray]], options: PyramidOptions
) -> NormalPyramid:
    """A one-texel pyramid holding a multiple surface: (amplitude, direction, exponent, horizon (8,))."""
    k = len(peaks)
    p = np.zeros((1, 1, k, 5), np.float32)
    hz = np.zeros((1, 1, k, 8), np.float32)
    for i, (a, d, n, horizon) in enumerate(sorted(peaks, key=lambda q: -q[0])):
        p[0, 0, i] = (*d, a, n)
        hz[0, 0, i] = horizon
    zero = [np.zeros((1, 1), np.float32)]
    return NormalPyramid([(1, 1)], [p], [hz], zero, zero, replace(options, max_peaks=k))


# -- scene parsing ---------------------------------------------------------------------------------------
def _options(r: Reader | None) -> PyramidOptions:
    if r is None:
        return PyramidOptions()
    defaults = PyramidOptions()
    tile = r.integer("tile", defaults.tile, lo=2, hi=4096)
    if tile & (tile - 1):
        raise r.fail("tile", f"must be a power of two, got {tile}")
    distance = r.integer("horizon_distance", 0, lo=0, hi=4096) if r.has("horizon_distance") else None
    options = PyramidOptions(
        exponent=defaults.exponent,
        max_peaks=r.integer("max_peaks", defaults.max_peaks, lo=1, hi=16),
        rms_tolerance=r.number("rms_tolerance", defaults.rms_tolerance, lo=1e-4, hi=1.0),
        max_tolerance=r.number("max_tolerance", defaults.max_tolerance, lo=1e-4, hi=1.0),
        n_theta=r.integer("n_theta", defaults.n_theta, lo=3, hi=180),
        n_phi=r.integer("n_phi", defaults.n_phi, lo=4, hi=720),
        pole_cap_degrees=r.number("pole_cap_degrees", defaults.pole_cap_degrees, lo=0.0, hi=45.0),
        horizon_distance=distance or None,
        tile=tile,
        exact=r.string("exact", defaults.exact, choices=("texels", "field")),
    )
    r.finish()
    return options


def _common(r: Reader) -> dict:
    return {
        "uv_scale": r.vector("uv_scale", 2, default=[1.0, 1.0]),
        "albedo": r.colour("albedo", "#808080"),
        "specular": r.number("specular", 0.3, lo=0.0),
        "exponent": r.number("exponent", 100.0, lo=1.0, hi=1e5),
        "shadowing": r.boolean("shadowing", False),
        "anisotropy": r.integer("anisotropy", 1, lo=1, hi=16),
        "lod_bias": r.number("lod_bias", 0.0, lo=-8.0, hi=8.0),
    }


@register_material("normal-map")
def parse_normal_map(r: Reader, base_dir: Path) -> NormalsMaterial:
    common = _common(r)
    paths = {}
    for key in ("normal_map", "height_map"):
        if r.has(key):
            path = Path(r.string(key))
            path = path if path.is_absolute() else base_dir / path
            if not path.is_file():
                raise r.fail(key, f"file not found: {path}")
            paths[key] = path
    gen = r.child("generator")
    if gen is not None and paths:
        raise r.fail("generator", "give either a generator or normal_map/height_map files, not both")
    if gen is not None:
        surface = call_from_table(gen, GENERATORS, "surface generator")
    elif paths:
        key = "normal_map" if "normal_map" in paths else "height_map"
        height_scale = r.number("height_scale", 1.0, lo=0.0)  # its own error names it, not the map
        try:
            surface = load_surface(paths.get("normal_map"), paths.get("height_map"), height_scale)
        except PrefilterError as exc:
            raise r.fail(key, str(exc)) from None
    else:
        raise r.fail(None, "needs normal_map, height_map or a [generator]")
    if common["shadowing"] and surface.heights is None:
        raise r.fail("shadowing", "needs heights (height_map or a generator) for the horizon maps")
    options = replace(_options(r.child("pyramid")), exponent=common["exponent"])
    return NormalsMaterial(surface, None, options=options, **common)


@register_material("multiple-surface")
def parse_multiple_surface(r: Reader, base_dir: Path) -> NormalsMaterial:
    common = _common(r)
    horizon = r.vector("horizon", 4, default=[0.0] * 4)
    horizon_std = r.vector("horizon_std", 4, default=[0.0] * 4)
    peaks = []
    if r.has("preset"):
        preset = r.string("preset", choices=tuple(MULTIPLE_SURFACES))
        for a, d, n in MULTIPLE_SURFACES[preset]:
            peaks.append((a, np.asarray(d, float), n, np.concatenate([horizon, horizon_std])))
    for pr in r.children("peak"):
        d = pr.vector("direction", 3, required=True)
        if np.linalg.norm(d) == 0:
            raise pr.fail("direction", "must be non-zero")
        peaks.append(
            (
                pr.number("amplitude", required=True, lo=0.0),
                d,
                pr.number("exponent", required=True, lo=0.0, hi=1e5),
                np.concatenate(
                    [pr.vector("horizon", 4, list(horizon)), pr.vector("horizon_std", 4, list(horizon_std))]
                ),
            )
        )
        pr.finish()
    if not peaks:
        raise r.fail("peak", "a multiple surface needs a preset or at least one [[peak]]")
    visible = [(a, d / np.linalg.norm(d), n, h) for a, d, n, h in peaks if d[2] >= 0]
    if not visible:
        raise r.fail("peak", "every peak points below the surface (direction z < 0)")
    if len(visible) > MAX_CONSTANT_PEAKS:
        raise r.fail("peak", f"at most {MAX_CONSTANT_PEAKS} peaks above the surface, got {len(visible)}")
    options = PyramidOptions(exponent=common["exponent"])
    return NormalsMaterial(None, constant_pyramid(visible, options), options=options, **common)
