"""Scene files: TOML -> dataclasses, with errors that name the file, the key path and what was expected.

A scene has a camera (look-at, vertical fov or orthographic height, optional end pose for flights),
directional lights, a background, and objects (a primitive or a mesh file, a transform, a material).
Materials are looked up by `type` in MATERIAL_TYPES; each technique registers its own parser.
Built-in presets live in src/prefilter/scenes/*.toml; `resolve_scene` takes a preset name or a path.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from prefilter import PrefilterError
from prefilter.registry import check_parameters

PRESET_DIR = Path(__file__).resolve().parent / "scenes"


class SceneError(PrefilterError):
    """Invalid scene file: the message is `file: key.path: what was expected`."""


def _bounds(lo: float | None, hi: float | None) -> str:
    if lo is not None and hi is not None:
        return f"in [{lo}, {hi}]"
    return f">= {lo}" if lo is not None else f"<= {hi}"


class Reader:
    """Typed access to a TOML table that reports `file: key.path: problem` on bad input."""

    def __init__(self, table: dict[str, Any], path: str, source: str):
        self.table, self.path, self.source = table, path, source
        self.used: set[str] = set()

    def fail(self, key: str | None, problem: str) -> SceneError:
        where = f"{self.path}.{key}" if self.path and key else (key or self.path or "<top>")
        return SceneError(f"{self.source}: {where}: {problem}")

    def has(self, key: str) -> bool:
        return key in self.table

    def _get(self, key: str, default: Any, required: bool) -> Any:
        self.used.add(key)
        if key not in self.table:
            if required:
                raise self.fail(key, "missing (required)")
            return default
        return self.table[key]

    def number(
        self,
        key: str,
        default: float | None = None,
        *,
        lo: float | None = None,
        hi: float | None = None,
        required: bool = False,
    ) -> float:
        value = self._get(key, default, required)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(key, f"expected a number, got {value!r}")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise self.fail(key, f"expected a number {_bounds(lo, hi)}, got {value!r}")
        return float(value)

    def integer(
        self,
        key: str,
        default: int | None = None,
        *,
        lo: int | None = None,
        hi: int | None = None,
        required: bool = False,
    ) -> int:
        value = self._get(key, default, required)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(key, f"expected an integer, got {value!r}")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise self.fail(key, f"expected an integer {_bounds(lo, hi)}, got {value!r}")
        return value

    def boolean(self, key: str, default: bool = False) -> bool:
        value = self._get(key, default, False)
        if not isinstance(value, bool):
            raise self.fail(key, f"expected true or false, got {value!r}")
        return value

    def string(
        self,
        key: str,
        default: str | None = None,
        *,
        choices: tuple[str, ...] | None = None,
        required: bool = False,
    ) -> str:
        value = self._get(key, default, required)
        if not isinstance(value, str):
            raise self.fail(key, f"expected a string, got {value!r}")
        if choices and value not in choices:
            raise self.fail(key, f"expected one of {', '.join(choices)}, got {value!r}")
        return value

    def vector(self, key: str, length: int, default: Any = None, required: bool = False) -> np.ndarray:
        value = self._get(key, default, required)
        if isinstance(value, int | float) and not isinstance(value, bool):
            value = [value] * length
        if (
            not isinstance(value, list)
            or len(value) != length
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
        ):
            raise self.fail(key, f"expected a list of {length} numbers, got {value!r}")
        return np.asarray(value, dtype=np.float64)

    def matrix(self, key: str, rows: int, cols: int, default: Any = None) -> np.ndarray:
        value = self._get(key, default, False)
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise self.fail(key, f"expected a {rows}x{cols} matrix of numbers, got {value!r}") from None
        if arr.shape != (rows, cols):
            raise self.fail(
                key, f"expected a {rows}x{cols} matrix (list of {rows} rows), got shape {arr.shape}"
            )
        return arr

    def colour(self, key: str, default: Any = None, required: bool = False) -> np.ndarray:
        """An sRGB colour as '#rrggbb' or [r, g, b] in [0, 1]; returned linear."""
        from prefilter.colormap.table import parse_srgb

        value = self._get(key, default, required)
        try:
            return parse_srgb(value)[:3]
        except PrefilterError as exc:
            raise self.fail(key, str(exc)) from None

    def child(self, key: str, required: bool = False) -> Reader | None:
        value = self._get(key, None, required)
        if value is None:
            return None
        if not isinstance(value, dict):
            raise self.fail(key, f"expected a table, got {value!r}")
        return Reader(value, f"{self.path}.{key}" if self.path else key, self.source)

    def children(self, key: str) -> list[Reader]:
        value = self._get(key, [], False)
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.fail(key, "expected an array of tables ([[...]])")
        base = f"{self.path}.{key}" if self.path else key
        return [Reader(v, f"{base}[{i}]", self.source) for i, v in enumerate(value)]

    def raw(self, key: str, default: Any = None) -> Any:
        return self._get(key, default, False)

    def finish(self) -> None:
        unknown = sorted(set(self.table) - self.used)
        if unknown:
            raise self.fail(unknown[0], f"unknown key (known here: {', '.join(sorted(self.used))})")


@dataclass
class Camera:
    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    fov: float = 40.0  # vertical, degrees (perspective)
    near: float = 0.05
    far: float = 20000.0
    projection: str = "perspective"
    height: float = 2.0  # view height in world units (orthographic)
    eye_end: np.ndarray | None = None  # pose at animation time t = 1 (camera flights)
    target_end: np.ndarray | None = None

    def at(self, t: float) -> Camera:
        eye = self.eye if self.eye_end is None else (1 - t) * self.eye + t * self.eye_end
        target = self.target if self.target_end is None else (1 - t) * self.target + t * self.target_end
        return replace(self, eye=eye, target=target)

    def view_matrix(self) -> np.ndarray:
        """cameraFromWorld (right-handed, camera looks down -z)."""
        forward = self.target - self.eye
        forward = forward / np.linalg.norm(forward)
        right = np.cross(forward, self.up)
        right = right / np.linalg.norm(right)
        up = np.cross(right, forward)
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = right, up, -forward
        m[:3, 3] = -m[:3, :3] @ self.eye
        return m

    def projection_matrix(self, aspect: float) -> np.ndarray:
        """clipFromCamera (OpenGL conventions)."""
        n, f = self.near, self.far
        m = np.zeros((4, 4))
        if self.projection == "orthographic":
            h = self.height / 2
            m[0, 0], m[1, 1] = 1 / (h * aspect), 1 / h
            m[2, 2], m[2, 3], m[3, 3] = -2 / (f - n), -(f + n) / (f - n), 1
            return m
        t = 1 / math.tan(math.radians(self.fov) / 2)
        m[0, 0], m[1, 1] = t / aspect, t
        m[2, 2], m[2, 3], m[3, 2] = -(f + n) / (f - n), -2 * f * n / (f - n), -1
        return m


@dataclass
class Light:
    direction: np.ndarray  # world space, unit, towards the light
    colour: np.ndarray  # linear RGB, intensity folded in
    direction_end: np.ndarray | None = None  # at animation time t = 1 (moving lights)

    def at(self, t: float) -> Light:
        if self.direction_end is None:
            return self
        d = (1 - t) * self.direction + t * self.direction_end
        return replace(self, direction=d / np.linalg.norm(d), direction_end=None)


@dataclass
class SceneObject:
    name: str
    shape: str  # primitive kind, or "mesh"
    shape_params: dict[str, Any]
    mesh_path: Path | None
    world_from_object: np.ndarray
    material: Any
    blend: str = "opaque"  # or "over" (premultiplied alpha compositing, drawn after opaque objects)
    double_sided: bool = False
    lit: bool = True
    source: str = ""  # where the scene file defines it ("file: object[i]"), for errors found when it is built


@dataclass
class Scene:
    name: str
    description: str
    source: str
    size: tuple[int, int]
    background: np.ndarray
    ambient: float
    camera: Camera
    lights: list[Light]
    objects: list[SceneObject]
    frames: int = 1
    tags: list[str] = field(default_factory=list)

    def technique_modes(self) -> list[str]:
        modes: list[str] = []
        for obj in self.objects:
            for mode in obj.material.modes():
                if mode not in modes:
                    modes.append(mode)
        return modes


MaterialParser = Callable[[Reader, Path], Any]
MATERIAL_TYPES: dict[str, MaterialParser] = {}


def register_material(name: str) -> Callable[[MaterialParser], MaterialParser]:
    def wrap(fn: MaterialParser) -> MaterialParser:
        MATERIAL_TYPES[name] = fn
        return fn

    return wrap


def _transform(r: Reader) -> np.ndarray:
    """worldFromObject = T * Rz * Ry * Rx * S from translate / rotate (degrees, XYZ) / scale."""
    scale = r.vector("scale", 3, default=[1.0, 1.0, 1.0])
    if not np.all(scale != 0.0):
        raise r.fail("scale", f"must be non-zero on every axis, got {list(scale)}")
    angles = np.radians(r.vector("rotate", 3, default=[0.0, 0.0, 0.0]))
    translate = r.vector("translate", 3, default=[0.0, 0.0, 0.0])
    cx, cy, cz = np.cos(angles)
    sx, sy, sz = np.sin(angles)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx @ np.diag(scale)
    m[:3, 3] = translate
    return m


def parse_scene(text: str, source: str, base_dir: Path) -> Scene:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{source}: TOML syntax error: {exc}") from None
    import prefilter.colormap.tabulated  # noqa: F401  (registers the material types)
    import prefilter.diffraction.material  # noqa: F401
    import prefilter.microsurface.material  # noqa: F401
    import prefilter.normals.material  # noqa: F401
    import prefilter.procedural.hart  # noqa: F401

    top = Reader(data, "", source)
    name = top.string("name", Path(source).stem)
    description = top.string("description", "")
    size = top.vector("size", 2, default=[512, 384])
    if any(v < 8 or v > 8192 or v != int(v) for v in size):
        raise top.fail("size", f"expected two integers in [8, 8192], got {list(size)}")
    background = top.colour("background", "#000000")
    ambient = top.number("ambient", 0.25, lo=0.0, hi=1.0)
    frames = top.integer("frames", 1, lo=1, hi=10000)
    tags = top.raw("tags", [])
    if not isinstance(tags, list) or not all(isinstance(t, str) for t in tags):
        raise top.fail("tags", "expected a list of strings")

    cam = top.child("camera", required=True)
    assert cam is not None
    camera = Camera(
        eye=cam.vector("eye", 3, required=True),
        target=cam.vector("target", 3, required=True),
        up=cam.vector("up", 3, default=[0.0, 1.0, 0.0]),
        fov=cam.number("fov", 40.0, lo=1.0, hi=170.0),
        near=cam.number("near", 0.05, lo=1e-5),
        far=cam.number("far", 20000.0, lo=1e-3),
        projection=cam.string("projection", "perspective", choices=("perspective", "orthographic")),
        height=cam.number("height", 2.0, lo=1e-6),
        eye_end=cam.vector("eye_end", 3) if cam.has("eye_end") else None,
        target_end=cam.vector("target_end", 3) if cam.has("target_end") else None,
    )
    if camera.far <= camera.near:
        raise cam.fail("far", f"must be greater than near ({camera.near})")
    if np.linalg.norm(camera.target - camera.eye) == 0:
        raise cam.fail("target", "must differ from eye")
    up = camera.up / max(np.linalg.norm(camera.up), 1e-300)
    for t in np.linspace(0.0, 1.0, 9 if camera.eye_end is not None or camera.target_end is not None else 1):
        pose = camera.at(float(t))
        forward = (pose.target - pose.eye) / max(np.linalg.norm(pose.target - pose.eye), 1e-300)
        if np.linalg.norm(np.cross(forward, up)) <= 1e-9:  # the view matrix's right = forward × up: none
            at = f" at t = {t:g} of the flight" if t > 0 else ""
            raise cam.fail("up", f"must not be parallel to the view direction (target - eye){at}")
    cam.finish()

    lights = []
    for lr in top.children("light"):
        direction = lr.vector("direction", 3, required=True)
        if np.linalg.norm(direction) == 0:
            raise lr.fail("direction", "must be non-zero")
        colour = lr.colour("colour", "#ffffff") * lr.number("intensity", 1.0, lo=0.0)
        end = None
        if lr.has("direction_end"):
            end = lr.vector("direction_end", 3)
            if np.linalg.norm(end) == 0:
                raise lr.fail("direction_end", "must be non-zero")
            end = end / np.linalg.norm(end)
        lights.append(Light(direction / np.linalg.norm(direction), colour, end))
        lr.finish()

    objects = []
    object_readers = top.children("object")
    if not object_readers:
        raise top.fail("object", "a scene needs at least one [[object]]")
    for i, orr in enumerate(object_readers):
        objects.append(_parse_object(orr, i, base_dir))
    top.finish()
    return Scene(
        name,
        description,
        source,
        (int(size[0]), int(size[1])),
        background,
        ambient,
        camera,
        lights,
        objects,
        frames,
        tags,
    )


def _parse_object(r: Reader, index: int, base_dir: Path) -> SceneObject:
    from prefilter.geometry import PRIMITIVES

    shape = r.string("shape", "mesh" if r.has("mesh") else None, required=not r.has("mesh"))
    mesh_path = None
    if shape == "mesh":
        mesh_path = Path(r.string("mesh", required=True))
        mesh_path = mesh_path if mesh_path.is_absolute() else base_dir / mesh_path
        if not mesh_path.is_file():
            raise r.fail("mesh", f"file not found: {mesh_path}")
    elif shape not in PRIMITIVES:
        raise r.fail(
            "shape", f"expected one of {', '.join(sorted(PRIMITIVES))} or mesh = 'file', got {shape!r}"
        )
    params = r.raw("params", {})
    if not isinstance(params, dict):
        raise r.fail("params", "expected a table of primitive parameters")
    if shape != "mesh":
        try:
            check_parameters(PRIMITIVES, "primitive", shape, params)
        except PrefilterError as exc:
            raise r.fail("params", str(exc)) from None
    mat = r.child("material", required=True)
    assert mat is not None
    kind = mat.string("type", "hart", choices=tuple(MATERIAL_TYPES))
    material = MATERIAL_TYPES[kind](mat, base_dir)
    mat.finish()
    obj = SceneObject(
        name=r.string("name", f"object{index}"),
        shape=shape,
        shape_params=params,
        mesh_path=mesh_path,
        world_from_object=_transform(r),
        material=material,
        blend=r.string("blend", "opaque", choices=("opaque", "over")),
        double_sided=r.boolean("double_sided", False),
        lit=r.boolean("lit", True),
        source=f"{r.source}: {r.path}",
    )
    r.finish()
    return obj


def load_scene(path: str | Path) -> Scene:
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise SceneError(f"{path}: cannot read scene file ({exc.strerror})") from None
    return parse_scene(text, str(path), path.parent)


def preset_names() -> list[str]:
    return sorted(p.stem for p in PRESET_DIR.glob("*.toml"))


def resolve_scene(name_or_path: str) -> Scene:
    """A preset name (see `prefilter list`) or a path to a .toml file."""
    preset = PRESET_DIR / f"{name_or_path}.toml"
    if preset.is_file():
        return load_scene(preset)
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        return load_scene(path)
    raise SceneError(f"{name_or_path}: no such preset or scene file (presets: {', '.join(preset_names())})")
