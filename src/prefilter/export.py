"""Export bundles (docs/export.md): a scene's assembled shaders, baked tables, meshes and a README.

What a material needs is learned without per-technique code: its `upload` runs on a real context and its
`bind` runs against a `BindingRecorder`, which keeps every uniform value and sampler texture it is given;
the textures are read back level by level and written as float32 EXR with JSON metadata. Shaders are the
renderer's own programs (same `program_defines`), assembled for `gl330` and `es300`. The browser viewer
draws from these bundles, so what an engine gets is what the viewer shows.
"""

from __future__ import annotations

import json
import math
import re
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import moderngl
import numpy as np

from prefilter import PrefilterError
from prefilter.export_readme import bundle_readme
from prefilter.geometry import VERTEX_LAYOUT
from prefilter.gl.annotations import (
    Uniform,
    parameter,
    referenced_uniforms,
    table_description,
    uniform_declarations,
)
from prefilter.gl.context import gl_context
from prefilter.gl.program import assemble
from prefilter.gl.render import (
    BASE_MODES,
    MAX_LIGHTS,
    RenderOptions,
    build_mesh,
    frame_uniforms,
    program_defines,
    scene_modes,
)
from prefilter.gl.uniforms import BindingRecorder
from prefilter.outputs import check_replaceable
from prefilter.scene import Scene, SceneObject

FORMAT = "prefilter-export/1"
EXPORT_TARGETS = ("gl330", "es300")
CHANNELS = "RGBA"
_FILTERS = {
    moderngl.NEAREST: "NEAREST",
    moderngl.LINEAR: "LINEAR",
    moderngl.NEAREST_MIPMAP_NEAREST: "NEAREST_MIPMAP_NEAREST",
    moderngl.LINEAR_MIPMAP_NEAREST: "LINEAR_MIPMAP_NEAREST",
    moderngl.NEAREST_MIPMAP_LINEAR: "NEAREST_MIPMAP_LINEAR",
    moderngl.LINEAR_MIPMAP_LINEAR: "LINEAR_MIPMAP_LINEAR",
}
_INTERNAL = {1: "R32F", 2: "RG32F", 3: "RGB32F", 4: "RGBA32F"}
GLSL_COMPONENTS = {
    **{t: 1 for t in ("float", "int", "uint", "bool")},
    **{f"{p}vec{n}": n for p in ("", "i", "u", "b") for n in (2, 3, 4)},
    "mat2": 4,
    "mat3": 9,
    "mat4": 16,
}
REFERENCE = {
    "mode": "point",
    "spp": 1024,
    "pattern": "N x N stratified jittered sub-pixel offsets of the projection (u_jitter), N = sqrt(spp); "
    "the mean of the passes (box pixel filter)",
}


def file_safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]", "_", name) or "_"


def _flat(value: object) -> list:
    """A uniform value as a flat JSON list: ints stay ints, everything else becomes float."""
    if isinstance(value, bool):
        return [int(value)]
    if isinstance(value, int | np.integer):
        return [int(value)]
    array = np.asarray(value)
    if array.dtype.kind in "iu":
        return [int(v) for v in array.ravel()]
    return [float(v) for v in np.asarray(array, dtype=np.float64).ravel()]


# -- tables ------------------------------------------------------------------------------------------


@dataclass
class Table:
    """A texture read back from the GPU: every level as (depth, height, width, components) float32."""

    sampler: str
    kind: str  # "2d" | "2d_array" | "3d"
    levels: list[np.ndarray]
    filter: tuple[str, str]
    wrap: dict[str, str]
    anisotropy: float

    @property
    def components(self) -> int:
        return self.levels[0].shape[-1]

    def metadata(self, description: str, related: dict[str, list]) -> dict:
        depth, height, width, components = self.levels[0].shape
        return {
            "sampler": self.sampler,
            "kind": self.kind,
            "width": width,
            "height": height,
            "depth": depth,
            "components": components,
            "internal_format": _INTERNAL[components],
            "levels": [
                {
                    "file": f"{self.sampler}.{k}.exr",
                    "width": lv.shape[2],
                    "height": lv.shape[1],
                    "depth": lv.shape[0],
                }
                for k, lv in enumerate(self.levels)
            ],
            "filter": {"min": self.filter[0], "mag": self.filter[1]},
            "wrap": self.wrap,
            "anisotropy": self.anisotropy,
            "description": description,
            "related_uniforms": related,
        }


