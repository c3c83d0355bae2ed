"""Tests for prefilter.geometry: closed forms (areas, volumes, derivatives) and trimesh's own measures."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
import trimesh

from prefilter import PrefilterError
from prefilter.geometry import (
    PRIMITIVES,
    Mesh,
    compute_tangents,
    cube,
    load_mesh,
    make_primitive,
    plane,
    plane_horizon,
    sphere,
    teapot,
    teapot_path,
    torus,
)

CLOSED = ["sphere", "torus", "cube"]
ALL_BUT_TEAPOT = [k for k in PRIMITIVES if k != "teapot"]


def as_trimesh(mesh: Mesh) -> trimesh.Trimesh:
    return trimesh.Trimesh(mesh.positions.astype(np.float64), mesh.indices.astype(np.int64), process=False)


def face_normals(mesh: Mesh) -> np.ndarray:
    p = mesh.positions.astype(np.float64)[mesh.indices.astype(np.int64)]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def assert_frames_valid(mesh: Mesh, atol: float = 1e-5) -> None:
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=atol)
    np.testing.assert_allclose(np.linalg.norm(mesh.tangents[:, :3], axis=1), 1.0, atol=atol)
    np.testing.assert_allclose(np.sum(mesh.normals * mesh.tangents[:, :3], axis=1), 0.0, atol=atol)
    assert set(np.unique(mesh.tangents[:, 3])) <= {-1.0, 1.0}


def assert_normals_follow_winding(mesh: Mesh, min_dot: float) -> None:
    """The counter-clockwise face normal agrees with the mean of its corners' vertex normals."""
    corner_mean = mesh.normals[mesh.indices.astype(np.int64)].mean(axis=1)
    dots = np.sum(face_normals(mesh) * corner_mean, axis=1)
    assert dots.min() > min_dot, f"worst face normal . vertex normals = {dots.min():.3f}"


@pytest.fixture(scope="module")
def teapot_mesh() -> Mesh:
    path = teapot_path()
    if not path.is_file():
        pytest.skip(f"Utah teapot asset not found at {path} (run: make setup)")
    return teapot()


# ---------------------------------------------------------------------------------------------- Mesh


def test_mesh_coerces_types_and_interleaves():
    m = cube()
    for name in ("positions", "normals", "tangents", "uvs"):
        assert getattr(m, name).dtype == np.float32
    assert m.indices.dtype == np.uint32
    data = m.interleaved()
    assert data.shape == (24, 12) and data.dtype == np.float32 and data.flags.c_contiguous
    np.testing.assert_array_equal(data[:, 0:3], m.positions)
    np.testing.assert_array_equal(data[:, 3:6], m.normals)
    np.testing.assert_array_equal(data[:, 6:10], m.tangents)
    np.testing.assert_array_equal(data[:, 10:12], m.uvs)
    lo, hi = m.bounds()
    np.testing.assert_array_equal(lo, [-1, -1, -1])
    np.testing.assert_array_equal(hi, [1, 1, 1])


def test_mesh_rejects_inconsistent_arrays():
    m = cube()
    with pytest.raises(ValueError, match="tangents"):
        Mesh(m.positions, m.normals, m.tangents[:, :3], m.uvs, m.indices)
    with pytest.raises(ValueError, match="refers to vertex 24"):
        Mesh(m.positions, m.normals, m.tangents, m.uvs, m.indices + 1)


# -------------------------------------------------------------------------------- closed-form measures


@pytest.mark.parametrize("radius", [1.0, 2.5])
def test_sphere_area_and_volume_converge_to_closed_forms(radius):
    exact_area, exact_volume = 4 * math.pi * radius**2, 4 / 3 * math.pi * radius**3
    errors = []
    for segments, rings in [(32, 16), (64, 32)]:
        tm = as_trimesh(sphere(radius, segments, rings))
        assert trimesh.Trimesh(tm.vertices, tm.faces).is_watertight  # once the seam copies are merged
        # An inscribed polyhedron: both measures fall short, by O(1/n^2).
        assert 0 < exact_area - tm.area < 0.01 * exact_area
        assert 0 < exact_volume - tm.volume < 0.02 * exact_volume
        errors.append((exact_area - tm.area, exact_volume - tm.volume))
    (a1, v1), (a2, v2) = errors
    assert 3.5 < a1 / a2 < 4.5 and 3.5 < v1 / v2 < 4.5  # second-order convergence


