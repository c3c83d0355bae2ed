"""Normal/height maps and Fournier's textures (§3): file round trips, clear errors, consistent generators."""

import re
import struct
import zlib

import imageio.v3 as iio
import numpy as np
import OpenEXR
import pytest

from prefilter import PrefilterError
from prefilter.normals.normal_maps import (
    GENERATORS,
    Z_MIN,
    cylinders,
    generate,
    hemispheres,
    load_surface,
    normals_from_heights,
    read_height_map,
    read_normal_map,
    stochastic,
    twill,
    twill_pattern,
    write_height_map,
    write_normal_map,
)


def random_normals(shape, seed=0, min_z=0.05):
    rng = np.random.default_rng(seed)
    n = rng.normal(size=shape + (3,))
    n[..., 2] = np.abs(n[..., 2]) + min_z
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def write_exr(path, channels):
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {k: np.asarray(v, np.float32) for k, v in channels.items()}).write(str(path))


def write_png16(path, codes):
    """A plain 16-bit PNG (grey, grey+alpha, RGB or RGBA), unfiltered: an independent writer."""
    h, w, c = codes.shape
    rows = np.zeros((h, 1 + 2 * w * c), np.uint8)
    rows[:, 1:] = np.ascontiguousarray(codes, ">u2").view(np.uint8).reshape(h, -1)

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", w, h, 16, {1: 0, 2: 4, 3: 2, 4: 6}[c], 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(rows.tobytes()))
        + chunk(b"IEND", b"")
    )


def raises_naming(path, *patterns):
    """pytest.raises for a one-line PrefilterError whose message names `path` and matches `patterns`."""

    class Check:
        def __enter__(self):
            self.ctx = pytest.raises(PrefilterError)
            self.info = self.ctx.__enter__()
            return self.info

        def __exit__(self, *exc):
            suppressed = self.ctx.__exit__(*exc)
            message = str(self.info.value)
            assert str(path) in message and "\n" not in message, message
            for pattern in patterns:
                assert re.search(pattern, message), message
            return suppressed

    return Check()


# ------------------------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("ext, atol", [(".png", 3e-5), (".exr", 1e-6)])
def test_normal_map_round_trip_non_square(tmp_path, ext, atol):
    n = random_normals((20, 48))
    path = write_normal_map(tmp_path / f"n{ext}", n)
    got = read_normal_map(path)
    assert got.shape == (20, 48, 3) and got.dtype == np.float64
    np.testing.assert_allclose(got, n, atol=atol)
    np.testing.assert_allclose(np.linalg.norm(got, axis=-1), 1.0, atol=1e-12)
    assert list(tmp_path.iterdir()) == [path]  # no temporary files left behind


def test_files_store_row_zero_as_the_bottom_row(tmp_path):
    n = random_normals((6, 10), seed=1)
    write_normal_map(tmp_path / "n.exr", n)
    with OpenEXR.File(str(tmp_path / "n.exr")) as f:
        top_row = np.array(f.channels()["RGB"].pixels[0])
    np.testing.assert_allclose(top_row, n[-1], atol=1e-6)
    heights = np.arange(60.0).reshape(6, 10)
    write_height_map(tmp_path / "h.png", heights)
    file_rows = iio.imread(tmp_path / "h.png")  # 16-bit grey: Pillow reads it exactly
    assert file_rows[0, 0] > file_rows[-1, 0]  # the file's top row holds the highest rows of the array


@pytest.mark.parametrize("ext", [".png", ".exr"])
def test_height_map_round_trip(tmp_path, ext):
    heights = np.random.default_rng(2).normal(size=(20, 48)) * 7.0 + 3.0
    lo, hi = write_height_map(tmp_path / f"h{ext}", heights)
    got = lo + (hi - lo) * read_height_map(tmp_path / f"h{ext}")
    np.testing.assert_allclose(got, heights, atol=(hi - lo) / 65535 if ext == ".png" else 1e-5)
    if ext == ".png":
        assert (lo, hi) == (heights.min(), heights.max())


