"""Triangle meshes for rendering: primitives, the Utah teapot, trimesh loading, tangent frames.

Every mesh is a `Mesh` of float32 per-vertex arrays (position, unit normal, tangent with handedness in w,
uv) and uint32 triangles wound counter-clockwise seen from outside. y is up. The tangent frame is
right-handed when w = +1: bitangent = w * cross(normal, tangent.xyz) (the glTF/MikkTSpace convention);
tangent.xyz points along dP/du and the bitangent along dP/dv.

Primitives (`make_primitive(kind, **params)`):
  plane(size=2, subdivisions=1)            xz square, normal +y, u along +x, v along -z, uv in [0,1]
  plane_horizon(extent=5000, subdivisions=64, inner=0.1)
                                           xz square reaching |x|, |z| = extent; grid lines are spaced
                                           geometrically (first cell `inner` wide, each next one q times
                                           wider); uv = (0.5 + x/2, 0.5 - z/2), so it coincides with
                                           plane(size=2) over [-1,1]^2
  sphere(radius=1, segments=64, rings=32)  UV sphere; u = azimuth/2pi from +x towards -z, v = 0 at the
                                           south pole (-y) to 1 at the north pole; seam at u = 0 / 1
  torus(major=1, minor=0.4, segments=96, sides=48)
                                           around the y axis; u around y as for the sphere, v around the tube
                                           starting at the outer equator, going up
  cube(size=2)                             24 vertices, flat normals, each face uv in [0,1]
  teapot()                                 Utah teapot OBJ (see `teapot_path`), centred, largest half-extent 1
Meshes read from files without uvs (and the teapot) get a spherical projection about the bounding-box
centre (the sphere's convention above), with vertices split along the seam and at the poles.
"""

from __future__ import annotations

import math
import numbers
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from prefilter import PrefilterError
from prefilter.registry import call_registered

# Layout of `Mesh.interleaved()`: (vertex attribute, float count) in order.
VERTEX_LAYOUT = (("in_pos", 3), ("in_nrm", 3), ("in_tan", 4), ("in_uv", 2))

SUPPORTED_MESH_FORMATS = (".obj", ".ply", ".stl", ".glb", ".gltf")

REPO_ROOT = Path(__file__).resolve().parents[2]
ASSETS_ENV = "PREFILTER_ASSETS"