def test_torus_area_and_volume_converge_to_closed_forms():
    R, r = 1.5, 0.5
    exact_area, exact_volume = 4 * math.pi**2 * R * r, 2 * math.pi**2 * R * r**2
    errors = []
    for segments, sides in [(48, 24), (96, 48)]:
        tm = as_trimesh(torus(R, r, segments, sides))
        assert trimesh.Trimesh(tm.vertices, tm.faces).is_watertight
        assert abs(tm.area - exact_area) < 0.02 * exact_area
        assert abs(tm.volume - exact_volume) < 0.02 * exact_volume
        errors.append((abs(tm.area - exact_area), abs(tm.volume - exact_volume)))
    (a1, v1), (a2, v2) = errors
    assert 3.5 < a1 / a2 < 4.5 and 3.5 < v1 / v2 < 4.5


def test_cube_measures_and_split_faces():
    m = cube(3.0)
    tm = as_trimesh(m)
    assert len(m.positions) == 24 and len(m.indices) == 12
    assert tm.volume == pytest.approx(27.0) and tm.area == pytest.approx(54.0)
    # flat normals: the 4 vertices of each face share the face's normal
    np.testing.assert_allclose(m.normals[m.indices.astype(np.int64)[:, 0]], face_normals(m), atol=1e-6)
    assert np.allclose(np.abs(m.normals).sum(axis=1), 1.0)


def test_plane_is_flat_square_with_unit_uvs():
    m = plane(size=3.0, subdivisions=4)
    assert len(m.positions) == 25 and len(m.indices) == 32
    assert as_trimesh(m).area == pytest.approx(9.0)
    np.testing.assert_array_equal(m.positions[:, 1], 0.0)
    np.testing.assert_allclose(face_normals(m), np.tile([0, 1, 0], (32, 1)), atol=1e-7)
    np.testing.assert_allclose(m.uvs[:, 0], m.positions[:, 0] / 3 + 0.5, atol=1e-7)
    np.testing.assert_allclose(m.uvs[:, 1], 0.5 - m.positions[:, 2] / 3, atol=1e-7)


# --------------------------------------------------------------------------------- normals and winding


@pytest.mark.parametrize("kind", CLOSED)
def test_closed_primitives_are_outward(kind):
    m = make_primitive(kind)
    tm = trimesh.Trimesh(m.positions, m.indices)  # merges the seam and split-face copies
    assert tm.is_watertight and tm.is_winding_consistent
    assert tm.volume > 0  # counter-clockwise seen from outside
    # the vertex normals point away from the centre of the (convex or ring) solid
    centre = np.zeros_like(m.positions)
    if kind == "torus":  # nearest point of the core circle
        xz = m.positions[:, [0, 2]]
        centre[:, [0, 2]] = xz / np.linalg.norm(xz, axis=1, keepdims=True)
    assert np.all(np.sum((m.positions - centre) * m.normals, axis=1) > 0)


@pytest.mark.parametrize("kind", ALL_BUT_TEAPOT)
def test_normals_unit_and_agree_with_winding(kind):
    m = make_primitive(kind)
    assert_frames_valid(m)
    assert_normals_follow_winding(m, min_dot=0.98)


def test_smooth_normals_match_trimesh_vertex_normals():
    m = sphere(segments=32, rings=16)
    tm = trimesh.Trimesh(m.positions, m.indices)  # merges the seam; trimesh's own smooth normals
    ours = m.normals[np.unique(m.indices)]
    _, nearest = tm.kdtree.query(m.positions[np.unique(m.indices)])
    assert np.min(np.sum(ours * tm.vertex_normals[nearest], axis=1)) > 0.999


# ------------------------------------------------------------------------------------------- tangents


def sphere_parallel_differences(m: Mesh, segments: int, rings: int):
    """Central differences of the positions along each non-polar ring (a parallel) of a UV sphere."""
    rows = []
    for j in range(1, rings):
        on_ring = np.flatnonzero(np.isclose(m.uvs[:, 1], j / rings))
        on_ring = on_ring[np.argsort(m.uvs[on_ring, 0])][:segments]  # drop the duplicate u = 1 column
        assert len(on_ring) == segments
        dp = m.positions[np.roll(on_ring, -1)] - m.positions[np.roll(on_ring, 1)]
        rows.append((on_ring, dp / np.linalg.norm(dp, axis=1, keepdims=True)))
    return rows