def test_eight_and_sixteen_bit_pngs_from_other_tools(tmp_path):
    rgb8 = np.zeros((3, 5, 4), np.uint8)
    rgb8[...] = [128, 128, 255, 7]  # flat normal, RGBA with an alpha that must be ignored
    rgb8[0, 0] = [255, 128, 128, 7]  # file's top-left: +x, lying in the tangent plane
    iio.imwrite(tmp_path / "n8.png", rgb8)
    got = read_normal_map(tmp_path / "n8.png")
    np.testing.assert_allclose(got[-1, 0], [1.0, 0.0, Z_MIN], atol=1e-2)  # z = 1/255 within quantisation
    assert got[..., 2].min() > 0
    np.testing.assert_allclose(got[0, 1], [0.0, 0.0, 1.0], atol=1e-2)
    codes = np.round((random_normals((7, 9), seed=4) + 1) / 2 * 65535).astype(np.uint16)
    for channels in (3, 4):
        data = np.concatenate([codes, np.full((7, 9, 1), 65535, np.uint16)], axis=2)[..., :channels]
        write_png16(tmp_path / f"n16_{channels}.png", data)
        want = codes[::-1] / 65535 * 2 - 1
        want /= np.linalg.norm(want, axis=-1, keepdims=True)
        np.testing.assert_allclose(read_normal_map(tmp_path / f"n16_{channels}.png"), want, atol=1e-12)
    grey = np.arange(12, dtype=np.uint8).reshape(3, 4) * 20
    iio.imwrite(tmp_path / "h8.png", grey)
    np.testing.assert_allclose(read_height_map(tmp_path / "h8.png"), grey[::-1] / 255)


def test_non_unit_normals_are_normalised_and_tangent_normals_lifted(tmp_path):
    n = random_normals((4, 5), seed=3)
    scale = np.linspace(0.3, 2.5, 20).reshape(4, 5, 1)
    raw = n * scale
    raw[1, 2] = [3.0, 4.0, 0.0]  # in the tangent plane
    write_exr(tmp_path / "n.exr", {"RGB": raw[::-1]})
    got = read_normal_map(tmp_path / "n.exr")
    np.testing.assert_allclose(np.linalg.norm(got, axis=-1), 1.0, atol=1e-12)
    mask = np.ones((4, 5), bool)
    mask[1, 2] = False
    np.testing.assert_allclose(got[mask], n[mask], atol=1e-6)
    np.testing.assert_allclose(got[1, 2], [0.6, 0.8, Z_MIN], atol=1e-9)


# ------------------------------------------------------------------------------------------------ errors


def test_unreadable_files(tmp_path):
    with raises_naming(tmp_path / "missing.png", "no such file"):
        read_normal_map(tmp_path / "missing.png")
    (tmp_path / "n.jpg").write_bytes(b"")
    with raises_naming(tmp_path / "n.jpg", "unsupported image extension"):
        read_normal_map(tmp_path / "n.jpg")
    (tmp_path / "text.png").write_text("just some text\nover two lines\n")
    with raises_naming(tmp_path / "text.png", "not a PNG"):
        read_normal_map(tmp_path / "text.png")
    (tmp_path / "text.exr").write_text("just some text\nover two lines\n")
    with raises_naming(tmp_path / "text.exr", "cannot read EXR"):
        read_height_map(tmp_path / "text.exr")
    truncated = tmp_path / "cut.png"
    iio.imwrite(truncated, np.zeros((16, 16, 3), np.uint8) + 128)
    truncated.write_bytes(truncated.read_bytes()[:40])
    with raises_naming(truncated, "cannot read PNG"):
        read_normal_map(truncated)


def test_too_few_channels(tmp_path):
    iio.imwrite(tmp_path / "la.png", np.full((4, 6, 2), 200, np.uint8))
    with raises_naming(tmp_path / "la.png", "needs 3 channels", "found 2"):
        read_normal_map(tmp_path / "la.png")
    write_png16(tmp_path / "la16.png", np.full((4, 6, 2), 40000, np.uint16))
    with raises_naming(tmp_path / "la16.png", "needs 3 channels", "found 2"):
        read_normal_map(tmp_path / "la16.png")
    iio.imwrite(tmp_path / "grey.png", np.full((4, 6), 200, np.uint8))
    with raises_naming(tmp_path / "grey.png", "found 1"):
        read_normal_map(tmp_path / "grey.png")
    write_exr(tmp_path / "y.exr", {"Y": np.ones((4, 6))})
    with raises_naming(tmp_path / "y.exr", "channels Y"):
        read_normal_map(tmp_path / "y.exr")


