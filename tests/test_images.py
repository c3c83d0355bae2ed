"""Tests for prefilter.images: sRGB curve against IEC 61966-2-1 values, PNG/EXR round trips and metadata,
atomic writes, magma false colour, labelled strips."""

import numpy as np
import pytest

from prefilter import PrefilterError, images


def test_linear_to_srgb_iec_values():
    x = np.array([0.0, 0.0031308, 0.5, 1.0, 0.001])
    expected = [0.0, 0.04045, 0.7353569830524495, 1.0, 0.01292]
    np.testing.assert_allclose(images.linear_to_srgb(x), expected, atol=1e-6)


def test_srgb_to_linear_iec_values():
    x = np.array([0.0, 0.04045, 0.5, 1.0, 0.02])
    expected = [0.0, 0.0031308, 0.21404114048223255, 1.0, 0.02 / 12.92]
    np.testing.assert_allclose(images.srgb_to_linear(x), expected, atol=1e-7)


def test_srgb_curve_round_trip_preserves_shape_and_dtype():
    x = np.linspace(-0.1, 1.5, 2 * 3 * 4 * 3).reshape(2, 3, 4, 3)
    y = images.linear_to_srgb(x)
    assert y.shape == x.shape and y.dtype == np.float64
    np.testing.assert_allclose(images.srgb_to_linear(y), x, atol=1e-12)
    # monotonic and continuous at the breakpoint
    t = np.linspace(0, 1, 10001)
    assert np.all(np.diff(images.linear_to_srgb(t)) > 0)


def test_exr_round_trip_is_bit_exact_with_metadata(tmp_path):
    rng = np.random.default_rng(0)
    img = (rng.standard_normal((17, 23, 3)) * 10.0 ** rng.integers(-30, 30, (17, 23, 3))).astype(np.float32)
    img[0, 0] = [0.0, -0.0, 1e-40]  # zeros and a denormal
    meta = {"mode": "hart-mip", "spp": 1024, "scale": 0.5, "nested": {"keys": ["a", "β"]}, "n": np.int64(3)}
    path = tmp_path / "out" / "deep" / "render.exr"  # parent directories are created
    assert images.write_image(path, img, meta) == path
    back, meta_back = images.read_image(path)
    assert back.dtype == np.float32 and back.shape == img.shape
    np.testing.assert_array_equal(back.view(np.uint32), img.view(np.uint32))
    assert meta_back == {**meta, "n": 3}
    assert [p.name for p in path.parent.iterdir()] == ["render.exr"]


def test_exr_header_is_zip_and_metadata_optional(tmp_path):
    import OpenEXR

    path = tmp_path / "plain.exr"
    images.write_image(path, np.ones((4, 5, 3), np.float64))
    with OpenEXR.File(str(path)) as f:
        assert f.header()["compression"] == OpenEXR.ZIP_COMPRESSION
        assert f.channels()["RGB"].pixels.dtype == np.float32
    img, meta = images.read_image(path)
    assert meta == {} and img.shape == (4, 5, 3)


def test_png_round_trip_within_one_code_value(tmp_path):
    rng = np.random.default_rng(1)
    img = rng.random((20, 30, 3)).astype(np.float32)
    img[0, :3] = [[-0.5, 0.0, 2.0], [np.nan, 1.0, 0.5], [0.0031308, 0.18, 1.0]]
    path = tmp_path / "render.png"
    images.write_image(path, img, {"mode": "naive"})
    back, meta = images.read_image(path)
    assert back.dtype == np.float32 and back.shape == img.shape
    assert meta == {"mode": "naive"}
    expected = images.linear_to_srgb(np.clip(np.nan_to_num(img, nan=0.0), 0, 1))
    assert np.max(np.abs(images.linear_to_srgb(back) - expected)) <= 0.5 / 255 + 1e-6


def test_png_is_srgb_encoded_8_bit(tmp_path):
    import imageio.v3 as iio

    path = tmp_path / "grey.png"
    images.write_image(path, np.full((2, 2, 3), 0.5))
    raw = iio.imread(path)
    assert raw.dtype == np.uint8
    assert np.all(raw == 188)  # round(255 * 0.735357)


def test_unsupported_extension_raises_and_leaves_nothing(tmp_path):
    path = tmp_path / "sub" / "render.tiff"
    with pytest.raises(PrefilterError) as info:
        images.write_image(path, np.zeros((2, 2, 3)))
    message = str(info.value)
    assert "\n" not in message and str(path) in message and ".png" in message and ".exr" in message
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(PrefilterError):
        images.read_image(tmp_path / "x.jpg")


def test_bad_shape_raises(tmp_path):
    with pytest.raises(PrefilterError, match="shape"):
        images.write_image(tmp_path / "a.png", np.zeros((2, 2, 4)))
    assert list(tmp_path.iterdir()) == []


def _partial_then_fail(path, *args, **kwargs):
    with open(path, "wb") as f:
        f.write(b"half an image")
    raise OSError("disk full (simulated)")


def test_png_encoder_failure_leaves_no_file_and_keeps_old(tmp_path, monkeypatch):
    import imageio.v3 as iio

    path = tmp_path / "out.png"
    images.write_image(path, np.zeros((3, 3, 3)))
    before = path.read_bytes()
    monkeypatch.setattr(iio, "imwrite", _partial_then_fail)
    with pytest.raises(OSError, match="simulated"):
        images.write_image(path, np.ones((3, 3, 3)))
    with pytest.raises(OSError, match="simulated"):
        images.write_image(tmp_path / "new.png", np.ones((3, 3, 3)))
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]
    assert path.read_bytes() == before