def test_sphere_tangents_follow_dp_du_along_parallels():
    segments, rings = 48, 24
    m = sphere(1.3, segments, rings)
    assert_frames_valid(m)
    recomputed = compute_tangents(m.positions, m.normals, m.uvs, m.indices)
    assert_frames_valid(Mesh(m.positions, m.normals, recomputed, m.uvs, m.indices))
    for j, (ring, fd) in enumerate(sphere_parallel_differences(m, segments, rings), start=1):
        assert np.min(np.sum(m.tangents[ring, :3] * fd, axis=1)) > 1 - 1e-5
        # Discrete uv derivatives are symmetric, hence second-order, except next to the pole fans and at
        # the seam (ring[0], u = 0), where the vertex sees triangles on one side only.
        dots = np.sum(recomputed[ring, :3] * fd, axis=1)
        assert dots.min() > 1 - 5e-3
        if j not in (1, rings - 1):
            assert dots[1:].min() > 1 - 5e-4
    np.testing.assert_array_equal(m.tangents[:, 3], 1.0)
    np.testing.assert_array_equal(recomputed[:, 3], 1.0)
    # bitangent = w cross(n, t) points along dP/dv, towards the north pole
    bitangent = np.cross(m.normals, m.tangents[:, :3])
    mid = np.abs(m.positions[:, 1]) < 0.9
    assert np.all(bitangent[mid, 1] > 0)


@pytest.mark.parametrize("kind", ["torus", "cube", "plane"])
def test_compute_tangents_reproduces_analytic_frames(kind):
    m = make_primitive(kind)
    t = compute_tangents(m.positions, m.normals, m.uvs, m.indices)
    assert np.min(np.sum(t[:, :3] * m.tangents[:, :3], axis=1)) > 0.999
    np.testing.assert_array_equal(t[:, 3], m.tangents[:, 3])


def test_compute_tangents_on_affine_uvs_with_handedness():
    """On a flat mesh with uv an affine function of position, dP/du is a closed form."""
    rng = np.random.default_rng(7)
    base = plane(subdivisions=5)
    positions, indices = base.positions.astype(np.float64), base.indices
    normals = np.tile([0.0, 1.0, 0.0], (len(positions), 1))
    xz = positions[:, [0, 2]]
    for mirror in (False, True):
        A = rng.normal(size=(2, 2))  # uv = A @ (x, z)
        if (np.linalg.det(A) > 0) != mirror:  # (x, z) is a left-handed basis seen from +y
            A[1] *= -1
        uvs = xz @ A.T + rng.normal(size=2)
        J = np.linalg.inv(A)  # (x, z) = J @ uv: dP/du = (J[0, 0], 0, J[1, 0]), dP/dv = (J[0, 1], 0, J[1, 1])
        dpdu = np.array([J[0, 0], 0.0, J[1, 0]])
        dpdv = np.array([J[0, 1], 0.0, J[1, 1]])
        t = compute_tangents(positions, normals, uvs, indices)
        np.testing.assert_allclose(t[:, :3], np.tile(dpdu / np.linalg.norm(dpdu), (len(t), 1)), atol=1e-6)
        w = np.sign(np.dot(np.cross([0.0, 1.0, 0.0], dpdu), dpdv))
        assert w == (-1 if mirror else 1)
        np.testing.assert_array_equal(t[:, 3], w)


def test_compute_tangents_degenerate_uvs_fall_back_to_orthogonal_unit_vectors():
    m = sphere(segments=12, rings=6)
    for uvs in (np.zeros_like(m.uvs), np.stack([np.zeros(len(m.uvs)), m.uvs[:, 1]], axis=1)):
        t = compute_tangents(m.positions, m.normals, uvs, m.indices)
        assert np.all(np.isfinite(t))
        assert_frames_valid(Mesh(m.positions, m.normals, t, uvs, m.indices))