@pytest.mark.parametrize(
    "value, pattern",
    [
        ([np.nan, 0.0, 1.0], "NaN or Inf"),
        ([0.0, np.inf, 1.0], "NaN or Inf"),
        ([0.0, 0.0, 0.0], "zero-length normal"),
        ([0.3, 0.0, -0.5], r"below the surface \(z < 0\)"),
    ],
)
def test_bad_normal_pixels_are_located(tmp_path, value, pattern):
    n = np.tile([0.0, 0.0, 1.0], (5, 7, 1))
    n[3, 2] = value  # file row 3 from the top, column 2
    write_exr(tmp_path / "bad.exr", {"RGB": n})
    with raises_naming(tmp_path / "bad.exr", pattern, r"x=2, y=3"):
        read_normal_map(tmp_path / "bad.exr")


def test_bad_pixels_in_pngs_and_height_maps(tmp_path):
    rgb = np.full((4, 6, 3), [128, 128, 255], np.uint8)
    rgb[1, 4] = [128, 128, 0]  # z = -1
    iio.imwrite(tmp_path / "down.png", rgb)
    with raises_naming(tmp_path / "down.png", "below the surface", r"x=4, y=1"):
        read_normal_map(tmp_path / "down.png")
    rgb[1, 4] = [128, 128, 128]  # (0, 0, 0) within 8-bit quantisation
    iio.imwrite(tmp_path / "zero.png", rgb)
    with raises_naming(tmp_path / "zero.png", "zero-length", r"x=4, y=1"):
        read_normal_map(tmp_path / "zero.png")
    h = np.zeros((5, 7))
    h[0, 6] = np.nan
    write_exr(tmp_path / "h.exr", {"Y": h})
    with raises_naming(tmp_path / "h.exr", "height map has NaN", r"x=6, y=0"):
        read_height_map(tmp_path / "h.exr")


def test_load_surface(tmp_path):
    s = stochastic((20, 12), seed=4)
    write_height_map(tmp_path / "h.exr", s.heights / 2.0)
    from_heights = load_surface(height_path=tmp_path / "h.exr", height_scale=2.0)
    np.testing.assert_allclose(from_heights.heights, s.heights, atol=1e-5)
    np.testing.assert_allclose(from_heights.normals, normals_from_heights(s.heights), atol=1e-5)
    assert from_heights.name == "h" and from_heights.size == (20, 12)
    write_normal_map(tmp_path / "n.exr", s.normals)
    both = load_surface(tmp_path / "n.exr", tmp_path / "h.exr", 2.0)
    np.testing.assert_allclose(both.normals, s.normals, atol=1e-6)
    assert load_surface(tmp_path / "n.exr").heights is None
    write_height_map(tmp_path / "small.exr", np.zeros((12, 19)))
    with raises_naming(tmp_path / "n.exr", "20x12", "19x12"):
        load_surface(tmp_path / "n.exr", tmp_path / "small.exr")
    with pytest.raises(PrefilterError, match="normal map, a height map, or both"):
        load_surface()


def test_normals_from_heights_are_periodic_central_differences():
    w = 24
    x, y = np.meshgrid(np.arange(w) + 0.5, np.arange(10) + 0.5)
    k = 2 * np.pi / w
    n = normals_from_heights(np.sin(k * x), scale=3.0)
    slope = 3.0 * np.cos(k * x) * np.sin(k)  # = 3 k cos(kx) damped by sin(k) / k
    np.testing.assert_allclose(n, np.stack([-slope, 0 * x, 1 + 0 * x], -1) / np.sqrt(1 + slope**2)[..., None])


# -------------------------------------------------------------------------------------------- generators


def fine_normals(generator, size, k=7, **params):
    """Oracle: the same surface sampled k times finer (sizes scale the texture), np.gradient normals,
    picked at the coarse texel centres (k odd), and a mask of the centres away from creases (where the
    fine normals' second differences over 1 and 2 fine steps are small)."""
    fine = generator(size=(size[0] * k, size[1] * k), **params).heights
    gy, gx = np.gradient(np.pad(fine, 1, mode="wrap"))
    n = np.stack([-gx, -gy, np.ones_like(gx)], -1)[1:-1, 1:-1]
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    c = (k - 1) // 2
    centre = n[c::k, c::k]
    bend = np.zeros(centre.shape[:2])
    for s in (1, 2):
        for axis in (0, 1):
            second = np.roll(n, s, axis=axis) + np.roll(n, -s, axis=axis) - 2 * n
            bend = np.maximum(bend, np.abs(second[c::k, c::k]).max(axis=-1))
    return centre, bend < 0.03