def read_table(sampler: str, texture) -> Table:
    """Read a moderngl Texture / TextureArray / Texture3D back, with all MIP levels of a mipmapped 2D one."""
    if texture.dtype != "f4":
        raise PrefilterError(
            f"sampler {sampler}: only float32 textures can be exported, got dtype {texture.dtype}"
        )
    c = texture.components
    min_filter, mag_filter = texture.filter
    mipmapped = min_filter not in (moderngl.NEAREST, moderngl.LINEAR)
    wrap = lambda repeat: "REPEAT" if repeat else "CLAMP_TO_EDGE"  # noqa: E731
    if isinstance(texture, moderngl.Texture):
        w, h = texture.size
        count = int(math.floor(math.log2(max(w, h)))) + 1 if mipmapped else 1
        levels = []
        for k in range(count):
            lw, lh = max(1, w >> k), max(1, h >> k)
            data = np.frombuffer(texture.read(level=k), dtype=np.float32)
            levels.append(data.reshape(1, lh, lw, c).copy())
        kind, wraps = "2d", {"s": wrap(texture.repeat_x), "t": wrap(texture.repeat_y)}
    else:
        if mipmapped:
            raise PrefilterError(f"sampler {sampler}: mipmapped array and 3D textures cannot be exported yet")
        w, h, d = texture.size
        levels = [np.frombuffer(texture.read(), dtype=np.float32).reshape(d, h, w, c).copy()]
        kind = "2d_array" if isinstance(texture, moderngl.TextureArray) else "3d"
        wraps = {"s": wrap(texture.repeat_x), "t": wrap(texture.repeat_y)}
        if kind == "3d":
            wraps["r"] = wrap(texture.repeat_z)
    anisotropy = float(getattr(texture, "anisotropy", 1.0) or 1.0)
    return Table(sampler, kind, levels, (_FILTERS[min_filter], _FILTERS[mag_filter]), wraps, anisotropy)


