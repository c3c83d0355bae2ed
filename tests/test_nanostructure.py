"""Nanostructure height fields: file round trips, input errors, and the generators' periods and tiling."""

import imageio.v3 as iio
import numpy as np
import pytest

from prefilter import PrefilterError
from prefilter.diffraction.nanostructure import (
    GENERATORS,
    MAX_PIXEL_UM,
    Nanostructure,
    blazed,
    elaphe,
    generate,
    read_heightfield,
    sinusoidal,
    validate,
    write_heightfield,
    xenopeltis,
)


def dominant_period(structure: Nanostructure) -> float:
    """Period along x (µm) of the strongest non-zero frequency of the mean row."""
    row = (structure.heights - structure.heights.mean()).mean(axis=0)
    spectrum = np.abs(np.fft.rfft(row))
    return structure.size_um[0] / (int(np.argmax(spectrum[1:])) + 1)


def random_structure(shape=(12, 20), seed=0) -> Nanostructure:
    rng = np.random.default_rng(seed)
    return Nanostructure(rng.uniform(-0.2, 0.3, shape), (0.05, 0.04), "random")


# ---------------------------------------------------------------------------------------------- files


@pytest.mark.parametrize("ext", [".npy", ".exr"])
def test_round_trip(tmp_path, ext):
    s = random_structure()
    path = write_heightfield(tmp_path / f"h{ext}", s)
    back = read_heightfield(path, s.pixel)
    assert back.heights.shape == s.heights.shape and back.pixel == s.pixel
    tol = 0 if ext == ".npy" else 1e-7
    np.testing.assert_allclose(back.heights, s.heights, atol=tol, rtol=tol)
    assert [p.name for p in tmp_path.iterdir()] == [f"h{ext}"]  # no temporary file left


def test_height_scale_and_square_pixel(tmp_path):
    s = random_structure()
    path = write_heightfield(tmp_path / "h.npy", s)
    back = read_heightfield(path, 0.02, height_scale_um=2.5)
    assert back.pixel == (0.02, 0.02)
    np.testing.assert_allclose(back.heights, 2.5 * s.heights)


def test_png_bottom_row_is_row_zero(tmp_path):
    codes = np.zeros((10, 9), np.uint16)
    codes[-1, :] = 65535  # bottom row of the file
    iio.imwrite(tmp_path / "h.png", codes)
    s = read_heightfield(tmp_path / "h.png", 0.05, height_scale_um=0.3)
    np.testing.assert_allclose(s.heights[0], 0.3)
    np.testing.assert_allclose(s.heights[1:], 0.0)


def test_unreadable_file_names_it(tmp_path):
    for name in ("bad.npy", "bad.exr", "bad.png"):
        (tmp_path / name).write_bytes(b"not an image at all")
        with pytest.raises(PrefilterError, match=r"bad\.(npy|exr|png)"):
            read_heightfield(tmp_path / name, 0.05)
    with pytest.raises(PrefilterError, match="missing.npy: no such file"):
        read_heightfield(tmp_path / "missing.npy", 0.05)
    with pytest.raises(PrefilterError, match="unsupported"):
        read_heightfield(tmp_path / "h.tif", 0.05)


def test_3d_npy_is_rejected(tmp_path):
    np.save(tmp_path / "cube.npy", np.zeros((16, 16, 3)))
    with pytest.raises(PrefilterError, match=r"cube\.npy: expected a 2D .*\(16, 16, 3\)") as info:
        read_heightfield(tmp_path / "cube.npy", 0.05)
    assert "\n" not in str(info.value)


def test_nan_position_is_reported(tmp_path):
    h = np.zeros((16, 16))
    h[3, 5] = np.nan
    np.save(tmp_path / "nan.npy", h)
    with pytest.raises(PrefilterError, match=r"nan\.npy: .*NaN.*x=5, y=3"):
        read_heightfield(tmp_path / "nan.npy", 0.05)


def test_coarse_pixel_is_rejected(tmp_path):
    np.save(tmp_path / "h.npy", np.zeros((16, 16)))
    with pytest.raises(PrefilterError, match=r"h\.npy: pixel size 0\.2 µm is too coarse .*0\.1 µm"):
        read_heightfield(tmp_path / "h.npy", 0.2)
    with pytest.raises(PrefilterError, match="too coarse"):
        sinusoidal(pixel=0.2)
    validate(Nanostructure(np.zeros((8, 8)), (MAX_PIXEL_UM, MAX_PIXEL_UM), "edge"), "edge")  # 0.1 is fine


def test_small_field_and_bad_parameters():
    with pytest.raises(PrefilterError, match="at least 8x8"):
        validate(Nanostructure(np.zeros((4, 16)), (0.05, 0.05), "small"), "small")
    with pytest.raises(PrefilterError, match="unknown nanostructure generator 'nope'"):
        generate("nope")
    with pytest.raises(PrefilterError, match="has no parameter 'colour'"):
        generate("blazed", colour=1)
    with pytest.raises(PrefilterError, match="sinusoidal: period"):
        sinusoidal(period=-1.0)


def test_centred_and_properties():
    s = blazed()
    assert s.size_um == pytest.approx((25.0, 25.0))
    assert abs(s.centred().heights.mean()) < 1e-12
    assert s.centred().height_range == pytest.approx(s.height_range)


# ------------------------------------------------------------------------------------------ generators


def test_sinusoid_period_and_amplitude():
    s = sinusoidal(period=1.6, amplitude=0.1)
    assert dominant_period(s) == pytest.approx(1.6, rel=0.005)
    assert s.height_range == pytest.approx(0.2, rel=1e-9)
    assert np.ptp(s.heights, axis=0).max() == 0.0  # constant along y (grooves along y)
    odd = sinusoidal(period=0.9, pixel=0.07)  # pixel adjusted to a whole number of pixels per period
    assert dominant_period(odd) == pytest.approx(0.9, rel=0.005)


def test_blazed_is_a_sawtooth():
    s = blazed(period=2.5, height=0.246)
    row = s.heights[0]
    n = round(2.5 / s.pixel[0])
    assert dominant_period(s) == pytest.approx(2.5, rel=0.005)
    steps = np.diff(np.concatenate([row, row[:1]]))
    rise = 0.246 / n
    drops = steps < 0
    assert drops.sum() == 10 and np.allclose(steps[drops], rise - 0.246)
    assert np.allclose(steps[~drops], rise)
    assert s.height_range + rise == pytest.approx(0.246)


@pytest.mark.parametrize("make, period", [(elaphe, 1.14), (xenopeltis, 1.55)])
def test_snake_ridges(make, period):
    s = make()
    assert dominant_period(s) == pytest.approx(period, rel=0.05)
    assert s.heights.min() >= 0.0 and s.heights.max() <= 0.4 * 1.2
    assert s.heights.max() > 0.4 * 0.9
    np.testing.assert_array_equal(make().heights, s.heights)
    assert not np.array_equal(make(seed=7).heights, s.heights)
    assert np.ptp(s.heights, axis=0).max() > 0.05  # wavy: not constant along y


@pytest.mark.parametrize("name", sorted(GENERATORS))
def test_generators_tile(name):
    h = generate(name).heights
    for axis in (0, 1):
        inside = np.abs(np.diff(h, axis=axis)).max()
        seam = np.abs(np.take(h, 0, axis=axis) - np.take(h, -1, axis=axis)).max()
        assert seam <= 1.05 * inside + 1e-12, (name, axis, seam, inside)