@pytest.mark.parametrize(
    "generator, size, params",
    [
        (hemispheres, (48, 20), {"count": (4, 2)}),
        (cylinders, (48, 20), {"count": 4, "radius": 0.4}),
        (twill, (48, 40), {"threads": 8}),
    ],
)
def test_generator_normals_match_finite_differences_of_heights(generator, size, params):
    surface = generator(size=size, **params)
    assert surface.normals.shape == (size[1], size[0], 3) and surface.heights.shape == (size[1], size[0])
    oracle, smooth = fine_normals(generator, size, **params)
    assert smooth.mean() > 0.5
    np.testing.assert_allclose(surface.normals[smooth], oracle[smooth], atol=0.005)


@pytest.mark.parametrize("name", sorted(GENERATORS))
def test_generators_give_unit_normals_above_the_plane_and_tile(name):
    for size in [(64, 64), (48, 20)]:
        s = generate(name, size=size)
        np.testing.assert_allclose(np.linalg.norm(s.normals, axis=-1), 1.0, atol=1e-12)
        assert s.normals[..., 2].min() > 0 and np.isfinite(s.heights).all()
        assert s.size == size
    if name != "stochastic":  # a doubled tile with doubled counts is the tile repeated
        params = {"hemispheres": ("count", (4, 2), (8, 4)), "cylinders": ("count", 4, 8)}
        key, one, two = params.get(name, ("threads", 8, 16))
        small = generate(name, size=(48, 20), **{key: one})
        big = generate(name, size=(96, 40), **{key: two})
        np.testing.assert_allclose(big.heights, np.tile(small.heights, (2, 2)), atol=1e-9)
        np.testing.assert_allclose(big.normals, np.tile(small.normals, (2, 2, 1)), atol=1e-6)


def test_hemispheres_are_analytic_and_symmetric():
    s = hemispheres((64, 48), count=(4, 3), radius=0.45)
    r = 0.45 * 16
    x, y = np.meshgrid(np.arange(64) + 0.5, np.arange(48) + 0.5)
    dx, dy = x % 16 - 8, y % 16 - 8
    inside = dx**2 + dy**2 < r**2
    h = np.sqrt(np.maximum(r**2 - dx**2 - dy**2, 0))
    np.testing.assert_allclose(s.heights, np.where(inside, h, 0), atol=1e-12)
    np.testing.assert_allclose(s.normals[inside] * r, np.stack([dx, dy, h], -1)[inside], atol=1e-9)
    np.testing.assert_array_equal(s.normals[~inside], np.tile([0.0, 0.0, 1.0], ((~inside).sum(), 1)))
    mean = s.normals.mean(axis=(0, 1))
    assert abs(mean[0]) < 1e-12 and abs(mean[1]) < 1e-12
    second = (s.normals[..., :2] ** 2).mean(axis=(0, 1))
    assert abs(second[0] - second[1]) < 1e-12  # the distribution is as wide along x as along y


def test_cylinders_run_along_y():
    s = cylinders((40, 24), count=5, radius=0.5)
    assert np.all(s.normals[..., 1] == 0)
    np.testing.assert_array_equal(s.heights, np.tile(s.heights[:1], (24, 1)))
    dx = (np.arange(40) + 0.5) % 8 - 4
    np.testing.assert_allclose(s.heights[0], np.sqrt(16 - dx**2))
    np.testing.assert_allclose(s.normals[0, :, 0], dx / 4)