def write_table_exr(path: Path, level: np.ndarray) -> None:
    """One level, layers stacked top to bottom (row k*height + j = row j of layer k), uncompressed float32."""
    import OpenEXR

    depth, height, width, components = level.shape
    image = level.reshape(depth * height, width, components)
    channels = {CHANNELS[i]: np.ascontiguousarray(image[..., i]) for i in range(components)}
    header = {"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, channels).write(str(path))


def read_table_exr(path: Path, components: int, depth: int) -> np.ndarray:
    """Inverse of write_table_exr: (depth, height, width, components) float32."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as exr:
        channels = exr.channels()
        planes = [np.asarray(channels[CHANNELS[i]].pixels, dtype=np.float32) for i in range(components)]
    image = np.stack(planes, axis=-1)
    return image.reshape(depth, image.shape[0] // depth, image.shape[1], components)


# -- capture -----------------------------------------------------------------------------------------


@dataclass
class CapturedObject:
    obj: SceneObject
    directory: str
    vertices: np.ndarray
    indices: np.ndarray
    shaders: dict[str, dict[str, tuple[str, str]]]  # mode -> target -> (vertex source, fragment source)
    declarations: dict[str, Uniform]
    uniforms: dict[str, dict[str, list]]
    tables: dict[str, Table]
    parameters: list[dict]
    view: dict[str, list] = field(default_factory=dict)


def _record(obj: SceneObject, resources, t: float, options: RenderOptions) -> BindingRecorder:
    recorder = BindingRecorder()
    obj.material.bind(recorder, resources, t, options)
    return recorder


def capture_object(
    ctx: moderngl.Context,
    scene: Scene,
    obj: SceneObject,
    directory: str,
    modes: list[str],
    options: RenderOptions,
) -> CapturedObject:
    mesh = build_mesh(obj)
    resources = obj.material.upload(ctx, mesh)
    try:
        start, end = _record(obj, resources, 0.0, options), _record(obj, resources, 1.0, options)
        tables = {name: read_table(name, tex) for name, tex in start.textures.items()}
    finally:
        obj.material.release(resources)
    light_count = min(len(scene.lights), MAX_LIGHTS)
    vertex_path, fragment_path = obj.material.shader_sources()
    shaders: dict[str, dict[str, tuple[str, str]]] = {}
    declarations: dict[str, Uniform] = {}
    for mode in modes:
        defines = program_defines(obj, mode, light_count, options)
        shaders[mode] = {}
        for target in EXPORT_TARGETS:
            stages = [
                assemble(path, target, defines, stage=stage, line_directives=True)
                for stage, path in (("vertex", vertex_path), ("fragment", fragment_path))
            ]
            shaders[mode][target] = (stages[0].source, stages[1].source)
            if target == EXPORT_TARGETS[0]:
                for stage in stages:
                    for name, u in uniform_declarations(stage).items():
                        declarations.setdefault(name, u)
    uniforms = {}
    for name, value in start.values.items():
        if name in start.textures:
            continue
        entry = {"value": _flat(value)}
        u = declarations.get(name)
        if u is not None:  # the GLSL type, for engines without reflection
            entry["type"] = u.type
            size = GLSL_COMPONENTS.get(u.type)
            entry["array"] = len(entry["value"]) // size if u.array and size else None
        moved = _flat(end.values.get(name, value))
        if moved != entry["value"]:
            entry["end"] = moved
        uniforms[name] = entry
    parameters = []
    for name, u in declarations.items():
        p = parameter(u)
        if p is not None and name in uniforms:
            parameters.append(p.as_json())
    w, h = scene.size
    camera = scene.camera.at(0.0)
    clip_from_world = camera.projection_matrix(w / h) @ camera.view_matrix()
    view = {k: _flat(v) for k, v in frame_uniforms(scene, obj, clip_from_world, camera, 0.0).items()}
    return CapturedObject(
        obj,
        directory,
        np.ascontiguousarray(mesh.interleaved(), dtype=np.float32),
        np.ascontiguousarray(mesh.indices, dtype=np.uint32),
        shaders,
        declarations,
        uniforms,
        tables,
        parameters,
        view,
    )


def mode_kinds(scene: Scene) -> list[dict[str, str]]:
    filtered = scene.technique_modes()
    return [
        {"name": m, "kind": "base" if m in BASE_MODES else "filtered" if m in filtered else "diagnostic"}
        for m in scene_modes(scene, diagnostics=True)
    ]


def capture_scene(scene: Scene, options: RenderOptions | None = None) -> list[CapturedObject]:
    options = options or RenderOptions()
    ctx = gl_context()
    modes = [m["name"] for m in mode_kinds(scene)]
    captured, used = [], set()
    for obj in scene.objects:
        directory = file_safe(obj.name)
        while directory in used:
            directory += "_"
        used.add(directory)
        captured.append(capture_object(ctx, scene, obj, directory, modes, options))
    return captured


# -- writing -----------------------------------------------------------------------------------------


def _vec(v) -> list[float] | None:
    return None if v is None else [float(x) for x in v]


def manifest(scene: Scene, captured: list[CapturedObject]) -> dict:
    cam = scene.camera
    stride = 4 * sum(n for _, n in VERTEX_LAYOUT)
    attributes, offset = [], 0
    for name, n in VERTEX_LAYOUT:
        attributes.append({"name": name, "size": n, "offset": offset})
        offset += 4 * n
    objects = []
    for c in captured:
        d = c.directory
        objects.append(
            {
                "name": c.obj.name,
                "directory": d,
                "world_from_object": np.asarray(c.obj.world_from_object, float).tolist(),
                "blend": c.obj.blend,
                "double_sided": c.obj.double_sided,
                "lit": c.obj.lit,
                "mesh": {
                    "vertices": f"meshes/{d}.vertices.bin",
                    "indices": f"meshes/{d}.indices.bin",
                    "vertex_count": len(c.vertices),
                    "index_count": int(c.indices.size),
                    "stride": stride,
                    "attributes": attributes,
                },
                "shaders": {
                    mode: {
                        t: {
                            "vertex": f"shaders/{d}/{mode}.{t}.vert",
                            "fragment": f"shaders/{d}/{mode}.{t}.frag",
                        }
                        for t in targets
                    }
                    for mode, targets in c.shaders.items()
                },
                "uniforms": c.uniforms,
                "samplers": {name: f"tables/{d}/{name}.json" for name in c.tables},
                "parameters": c.parameters,
                "view": c.view,
            }
        )
    return {
        "format": FORMAT,
        "scene": {
            "name": scene.name,
            "description": scene.description,
            "tags": list(scene.tags),
            "size": list(scene.size),
            "background": _vec(scene.background),
            "ambient": float(scene.ambient),
            "frames": scene.frames,
        },
        "camera": {
            "eye": _vec(cam.eye),
            "target": _vec(cam.target),
            "up": _vec(cam.up),
            "fov": float(cam.fov),
            "near": float(cam.near),
            "far": float(cam.far),
            "projection": cam.projection,
            "height": float(cam.height),
            "eye_end": _vec(cam.eye_end),
            "target_end": _vec(cam.target_end),
        },
        "lights": [
            {"direction": _vec(x.direction), "colour": _vec(x.colour), "direction_end": _vec(x.direction_end)}
            for x in scene.lights
        ],
        "modes": mode_kinds(scene),
        "reference": REFERENCE,
        "objects": objects,
    }


def _write_object(root: Path, c: CapturedObject) -> None:
    d = c.directory
    (root / "meshes").mkdir(exist_ok=True)
    (root / "meshes" / f"{d}.vertices.bin").write_bytes(c.vertices.astype("<f4").tobytes())
    (root / "meshes" / f"{d}.indices.bin").write_bytes(c.indices.astype("<u4").tobytes())
    shader_dir = root / "shaders" / d
    shader_dir.mkdir(parents=True)
    for mode, targets in c.shaders.items():
        for target, (vertex, fragment) in targets.items():
            (shader_dir / f"{mode}.{target}.vert").write_text(vertex)
            (shader_dir / f"{mode}.{target}.frag").write_text(fragment)
    table_dir = root / "tables" / d
    table_dir.mkdir(parents=True)
    values = {name: u["value"] for name, u in c.uniforms.items()}
    for name, table in c.tables.items():
        u = c.declarations.get(name)
        description = (table_description(u) if u else None) or ""
        related = {k: values[k] for k in referenced_uniforms(description, set(values))}
        (table_dir / f"{name}.json").write_text(json.dumps(table.metadata(description, related), indent=1))
        for k, level in enumerate(table.levels):
            write_table_exr(table_dir / f"{name}.{k}.exr", level)


def export_scene(scene: Scene, out: Path, options: RenderOptions | None = None) -> Path:
    """Write the bundle to `out` atomically: staged beside it, then renamed into place.

    An existing `out` is replaced only if it is an export bundle (has a scene.json of this format).
    """
    out = Path(out)
    check_replaceable(
        out, "scene.json", lambda manifest: manifest.get("format") == FORMAT, "an export bundle"
    )
    captured = capture_scene(scene, options)
    data = manifest(scene, captured)
    out.parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        for c in captured:
            _write_object(stage, c)
        (stage / "scene.json").write_text(json.dumps(data, indent=1))
        (stage / "README.md").write_text(bundle_readme(scene, data, captured))
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", dir=out.parent))
            out.rename(old / "bundle")
            shutil.rmtree(old)
        stage.rename(out)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    return out