@dataclass
class Mesh:
    """An indexed triangle mesh in object space; arrays are coerced to contiguous float32/uint32."""

    positions: np.ndarray  # (n, 3) float32
    normals: np.ndarray  # (n, 3) float32, unit
    tangents: np.ndarray  # (n, 4) float32, xyz unit and orthogonal to the normal, w = handedness +-1
    uvs: np.ndarray  # (n, 2) float32
    indices: np.ndarray  # (m, 3) uint32, counter-clockwise seen from outside

    def __post_init__(self) -> None:
        self.positions = np.ascontiguousarray(self.positions, dtype=np.float32)
        self.normals = np.ascontiguousarray(self.normals, dtype=np.float32)
        self.tangents = np.ascontiguousarray(self.tangents, dtype=np.float32)
        self.uvs = np.ascontiguousarray(self.uvs, dtype=np.float32)
        self.indices = np.ascontiguousarray(self.indices, dtype=np.uint32)
        n = len(self.positions)
        for name, width in (("positions", 3), ("normals", 3), ("tangents", 4), ("uvs", 2)):
            shape = getattr(self, name).shape
            if shape != (n, width):
                raise ValueError(f"Mesh.{name} has shape {shape}, expected ({n}, {width})")
        if self.indices.ndim != 2 or self.indices.shape[1] != 3:
            raise ValueError(f"Mesh.indices has shape {self.indices.shape}, expected (m, 3)")
        if self.indices.size and int(self.indices.max()) >= n:
            raise ValueError(f"Mesh.indices refers to vertex {int(self.indices.max())} of {n}")

    def interleaved(self) -> np.ndarray:
        """(n, 12) float32 rows [position xyz, normal xyz, tangent xyzw, uv] (see VERTEX_LAYOUT)."""
        return np.hstack([self.positions, self.normals, self.tangents, self.uvs]).astype(np.float32)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounding box (min xyz, max xyz) of the vertex positions."""
        return self.positions.min(axis=0), self.positions.max(axis=0)


# ----------------------------------------------------------------------------------------------------------
# Tangents


def compute_tangents(
    positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray, indices: np.ndarray
) -> np.ndarray:
    """Per-vertex tangents (n, 4) float32 from the uv parameterisation (Lengyel 2001).

    Each triangle's dP/du and dP/dv (solved from its edges and uv differences) are normalised, weighted
    by the triangle's angle at the corner (as MikkTSpace does) and summed at its corners. The sum of dP/du
    is made orthogonal to the normal (Gram-Schmidt); w = +1 when cross(normal, tangent) points along the
    summed dP/dv, else -1. Where the uvs give no usable dP/du (degenerate uvs, or a mirror seam where the
    two sides cancel), the tangent is cross(dP/dv, normal) if dP/dv is usable, otherwise an arbitrary
    unit vector orthogonal to the normal; w = +1 in both cases.
    """
    p = np.asarray(positions, dtype=np.float64)
    nrm = np.asarray(normals, dtype=np.float64)
    t = np.asarray(uvs, dtype=np.float64)
    f = np.asarray(indices, dtype=np.int64).reshape(-1, 3)
    n_vertices = len(p)

    e1 = p[f[:, 1]] - p[f[:, 0]]
    e2 = p[f[:, 2]] - p[f[:, 0]]
    d1 = t[f[:, 1]] - t[f[:, 0]]
    d2 = t[f[:, 2]] - t[f[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    # det * dP/du and det * dP/dv; only their directions are used, so the sign of det is put back below.
    sdir = d2[:, 1, None] * e1 - d1[:, 1, None] * e2
    tdir = d1[:, 0, None] * e2 - d2[:, 0, None] * e1
    uv_scale = np.linalg.norm(d1, axis=1) * np.linalg.norm(d2, axis=1)
    usable = np.abs(det) > 1e-9 * uv_scale
    sign = np.where(usable, np.sign(det), 0.0)
    sdir = _unit(sdir) * sign[:, None]
    tdir = _unit(tdir) * sign[:, None]

    acc_t = np.zeros((n_vertices, 3))
    acc_b = np.zeros((n_vertices, 3))
    acc_w = np.zeros(n_vertices)
    corners = p[f]
    for k in range(3):
        # weight = the triangle's angle at this corner (as MikkTSpace), so splitting a quad either way
        # gives the same sum and a mirror seam cancels exactly
        a = _unit(corners[:, (k + 1) % 3] - corners[:, k])
        b = _unit(corners[:, (k + 2) % 3] - corners[:, k])
        angle = np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0))
        np.add.at(acc_t, f[:, k], sdir * angle[:, None])
        np.add.at(acc_b, f[:, k], tdir * angle[:, None])
        np.add.at(acc_w, f[:, k], angle * usable)

    tan = acc_t - nrm * np.sum(nrm * acc_t, axis=1, keepdims=True)
    bit = acc_b - nrm * np.sum(nrm * acc_b, axis=1, keepdims=True)
    tan_len = np.linalg.norm(tan, axis=1)
    bit_len = np.linalg.norm(bit, axis=1)
    tan_ok = tan_len > 1e-6 * acc_w  # acc_w: the most the sum of unit vectors could reach
    bit_ok = bit_len > 1e-6 * acc_w

    # Fallback 1: only dP/dv is usable -> tangent completes the right-handed frame (w = +1).
    from_b = ~tan_ok & bit_ok
    tan[from_b] = np.cross(bit[from_b], nrm[from_b])
    # Fallback 2: nothing usable -> any unit vector orthogonal to the normal.
    none = ~tan_ok & ~bit_ok
    if np.any(none):
        n_none = nrm[none]
        axis = np.zeros_like(n_none)
        axis[np.arange(len(n_none)), np.argmin(np.abs(n_none), axis=1)] = 1.0
        tan[none] = axis - n_none * np.sum(n_none * axis, axis=1, keepdims=True)
    tan = _unit(tan)

    w = np.where(np.sum(np.cross(nrm, tan) * acc_b, axis=1) < 0.0, -1.0, 1.0)
    w[~tan_ok] = 1.0
    return np.hstack([tan, w[:, None]]).astype(np.float32)


# ----------------------------------------------------------------------------------------------------------
# Primitives


def plane(size: float = 2.0, subdivisions: int = 1) -> Mesh:
    """Square of side `size` in the xz-plane, normal +y, split into subdivisions^2 quads.

    u = (x + size/2) / size, v = (size/2 - z) / size: u runs along +x and v along -z, so that seen from
    above with -z up the texture is upright and the frame (tangent +x, bitangent -z, normal +y) has w = +1.
    """
    size = _positive("plane", "size", size)
    n = _count("plane", "subdivisions", subdivisions, 1)
    s = np.linspace(0.0, 1.0, n + 1)
    u, v = np.meshgrid(s, s)  # (n+1, n+1), u varies fastest
    u, v = u.ravel(), v.ravel()
    positions = np.stack([(u - 0.5) * size, np.zeros_like(u), (0.5 - v) * size], axis=1)
    return _flat_grid(positions, np.stack([u, v], axis=1), _grid_faces(n, n).reshape(-1, 3))


def plane_horizon(extent: float = 5000.0, subdivisions: int = 64, inner: float = 0.1) -> Mesh:
    """Ground plane (xz, normal +y) reaching |x|, |z| = `extent`, for cameras near the ground.

    Each axis has `subdivisions` cells (rounded up to even), half on each side of the origin. Cell widths
    grow geometrically from `inner` next to the centre by a ratio q chosen so that they sum to `extent`
    (q = 1, uniform cells, if inner * subdivisions/2 >= extent). Cells therefore subtend roughly equal
    angles from a viewpoint above the centre, the near triangles stay small and the far ones reach the
    horizon. uv = (0.5 + x/2, 0.5 - z/2): the same texture mapping as plane(size=2) where they overlap,
    with the same frame (tangent +x, w = +1). At the rim |uv| ~ extent/2, where float32 resolves about
    2.5e-4 uv units for extent 5000.
    """
    extent = _positive("plane_horizon", "extent", extent)
    inner = _positive("plane_horizon", "inner", inner)
    half = (_count("plane_horizon", "subdivisions", subdivisions, 2) + 1) // 2
    steps = inner * _geometric_ratio(extent / inner, half) ** np.arange(half)
    radii = np.cumsum(steps)
    radii *= extent / radii[-1]  # exact rim despite rounding in the ratio
    coords = np.concatenate([-radii[::-1], [0.0], radii])
    n = 2 * half
    x, negz = np.meshgrid(coords, coords)  # x varies fastest, rows run towards -z
    x, negz = x.ravel(), negz.ravel()
    positions = np.stack([x, np.zeros_like(x), -negz], axis=1)
    uvs = np.stack([0.5 + 0.5 * x, 0.5 + 0.5 * negz], axis=1)
    return _flat_grid(positions, uvs, _grid_faces(n, n).reshape(-1, 3))


def sphere(radius: float = 1.0, segments: int = 64, rings: int = 32) -> Mesh:
    """UV sphere: `segments` around the y axis, `rings` from pole to pole; analytic normals and tangents.

    P(u, v) = r (sin(theta) cos(phi), cos(theta), -sin(theta) sin(phi)), phi = 2 pi u, theta = pi (1 - v).
    The seam column is duplicated (u = 0 and u = 1); each pole has one vertex per segment, at the middle u
    of its triangle, and the degenerate triangles at the poles are left out.
    """
    radius = _positive("sphere", "radius", radius)
    segments = _count("sphere", "segments", segments, 3)
    rings = _count("sphere", "rings", rings, 2)
    u, v = np.meshgrid(np.linspace(0.0, 1.0, segments + 1), np.linspace(0.0, 1.0, rings + 1))
    u[0] += 0.5 / segments  # pole vertices sit at the middle of their one triangle
    u[-1] -= 0.5 / segments
    u, v = u.ravel(), v.ravel()
    phi, theta = 2.0 * np.pi * np.mod(u, 1.0), np.pi * (1.0 - v)  # mod: seam copies coincide exactly
    normals = np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), -np.sin(theta) * np.sin(phi)], axis=1)
    normals[v == 0.0] = (0.0, -1.0, 0.0)
    normals[v == 1.0] = (0.0, 1.0, 0.0)
    tangents = np.stack([-np.sin(phi), np.zeros_like(phi), -np.cos(phi), np.ones_like(phi)], axis=1)

    faces = _grid_faces(segments, rings)  # (rings, segments, 2, 3)
    keep = np.ones(faces.shape[:3], dtype=bool)
    keep[0, :, 0] = False  # (a, b, c) with a, b both at the south pole
    keep[-1, :, 1] = False  # (a, c, d) with c, d both at the north pole
    return _compact(radius * normals, normals, tangents, np.stack([u, v], axis=1), faces[keep])


def torus(major: float = 1.0, minor: float = 0.4, segments: int = 96, sides: int = 48) -> Mesh:
    """Ring torus around the y axis: `segments` around y, `sides` around the tube; analytic frames.

    P(u, v) = ((R + r cos(psi)) cos(phi), r sin(psi), -(R + r cos(psi)) sin(phi)), phi = 2 pi u,
    psi = 2 pi v; seam vertices are duplicated on both parameters.
    """
    major = _positive("torus", "major", major)
    minor = _positive("torus", "minor", minor)
    if minor >= major:
        raise PrefilterError(f"torus: minor radius {minor} must be smaller than major radius {major}")
    segments = _count("torus", "segments", segments, 3)
    sides = _count("torus", "sides", sides, 3)
    u, v = np.meshgrid(np.linspace(0.0, 1.0, segments + 1), np.linspace(0.0, 1.0, sides + 1))
    u, v = u.ravel(), v.ravel()
    phi, psi = 2.0 * np.pi * np.mod(u, 1.0), 2.0 * np.pi * np.mod(v, 1.0)  # seam copies coincide exactly
    normals = np.stack([np.cos(psi) * np.cos(phi), np.sin(psi), -np.cos(psi) * np.sin(phi)], axis=1)
    ring = np.stack([np.cos(phi), np.zeros_like(phi), -np.sin(phi)], axis=1)
    positions = major * ring + minor * normals
    tangents = np.stack([-np.sin(phi), np.zeros_like(phi), -np.cos(phi), np.ones_like(phi)], axis=1)
    faces = _grid_faces(segments, sides).reshape(-1, 3)
    return Mesh(positions, normals, tangents, np.stack([u, v], axis=1), faces)


def cylinder(radius: float = 0.5, length: float = 3.0, segments: int = 96, rings: int = 8) -> Mesh:
    """Open tube along the x axis (a snake's body): `segments` around it, `rings` along it; analytic frames.

    P(u, v) = (length (u - 1/2), r cos(psi), -r sin(psi)), psi = 2 pi v: u runs along the axis, v around it;
    tangent dP/du = +x, bitangent dP/dv, normal outwards (right-handed, w = +1).
    """
    radius = _positive("cylinder", "radius", radius)
    length = _positive("cylinder", "length", length)
    segments = _count("cylinder", "segments", segments, 3)
    rings = _count("cylinder", "rings", rings, 1)
    u, v = np.meshgrid(np.linspace(0.0, 1.0, rings + 1), np.linspace(0.0, 1.0, segments + 1))
    u, v = u.ravel(), v.ravel()
    psi = 2.0 * np.pi * np.mod(v, 1.0)
    normals = np.stack([np.zeros_like(psi), np.cos(psi), -np.sin(psi)], axis=1)
    positions = np.stack([length * (u - 0.5), radius * normals[:, 1], radius * normals[:, 2]], axis=1)
    tangents = np.tile([1.0, 0.0, 0.0, 1.0], (len(u), 1))
    faces = _grid_faces(rings, segments).reshape(-1, 3)
    return Mesh(positions, normals, tangents, np.stack([u, v], axis=1), faces)


# (normal, tangent = dP/du, bitangent = dP/dv) per face, each right-handed: tangent x bitangent = normal.
_CUBE_FACES = (
    ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
    ((-1, 0, 0), (0, 0, 1), (0, 1, 0)),
    ((0, 1, 0), (1, 0, 0), (0, 0, -1)),
    ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
    ((0, 0, 1), (1, 0, 0), (0, 1, 0)),
    ((0, 0, -1), (-1, 0, 0), (0, 1, 0)),
)


def cube(size: float = 2.0) -> Mesh:
    """Axis-aligned cube of side `size`: 24 vertices (4 per face), flat normals, uv in [0,1] per face.

    +-x, +-z faces have v up (+y); the +y face has u along +x, v along -z, the -y face u along +x, v along
    +z. All faces have w = +1.
    """
    half = 0.5 * _positive("cube", "size", size)
    corner_uv = np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)])
    positions, normals, tangents, uvs, faces = [], [], [], [], []
    for k, (n, t, b) in enumerate(_CUBE_FACES):
        n, t, b = np.array(n, float), np.array(t, float), np.array(b, float)
        for cu, cv in corner_uv:
            positions.append(half * (n + (2.0 * cu - 1.0) * t + (2.0 * cv - 1.0) * b))
            normals.append(n)
            tangents.append([*t, 1.0])
            uvs.append((cu, cv))
        faces += [(4 * k, 4 * k + 1, 4 * k + 2), (4 * k, 4 * k + 2, 4 * k + 3)]
    return Mesh(np.array(positions), np.array(normals), np.array(tangents), np.array(uvs), np.array(faces))


def teapot_path() -> Path:
    """Where the teapot OBJ is looked for.

    $PREFILTER_ASSETS names the assets directory holding teapot.obj (a value ending in .obj is taken as
    the file itself); the default is <repo>/.cache/assets/teapot.obj, written by scripts/fetch-assets.sh.
    """
    env = os.environ.get(ASSETS_ENV)
    if env:
        path = Path(env).expanduser()
        return path if path.suffix.lower() == ".obj" else path / "teapot.obj"
    return REPO_ROOT / ".cache" / "assets" / "teapot.obj"


class MissingAsset(PrefilterError):
    """A primitive's asset is not installed (the set-up's fault, not the scene's)."""


def teapot() -> Mesh:
    """The Utah teapot (Newell 1975) with merged vertices, y up, bounding box centred on the origin and
    scaled so that its largest half-extent (along x, spout to handle) is 1.

    Normals are trimesh's smooth vertex normals, uvs a spherical projection about the origin (see the
    module docstring). The mesh is not closed: the spout and handle ends are open where they enter the
    body (about 1.7 % of the edges are boundary edges).
    """
    path = teapot_path()
    if not path.is_file():
        raise MissingAsset(f"Utah teapot asset missing at {path}; run: make setup")
    mesh = _read_trimesh(path)
    mesh.merge_vertices()
    lo, hi = mesh.bounds
    centre = 0.5 * (lo + hi)
    scale = 1.0 / (0.5 * float(np.max(hi - lo)))
    positions = (np.asarray(mesh.vertices) - centre) * scale
    normals = np.asarray(mesh.vertex_normals)  # invariant under translation and uniform scaling
    return _assemble(positions, normals, None, np.asarray(mesh.faces))


PRIMITIVES = {
    "plane": plane,
    "plane_horizon": plane_horizon,
    "sphere": sphere,
    "torus": torus,
    "cylinder": cylinder,
    "cube": cube,
    "teapot": teapot,
}


def make_primitive(kind: str, **params) -> Mesh:
    """Build the primitive `kind` (a key of PRIMITIVES) with keyword parameters `params`."""
    return call_registered(PRIMITIVES, "primitive", kind, params)


# ----------------------------------------------------------------------------------------------------------
# Loading


def _why_unreadable(path: Path, exc: Exception) -> str:
    """trimesh's error on one line; for an .obj that is not UTF-8 text, where its bytes stop being text
    (trimesh guesses the encoding of such files with a module that may be missing, and reports that)."""
    if path.suffix.lower() == ".obj":
        try:
            path.read_bytes().decode("utf-8")
        except UnicodeDecodeError as bad:
            return f"not UTF-8 text (byte 0x{bad.object[bad.start]:02x} at offset {bad.start})"
    return _one_line(exc)


def load_mesh(path: str | os.PathLike) -> Mesh:
    """Read an OBJ, PLY, STL, glTF or GLB file through trimesh into one Mesh, in the file's own units.

    All triangle meshes of the file's scene are concatenated with their scene-graph transforms applied.
    Vertices are merged where position, uv and normal agree (trimesh's processing). Normals come from the
    file when it has them, otherwise they are trimesh's smooth (area- and angle-weighted) vertex normals.
    Uvs come from the file when every part has them (glTF's V is flipped by trimesh to the OpenGL
    lower-left convention), otherwise they are a spherical projection about the bounding-box centre.
    Tangents come from `compute_tangents`. Winding is kept as it is in the file.
    """
    path = Path(path)
    if not path.exists():
        raise PrefilterError(f"mesh file not found: {path}")
    if not path.is_file():
        raise PrefilterError(f"mesh path is not a file: {path}")
    ext = path.suffix.lower()
    if ext not in SUPPORTED_MESH_FORMATS:
        raise PrefilterError(
            f"unsupported mesh format '{ext or '(no extension)'}' for {path} "
            f"(supported: {', '.join(SUPPORTED_MESH_FORMATS)})"
        )
    try:
        scene = trimesh.load_scene(str(path))
    except Exception as exc:  # trimesh's loaders raise anything from ValueError to IndexError on bad input
        raise PrefilterError(
            f"cannot read mesh {path} as {ext[1:].upper()}: {_why_unreadable(path, exc)}"
        ) from exc

    parts = []
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        geometry = scene.geometry.get(name)
        if not isinstance(geometry, trimesh.Trimesh) or len(geometry.faces) == 0:
            continue
        # Scene.to_mesh() (and so trimesh.load_mesh) copies without the cache and loses file normals.
        part = geometry.copy(include_cache=True)
        part.apply_transform(transform)
        part.remove_unreferenced_vertices()
        parts.append(part)
    if not parts:
        raise PrefilterError(f"mesh file {path} contains no triangles")

    positions, normals, uvs, faces = [], [], [], []
    offset = 0
    for part in parts:
        positions.append(np.asarray(part.vertices, dtype=np.float64))
        normals.append(np.asarray(part.vertex_normals, dtype=np.float64))
        uv = getattr(part.visual, "uv", None) if part.visual.kind == "texture" else None
        uvs.append(None if uv is None or len(uv) != len(part.vertices) else np.asarray(uv, np.float64))
        faces.append(np.asarray(part.faces, dtype=np.int64) + offset)
        offset += len(part.vertices)
    file_uvs = None if any(uv is None for uv in uvs) else np.concatenate(uvs)
    return _assemble(np.concatenate(positions), np.concatenate(normals), file_uvs, np.concatenate(faces))


def _read_trimesh(path: Path) -> trimesh.Trimesh:
    try:
        mesh = trimesh.load_mesh(str(path))
    except Exception as exc:
        raise PrefilterError(f"cannot read mesh {path}: {_one_line(exc)}") from exc
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise PrefilterError(f"mesh file {path} contains no triangles")
    return mesh


def spherical_uvs(
    positions: np.ndarray, indices: np.ndarray, centre: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spherical projection about `centre` (default: bounding-box centre), with the sphere's convention:
    u = atan2(-z, x) / 2pi in [0, 1), v = 1 - polar angle from +y / pi.

    Returns (source, uvs, indices): new vertex k copies old vertex source[k]. A triangle whose corners span
    more than half a turn in u crosses the seam; its corners with u < 1/2 get copies with u + 1. Vertices on
    the polar axis take, per triangle, the mean u of the triangle's other corners.
    """
    p = np.asarray(positions, dtype=np.float64)
    f = np.asarray(indices, dtype=np.int64).reshape(-1, 3)
    if centre is None:
        centre = 0.5 * (p.min(axis=0) + p.max(axis=0))
    d = p - centre
    r = np.linalg.norm(d, axis=1)
    u = np.mod(np.arctan2(-d[:, 2], d[:, 0]) / (2.0 * np.pi), 1.0)
    v = 1.0 - np.arccos(np.clip(d[:, 1] / np.maximum(r, 1e-300), -1.0, 1.0)) / np.pi
    v[r == 0.0] = 0.5
    pole = np.hypot(d[:, 0], d[:, 2]) <= 1e-9 * max(float(r.max()), 1e-300)

    cu = u[f]
    cpole = pole[f]
    real = ~cpole
    hi = np.where(real, cu, -np.inf).max(axis=1)
    lo = np.where(real, cu, np.inf).min(axis=1)
    seam = (hi - lo) > 0.5
    cu = np.where(seam[:, None] & real & (cu < 0.5), cu + 1.0, cu)
    count = real.sum(axis=1)
    mean = np.where(real, cu, 0.0).sum(axis=1) / np.maximum(count, 1)
    mean[count == 0] = 0.5
    cu = np.where(cpole, mean[:, None], cu)

    key = np.stack([f.ravel(), cu.ravel().view(np.int64)], axis=1)
    unique, inverse = np.unique(key, axis=0, return_inverse=True)
    source = unique[:, 0]
    uvs = np.stack([unique[:, 1].view(np.float64), v[source]], axis=1)
    return source, uvs, inverse.reshape(-1, 3)


# ----------------------------------------------------------------------------------------------------------
# Helpers


def _assemble(positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray | None, faces: np.ndarray) -> Mesh:
    """Mesh from positions, normals (any length), optional uvs (else spherical) and faces; adds tangents."""
    normals = _unit(np.asarray(normals, dtype=np.float64), fallback=(0.0, 1.0, 0.0))
    if uvs is None:
        source, uvs, faces = spherical_uvs(positions, faces)
        positions, normals = positions[source], normals[source]
    tangents = compute_tangents(positions, normals, uvs, faces)
    return Mesh(positions, normals, tangents, uvs, faces)


def _grid_faces(nu: int, nv: int) -> np.ndarray:
    """Triangles (nv, nu, 2, 3) of a grid of (nu+1) x (nv+1) vertices numbered j * (nu+1) + i.

    Counter-clockwise seen from the side dP/du x dP/dv points to.
    """
    i, j = np.meshgrid(np.arange(nu), np.arange(nv))
    a = j * (nu + 1) + i
    b, c, d = a + 1, a + nu + 2, a + nu + 1
    return np.stack([np.stack([a, b, c], axis=-1), np.stack([a, c, d], axis=-1)], axis=2)


def _flat_grid(positions: np.ndarray, uvs: np.ndarray, faces: np.ndarray) -> Mesh:
    n = len(positions)
    normals = np.tile([0.0, 1.0, 0.0], (n, 1))
    tangents = np.tile([1.0, 0.0, 0.0, 1.0], (n, 1))
    return Mesh(positions, normals, tangents, uvs, faces)


def _compact(positions, normals, tangents, uvs, faces) -> Mesh:
    """Drop the vertices no triangle uses."""
    used, faces = np.unique(faces, return_inverse=True)
    return Mesh(positions[used], normals[used], tangents[used], uvs[used], faces.reshape(-1, 3))


def _geometric_ratio(total: float, n: int) -> float:
    """q >= 1 with 1 + q + ... + q^(n-1) = total (q = 1 when total <= n), by bisection."""
    if n <= 1 or total <= n:
        return 1.0
    lo, hi = 1.0, total ** (1.0 / (n - 1)) + 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if (mid**n - 1.0) / (mid - 1.0) < total:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _unit(x: np.ndarray, fallback: tuple[float, float, float] | None = None) -> np.ndarray:
    length = np.linalg.norm(x, axis=1, keepdims=True)
    out = np.divide(x, length, out=np.zeros_like(x), where=length > 0.0)
    if fallback is not None:
        out[length[:, 0] == 0.0] = fallback
    return out


def _positive(kind: str, name: str, value) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, numbers.Real)
        or not math.isfinite(value)
        or value <= 0
    ):
        raise PrefilterError(f"{kind}: {name} must be a positive number, got {value!r}")
    return float(value)


def _count(kind: str, name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise PrefilterError(f"{kind}: {name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__