def test_compute_tangents_at_a_mirror_seam_use_the_bitangent():
    """u = |x| mirrors the texture at x = 0: dP/du cancels there, dP/dv (-z) still gives the frame."""
    m = plane(subdivisions=2)
    uvs = np.stack([np.abs(m.positions[:, 0]), m.uvs[:, 1]], axis=1)
    t = compute_tangents(m.positions, m.normals, uvs, m.indices)
    x = m.positions[:, 0]
    np.testing.assert_allclose(t[x == 0], np.tile([1, 0, 0, 1], (3, 1)), atol=1e-6)
    np.testing.assert_allclose(t[x > 0], np.tile([1, 0, 0, 1], (3, 1)), atol=1e-6)
    np.testing.assert_allclose(t[x < 0], np.tile([-1, 0, 0, -1], (3, 1)), atol=1e-6)


# -------------------------------------------------------------------------------------- plane_horizon


def test_plane_horizon_reaches_extent_with_small_central_cells():
    extent, inner = 5000.0, 0.1
    m = plane_horizon(extent=extent, subdivisions=64, inner=inner)
    lo, hi = m.bounds()
    np.testing.assert_allclose([lo[0], lo[2], hi[0], hi[2]], [-extent, -extent, extent, extent])
    assert as_trimesh(m).area == pytest.approx((2 * extent) ** 2, rel=1e-6)
    assert len(m.positions) == 65 * 65

    # Grid lines: symmetric, first step `inner`, steps growing by one constant ratio.
    coords = np.unique(m.positions[:, 0].astype(np.float64))
    steps = np.diff(coords[coords >= 0])
    assert steps[0] == pytest.approx(inner, rel=1e-5)
    ratios = steps[1:] / steps[:-1]
    np.testing.assert_allclose(ratios, ratios.mean(), rtol=1e-3)
    assert 1.2 < ratios.mean() < 1.5

    # Triangles touching the centre are small; every cell subtends a bounded angle from the centre.
    p = m.positions.astype(np.float64)[m.indices.astype(np.int64)]
    edges = np.linalg.norm(p - np.roll(p, 1, axis=1), axis=2).max(axis=1)
    dist = np.linalg.norm(p, axis=2).min(axis=1)
    assert edges[dist == 0].max() <= inner * math.sqrt(2) * 1.0001
    far = dist > 10 * inner
    assert np.max(edges[far] / dist[far]) < 0.75
    # a camera 1 unit above the ground sees the rim within 0.02 degrees of the horizon
    assert math.degrees(math.atan2(1.0, extent)) < 0.02


def test_plane_horizon_uvs_match_plane_and_frames():
    m = plane_horizon(extent=100.0, subdivisions=9, inner=0.5)
    assert len(np.unique(m.positions[:, 0])) == 11  # 9 rounded up to 10 cells
    np.testing.assert_allclose(m.uvs[:, 0], 0.5 + m.positions[:, 0] / 2, rtol=1e-6)
    np.testing.assert_allclose(m.uvs[:, 1], 0.5 - m.positions[:, 2] / 2, rtol=1e-6)
    p = plane(size=2.0)
    np.testing.assert_allclose(p.uvs[:, 0], 0.5 + p.positions[:, 0] / 2)
    np.testing.assert_allclose(p.uvs[:, 1], 0.5 - p.positions[:, 2] / 2)
    np.testing.assert_array_equal(m.tangents, np.tile([1, 0, 0, 1], (len(m.positions), 1)))
    # few cells: uniform spacing
    uniform = np.unique(plane_horizon(extent=10.0, subdivisions=4, inner=5.0).positions[:, 0])
    np.testing.assert_allclose(uniform, [-10, -5, 0, 5, 10])


# -------------------------------------------------------------------------------------- make_primitive


def test_make_primitive_dispatches_with_parameters():
    m = make_primitive("sphere", radius=2.0, segments=8, rings=4)
    assert np.max(np.linalg.norm(m.positions, axis=1)) == pytest.approx(2.0)
    assert len(make_primitive("plane", subdivisions=3).indices) == 18