def test_exr_encoder_failure_leaves_no_file(tmp_path, monkeypatch):
    import OpenEXR

    class FailingFile:
        def __init__(self, header, channels):
            pass

        def write(self, path):
            _partial_then_fail(path)

    monkeypatch.setattr(OpenEXR, "File", FailingFile)
    with pytest.raises(OSError, match="simulated"):
        images.write_image(tmp_path / "out.exr", np.ones((3, 3, 3)), {"a": 1})
    assert list(tmp_path.iterdir()) == []


def test_unserialisable_metadata_fails_before_writing(tmp_path):
    with pytest.raises(TypeError):
        images.write_image(tmp_path / "a" / "out.exr", np.ones((2, 2, 3)), {"f": object()})
    assert list(tmp_path.iterdir()) == []


# Endpoints of matplotlib's magma (van der Walt & Smith), sRGB-encoded.
MAGMA_0 = (0.001462, 0.000466, 0.013866)
MAGMA_1 = (0.987053, 0.991438, 0.749504)


def test_false_colour_uses_magma_and_clips():
    out = images.false_colour(np.array([[0.0, 2.0, -1.0, 4.0, 1.0]]), vmax=2.0)
    assert out.shape == (1, 5, 3) and out.dtype == np.float32
    srgb = images.linear_to_srgb(out)
    np.testing.assert_allclose(srgb[0, [0, 2]], [MAGMA_0, MAGMA_0], atol=1e-6)
    np.testing.assert_allclose(srgb[0, [1, 3]], [MAGMA_1, MAGMA_1], atol=1e-6)
    # lightness of magma increases monotonically
    ramp = images.false_colour(np.linspace(0, 1, 64)[None, :])
    luminance = ramp[0] @ np.array([0.2126, 0.7152, 0.0722])
    assert np.all(np.diff(luminance) >= 0)
    with pytest.raises(ValueError):
        images.false_colour(np.zeros((2, 2)), vmax=0)


def test_labelled_strip_layout():
    rng = np.random.default_rng(2)
    a = rng.random((30, 40, 3)).astype(np.float32)
    b = rng.random((30, 40, 3)).astype(np.float32)
    c = rng.random((30, 40, 3)).astype(np.float32)
    strip = images.labelled_strip([("reference", a), ("naive", b), ("a very long label that cannot fit", c)])
    assert strip.shape == (22 + 30, 3 * 40 + 2 * 2, 3) and strip.dtype == np.float32
    np.testing.assert_array_equal(strip[22:, 0:40], a)
    np.testing.assert_array_equal(strip[22:, 42:82], b)
    np.testing.assert_array_equal(strip[22:, 84:124], c)
    grey = images.srgb_to_linear(images.LABEL_BACKGROUND / 255)
    np.testing.assert_allclose(strip[22:, 40:42], grey, rtol=1e-6)  # gaps
    for x0 in (0, 42, 84):  # each label bar: dark grey with white text, neutral
        bar = strip[:22, x0 : x0 + 40]
        assert bar.max() == pytest.approx(1.0) and bar.min() == pytest.approx(grey, rel=1e-6)
        np.testing.assert_array_equal(bar[..., 0], bar[..., 1])


def test_labelled_strip_rejects_mismatched_panels():
    with pytest.raises(ValueError):
        images.labelled_strip([])
    with pytest.raises(ValueError, match="shape"):
        images.labelled_strip([("a", np.zeros((4, 4, 3))), ("b", np.zeros((4, 5, 3)))])


def test_strip_writes_as_png(tmp_path):
    strip = images.labelled_strip(
        [("x", np.zeros((10, 12, 3))), ("y", np.ones((10, 12, 3)))], label_height=16
    )
    images.write_image(tmp_path / "strip.png", strip)
    back, _ = images.read_image(tmp_path / "strip.png")
    assert back.shape == (26, 26, 3)


@pytest.mark.parametrize("shape,size", [((9, 15), (10, 6)), ((256, 256), (200, 200)), ((12, 8), (4, 6))])
def test_box_downsample_is_the_area_mean(shape, size):
    """Against the exact area mean: both grids refined to their least common multiple (each input pixel
    repeated, each output pixel a block mean); the last case has integer factors, a plain block mean."""
    import math

    rng = np.random.default_rng(3)
    image = rng.random((*shape, 3)).astype(np.float32)
    (rows, cols), (w, h) = shape, size
    ly, lx = math.lcm(rows, h), math.lcm(cols, w)
    fine = np.repeat(np.repeat(image.astype(np.float64), ly // rows, 0), lx // cols, 1)
    expected = fine.reshape(h, ly // h, w, lx // w, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(images.box_downsample(image, size), expected, atol=1e-6)


def test_box_downsample_keeps_the_mean_and_refuses_to_enlarge():
    image = np.random.default_rng(4).random((37, 53, 3)).astype(np.float32)
    assert images.box_downsample(image, (29, 31)).mean() == pytest.approx(image.mean(), rel=1e-6)
    with pytest.raises(PrefilterError, match="reduces only"):
        images.box_downsample(image, (54, 10))