def test_twill_pattern_period_and_diagonal():
    threads, over, under, cell = 8, 3, 1, 9
    pattern = twill_pattern(threads, over, under)
    i, j = np.mgrid[0:threads, 0:threads]
    np.testing.assert_array_equal(pattern, (j - i) % (over + under) < over)
    s = twill((threads * cell, threads * cell), threads=threads, over=over, under=under)
    h = s.heights
    np.testing.assert_allclose(np.roll(h, (over + under) * cell, axis=1), h, atol=1e-12)  # period 4 threads
    np.testing.assert_allclose(np.roll(h, (cell, cell), axis=(0, 1)), h, atol=1e-12)  # diagonal shift
    assert np.abs(np.roll(h, cell, axis=1) - h).max() > 0.5
    # which thread lies on top, read off the heights: across the warp (along x) the height falls away
    # from the cell centre, along it (y) it stays up; the weft is the other way round.
    c, off = cell // 2, 3
    centre = h[c::cell, c::cell]
    drop_x = centre - 0.5 * (h[c::cell, c - off :: cell] + h[c::cell, c + off :: cell])
    drop_y = centre - 0.5 * (h[c - off :: cell, c::cell] + h[c + off :: cell, c::cell])
    np.testing.assert_array_equal(drop_x > drop_y, pattern)
    assert (np.abs(drop_x - drop_y) > 0.3).all()


def test_twill_heights_are_continuous():
    # Magnifying a continuous surface keeps its largest step between texels (a slope) the same; a
    # discontinuity of J texels would grow with the magnification.
    def largest_step(size):
        h = twill((size, size), threads=8).heights
        return max(np.abs(h - np.roll(h, 1, axis=a)).max() for a in (0, 1))

    assert largest_step(512) < 1.1 * largest_step(128)


def fourier_upsample(h, k):
    """Exact k-times finer samples of a band-limited periodic surface (no Nyquist content)."""
    rows, cols = h.shape
    fine = np.zeros((k * rows, k * cols), complex)
    iy = np.round(np.fft.fftfreq(rows) * rows).astype(int) % (k * rows)
    ix = np.round(np.fft.fftfreq(cols) * cols).astype(int) % (k * cols)
    fine[np.ix_(iy, ix)] = np.fft.fft2(h)
    return np.fft.ifft2(fine).real * k * k


def fourth_order_slopes(h, step):
    def d(axis):
        r = lambda s: np.roll(h, -s, axis=axis)  # noqa: E731
        return (-r(2) + 8 * r(1) - 8 * r(-1) + r(-2)) / (12 * step)

    return d(1), d(0)


@pytest.mark.parametrize("size, rms, beta", [((64, 64), 0.5, 2.0), ((48, 20), 0.8, 3.0)])
def test_stochastic_rms_slope_and_normals(size, rms, beta):
    s = stochastic(size, rms_slope=rms, beta=beta, seed=7)
    k = 8
    gx, gy = fourth_order_slopes(fourier_upsample(s.heights, k), 1.0 / k)
    measured = np.sqrt(np.mean(gx**2 + gy**2))
    assert abs(measured / rms - 1) < 5e-3
    n = np.stack([-gx, -gy, np.ones_like(gx)], -1)[::k, ::k]
    np.testing.assert_allclose(s.normals, n / np.linalg.norm(n, axis=-1, keepdims=True), atol=5e-3)
    assert abs(s.heights.mean()) < 1e-12


def test_stochastic_is_deterministic_for_a_seed():
    a, b, c = stochastic(seed=3), stochastic(seed=3), stochastic(seed=4)
    np.testing.assert_array_equal(a.heights, b.heights)
    np.testing.assert_array_equal(a.normals, b.normals)
    assert not np.allclose(a.heights, c.heights)


def test_generate_errors():
    with pytest.raises(PrefilterError, match="unknown surface generator 'spheres'.*hemispheres"):
        generate("spheres")
    with pytest.raises(PrefilterError, match="'twill' has no parameter 'thread'.*threads"):
        generate("twill", thread=4)
    with pytest.raises(PrefilterError, match=r"hemispheres: radius must be in \(0, 0.5\]"):
        generate("hemispheres", radius=0.7)
    with pytest.raises(PrefilterError, match="cylinders: size"):
        generate("cylinders", size=(0, 8))
    with pytest.raises(PrefilterError, match="cylinders: size .W, H. must be at most 8192 a side"):
        generate("cylinders", size=(128, 10**9))  # refused before it allocates
    with pytest.raises(PrefilterError, match="twill: over must be a positive integer"):
        generate("twill", over=1.5)
    assert generate("cylinders", size=[16, 8], count=2).size == (16, 8)  # lists from scene files