def test_make_primitive_errors_name_the_problem():
    with pytest.raises(PrefilterError, match=r"unknown primitive 'donut' \(valid: plane, plane_horizon"):
        make_primitive("donut")
    with pytest.raises(
        PrefilterError, match=r"'sphere' has no parameter 'radious' \(valid: radius, segments"
    ):
        make_primitive("sphere", radious=2.0)
    with pytest.raises(PrefilterError, match=r"'teapot' has no parameter 'size' \(valid: none\)"):
        make_primitive("teapot", size=2)
    with pytest.raises(PrefilterError, match="segments must be an integer >= 3"):
        make_primitive("torus", segments=2)
    with pytest.raises(PrefilterError, match="radius must be a positive number"):
        make_primitive("sphere", radius=-1)
    with pytest.raises(PrefilterError, match="minor radius"):
        make_primitive("torus", major=1.0, minor=1.0)


# ------------------------------------------------------------------------------------------- load_mesh


def textured(mesh: Mesh, normals: np.ndarray | None = None) -> trimesh.Trimesh:
    return trimesh.Trimesh(
        mesh.positions,
        mesh.indices,
        vertex_normals=mesh.normals if normals is None else normals,
        visual=trimesh.visual.TextureVisuals(uv=mesh.uvs),
        process=False,
    )


@pytest.mark.parametrize("ext", ["obj", "ply", "glb", "gltf"])
def test_load_mesh_round_trips_positions_uvs_and_file_normals(tmp_path, ext):
    src = torus(segments=24, sides=12)
    # Normals deliberately unlike the geometric ones, to tell file normals from computed ones.
    radial = src.positions / np.linalg.norm(src.positions, axis=1, keepdims=True)
    path = tmp_path / f"torus.{ext}"
    textured(src, radial).export(path)
    m = load_mesh(path)
    assert len(m.positions) == len(src.positions) and len(m.indices) == len(src.indices)
    assert as_trimesh(m).area == pytest.approx(as_trimesh(src).area, rel=1e-6)
    # match vertices on (position, uv)
    key_src = np.hstack([src.positions, src.uvs]).astype(np.float64)
    key_m = np.hstack([m.positions, m.uvs]).astype(np.float64)
    d = np.linalg.norm(key_m[:, None, :] - key_src[None, :, :], axis=2)
    nearest = d.argmin(axis=1)
    assert d.min(axis=1).max() < 1e-5
    np.testing.assert_allclose(m.normals, radial[nearest], atol=1e-5)
    assert_frames_valid(m)


def test_load_mesh_round_trips_stl_and_generates_spherical_uvs(tmp_path):
    src = sphere(radius=1.0, segments=24, rings=12)
    path = tmp_path / "sphere.stl"
    as_trimesh(src).export(path)
    m = load_mesh(path)
    assert as_trimesh(m).area == pytest.approx(as_trimesh(src).area, rel=1e-6)
    assert len(m.indices) == len(src.indices)
    assert len(np.unique(m.positions, axis=0)) == len(np.unique(src.positions, axis=0))
    # computed smooth normals of a sphere point outward
    assert np.min(np.sum(m.normals * m.positions, axis=1)) > 0.99
    # spherical projection, closed form (away from the seam and the poles)
    x, y, z = m.positions.astype(np.float64).T
    u = np.mod(np.arctan2(-z, x) / (2 * np.pi), 1.0)
    v = 1 - np.arccos(np.clip(y, -1, 1)) / np.pi
    inner = (np.abs(y) < 0.99) & (u > 0.01) & (u < 0.99)
    np.testing.assert_allclose(m.uvs[inner, 0], u[inner], atol=1e-5)
    np.testing.assert_allclose(m.uvs[:, 1], v, atol=1e-5)
    # no triangle wraps around the seam
    cu = m.uvs[m.indices.astype(np.int64), 0]
    assert np.max(cu.max(axis=1) - cu.min(axis=1)) < 0.25
    assert_frames_valid(m)
    assert_normals_follow_winding(m, min_dot=0.9)


def test_load_mesh_keeps_flat_file_normals_of_a_cube(tmp_path):
    path = tmp_path / "cube.obj"
    textured(cube()).export(path)
    m = load_mesh(path)
    assert len(m.positions) == 24
    np.testing.assert_allclose(np.abs(m.normals).sum(axis=1), 1.0, atol=1e-6)
    assert_normals_follow_winding(m, min_dot=0.999)


def test_load_mesh_concatenates_scene_with_transforms(tmp_path):
    scene = trimesh.Scene()
    box = trimesh.creation.box(extents=(1, 1, 1))
    scene.add_geometry(box, node_name="a")
    scene.add_geometry(box, node_name="b", transform=trimesh.transformations.translation_matrix([3, 0, 0]))
    path = tmp_path / "two.glb"
    scene.export(path)
    m = load_mesh(path)
    assert len(m.indices) == 24
    lo, hi = m.bounds()
    np.testing.assert_allclose(lo, [-0.5, -0.5, -0.5], atol=1e-6)
    np.testing.assert_allclose(hi, [3.5, 0.5, 0.5], atol=1e-6)
    assert as_trimesh(m).volume == pytest.approx(2.0)


def test_load_mesh_errors(tmp_path):
    with pytest.raises(PrefilterError, match="mesh file not found: .*nothing.obj"):
        load_mesh(tmp_path / "nothing.obj")
    (tmp_path / "mesh.xyz").write_text("1 2 3\n")
    with pytest.raises(PrefilterError, match=r"unsupported mesh format '.xyz' .*mesh.xyz .*supported: .obj"):
        load_mesh(tmp_path / "mesh.xyz")
    with pytest.raises(PrefilterError, match="not a file"):
        load_mesh(tmp_path)
    garbage = b"this is not a mesh\n\x00\x01\x02 at all\n"
    for ext in ("obj", "ply", "stl", "glb", "gltf"):
        path = tmp_path / f"garbage.{ext}"
        path.write_bytes(garbage)
        with pytest.raises(PrefilterError) as info:
            load_mesh(path)
        message = str(info.value)
        assert str(path) in message and "\n" not in message
        assert "contains no triangles" in message or "cannot read mesh" in message
    binary = tmp_path / "binary.obj"  # trimesh would guess its encoding with a module it may lack
    binary.write_bytes(b"v 0 0 0\n\xa9\xff\x00")
    with pytest.raises(PrefilterError, match=r"binary.obj as OBJ: not UTF-8 text \(byte 0xa9 at offset 8\)"):
        load_mesh(binary)
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    with pytest.raises(PrefilterError, match="contains no triangles"):
        load_mesh(empty)


# --------------------------------------------------------------------------------------------- teapot


def test_teapot_is_centred_unit_and_closed_enough(teapot_mesh):
    m = teapot_mesh
    lo, hi = m.bounds()
    np.testing.assert_allclose(lo + hi, 0.0, atol=1e-6)
    assert np.max(hi - lo) / 2 == pytest.approx(1.0, abs=1e-6)
    assert hi[1] - lo[1] < hi[0] - lo[0]  # y up: wider (spout to handle) than tall
    assert_frames_valid(m)
    assert_normals_follow_winding(m, min_dot=0.5)  # smooth normals; the worst faces sit on creases

    tm = trimesh.Trimesh(m.positions, m.indices)  # merges the uv-seam copies again
    raw_positions = sum(1 for line in teapot_path().read_text().splitlines() if line.startswith("v "))
    assert len(tm.vertices) < raw_positions  # duplicated OBJ positions were merged
    assert tm.is_winding_consistent and tm.volume > 0
    # watertight apart from the open spout and handle ends where they meet the body
    counts = np.bincount(tm.edges_unique_inverse)
    assert counts.max() == 2 and np.mean(counts == 1) < 0.03
    assert as_trimesh(m).area == pytest.approx(tm.area)


def test_teapot_asset_path_override(tmp_path, monkeypatch, teapot_mesh):
    shutil.copy(teapot_path(), tmp_path / "teapot.obj")
    monkeypatch.setenv("PREFILTER_ASSETS", str(tmp_path))
    assert teapot_path() == tmp_path / "teapot.obj"
    np.testing.assert_array_equal(teapot().positions, teapot_mesh.positions)
    monkeypatch.setenv("PREFILTER_ASSETS", str(tmp_path / "teapot.obj"))
    assert teapot_path() == tmp_path / "teapot.obj"


def test_teapot_missing_asset_says_how_to_get_it(tmp_path, monkeypatch):
    monkeypatch.setenv("PREFILTER_ASSETS", str(tmp_path / "elsewhere"))
    with pytest.raises(
        PrefilterError, match=r"Utah teapot asset missing at .*elsewhere.teapot.obj; run: make setup"
    ):
        make_primitive("teapot")
