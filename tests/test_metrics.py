"""Tests for prefilter.metrics: CIEDE2000 against Sharma, Wu, Dalal 2005 (Table 1), CIELAB against the CIE
formula, FLIP sanity and monotonicity, RMSE of known offsets, mask handling."""

import numpy as np
import pytest

from prefilter import metrics

# Sharma, Wu, Dalal, Color Res. Appl. 30(1), 2005, Table 1: (pair, Lab_1, Lab_2, ΔE00), printed to 4 decimals.
SHARMA_2005 = [
    (1, (50.0000, 2.6772, -79.7751), (50.0000, 0.0000, -82.7485), 2.0425),
    (2, (50.0000, 3.1571, -77.2803), (50.0000, 0.0000, -82.7485), 2.8615),
    (4, (50.0000, -1.3802, -84.2814), (50.0000, 0.0000, -82.7485), 1.0000),
    (7, (50.0000, 0.0000, 0.0000), (50.0000, -1.0000, 2.0000), 2.3669),
    (10, (50.0000, 2.4900, -0.0010), (50.0000, -2.4900, 0.0010), 7.1792),
    (11, (50.0000, 2.4900, -0.0010), (50.0000, -2.4900, 0.0011), 7.2195),
    (15, (50.0000, -0.0010, 2.4900), (50.0000, 0.0011, -2.4900), 4.7461),
    (17, (50.0000, 2.5000, 0.0000), (73.0000, 25.0000, -18.0000), 27.1492),
    (19, (50.0000, 2.5000, 0.0000), (56.0000, -27.0000, -3.0000), 31.9030),
    (25, (60.2574, -34.0099, 36.2677), (60.4626, -34.1751, 39.4387), 1.2644),
    (31, (90.8027, -2.0831, 1.4410), (91.1528, -1.6435, 0.0447), 1.4441),
    (34, (2.0776, 0.0795, -1.1350), (0.9033, -0.0636, -0.5514), 0.9082),
]


@pytest.mark.parametrize(
    "pair, lab_1, lab_2, expected", SHARMA_2005, ids=[f"pair{r[0]}" for r in SHARMA_2005]
)
def test_ciede2000_matches_sharma_2005(pair, lab_1, lab_2, expected):
    assert metrics.delta_e2000_lab(np.array(lab_1), np.array(lab_2)) == pytest.approx(expected, abs=5e-5)
    # the formula is symmetric in its arguments
    assert metrics.delta_e2000_lab(np.array(lab_2), np.array(lab_1)) == pytest.approx(expected, abs=5e-5)


def test_ciede2000_vectorised_over_image_shape():
    lab_1 = np.array([r[1] for r in SHARMA_2005]).reshape(3, 4, 3)
    lab_2 = np.array([r[2] for r in SHARMA_2005]).reshape(3, 4, 3)
    expected = np.array([r[3] for r in SHARMA_2005]).reshape(3, 4)
    np.testing.assert_allclose(metrics.delta_e2000_lab(lab_1, lab_2), expected, atol=5e-5)


def test_lab_of_greys_follows_cie_lightness_formula():
    # CIE 1976: L* = 116 (Y/Yn)^(1/3) - 16 for Y/Yn > (6/29)^3, and a* = b* = 0 for neutral greys.
    for y in (1.0, 0.5, 0.18, 0.05):
        lab = metrics.linear_srgb_to_lab(np.full(3, y))
        assert lab[0] == pytest.approx(116.0 * y ** (1.0 / 3.0) - 16.0, abs=1e-9)
        assert lab[1:] == pytest.approx([0.0, 0.0], abs=1e-9)
    # below the knee: L* = (29/3)^3 Y
    assert metrics.linear_srgb_to_lab(np.full(3, 0.001))[0] == pytest.approx((29.0 / 3.0) ** 3 * 0.001)


def test_lab_of_srgb_red_matches_published_value():
    # sRGB red in CIELAB (D65), as tabulated e.g. by Lindbloom: (53.24, 80.09, 67.20).
    np.testing.assert_allclose(
        metrics.linear_srgb_to_lab(np.array([1.0, 0.0, 0.0])), [53.24, 80.09, 67.20], atol=0.05
    )


def test_delta_e_map_identical_and_black_white():
    rng = np.random.default_rng(1)
    img = rng.random((8, 9, 3)).astype(np.float32)
    de = metrics.delta_e2000_map(img, img)
    assert de.shape == (8, 9) and de.dtype == np.float32
    assert np.all(de == 0)
    black = np.zeros((4, 5, 3), np.float32)
    white = np.ones((4, 5, 3), np.float32)
    # Lab (0, 0, 0) vs (100, 0, 0): ΔE00 = 100 (lightness term only, S_L = 1 at mean L = 50)
    np.testing.assert_allclose(metrics.delta_e2000_map(black, white), 100.0, atol=1e-4)


def test_flip_identical_is_zero_and_black_white_is_large():
    rng = np.random.default_rng(2)
    img = rng.random((48, 48, 3)).astype(np.float32)
    f = metrics.flip_map(img, img)
    assert f.shape == (48, 48) and f.dtype == np.float32
    assert np.all(f == 0)
    black = np.zeros((32, 32, 3), np.float32)
    white = np.ones((32, 32, 3), np.float32)
    assert metrics.flip_map(black, white).mean() > 0.5


def test_flip_grows_with_noise_amplitude():
    rng = np.random.default_rng(3)
    ref = np.clip(0.2 + 0.4 * rng.random((64, 64, 1)), 0, 1) * np.array([1.0, 0.8, 0.6])
    noise = rng.standard_normal((64, 64, 3))
    means = [metrics.flip_map(np.clip(ref + a * noise, 0, 1), ref).mean() for a in (0.0, 0.01, 0.04, 0.16)]
    assert means[0] == 0
    assert all(b > a for a, b in zip(means, means[1:], strict=False)), means


def test_flip_clips_out_of_range_linear_values():
    ref = np.full((16, 16, 3), 0.5)
    assert np.all(metrics.flip_map(np.full((16, 16, 3), 7.0), np.ones((16, 16, 3))) == 0)
    assert metrics.flip_map(ref, ref).max() == 0


def test_rmse_of_constant_offset_is_the_offset():
    rng = np.random.default_rng(4)
    ref = rng.random((10, 12, 3)).astype(np.float32)
    mask = np.ones((10, 12), bool)
    assert metrics.rmse(ref + np.float32(0.125), ref, mask) == pytest.approx(0.125, rel=1e-6)
    # a large error outside the mask is ignored
    test = ref + np.float32(0.25)
    test[:3] = 100.0
    mask[:3] = False
    assert metrics.rmse(test, ref, mask) == pytest.approx(0.25, rel=1e-6)


def test_rmse_is_unclipped_linear():
    ref = np.zeros((2, 2, 3))
    test = ref.copy()
    test[..., 0] = 3.0  # one channel of three off by 3: sqrt(9 / 3)
    assert metrics.rmse(test, ref, np.ones((2, 2), bool)) == pytest.approx(np.sqrt(3.0))


def test_compare_averages_over_mask():
    rng = np.random.default_rng(5)
    ref = rng.random((40, 40, 3)).astype(np.float32)
    test = np.clip(ref + 0.05 * rng.standard_normal(ref.shape), 0, 1).astype(np.float32)
    mask = np.zeros((40, 40), bool)
    mask[5:30, 10:35] = True
    out = metrics.compare(test, ref, mask)
    assert set(out) == {"flip", "delta_e", "rmse", "flip_map"}
    fmap = metrics.flip_map(np.where(mask[..., None], test, ref), ref)
    np.testing.assert_array_equal(out["flip_map"], fmap)
    assert out["flip"] == pytest.approx(fmap[mask].mean(dtype=np.float64))
    assert out["delta_e"] == pytest.approx(metrics.delta_e2000_map(test, ref)[mask].mean(dtype=np.float64))
    assert out["rmse"] == pytest.approx(metrics.rmse(test, ref, mask))
    assert 0 < out["flip"] < 1 and out["delta_e"] > 0
    same = metrics.compare(ref, ref, mask)
    assert same["flip"] == 0 and same["delta_e"] == 0 and same["rmse"] == 0


def test_errors_off_the_mask_do_not_leak_into_covered_pixels():
    """A hard edge just outside the mask (an aliased silhouette) must not change the covered pixels' FLIP,
    although FLIP's spatial filters would carry it several pixels inwards."""
    rng = np.random.default_rng(6)
    ref = np.full((48, 48, 3), 0.5, np.float32)
    test = np.clip(ref + 0.02 * rng.standard_normal(ref.shape), 0, 1).astype(np.float32)
    mask = np.zeros((48, 48), bool)
    mask[8:40, 8:24] = True
    with_edge = test.copy()
    with_edge[:, 24:26] = 1.0  # a bright aliased edge in the two columns next to the mask
    clean = metrics.compare(test, ref, mask)["flip"]
    assert metrics.compare(with_edge, ref, mask)["flip"] == pytest.approx(clean, rel=1e-6)
    # evaluated naively on the whole image, the edge would have raised the covered pixels' mean
    assert metrics.flip_map(with_edge, ref)[mask].mean() > 1.2 * clean


def test_empty_mask_raises():
    img = np.zeros((4, 4, 3), np.float32)
    with pytest.raises(ValueError, match="empty"):
        metrics.compare(img, img, np.zeros((4, 4), bool))
    with pytest.raises(ValueError, match="empty"):
        metrics.rmse(img, img, np.zeros((4, 4), bool))


def test_bad_mask_and_shapes_raise():
    img = np.zeros((4, 4, 3), np.float32)
    with pytest.raises(ValueError, match="boolean"):
        metrics.compare(img, img, np.ones((4, 4)))
    with pytest.raises(ValueError, match="shape"):
        metrics.compare(img, img, np.ones((4, 5), bool))
    with pytest.raises(ValueError):
        metrics.flip_map(img, np.zeros((4, 5, 3)))
    with pytest.raises(ValueError, match="ppd"):
        metrics.flip_map(img, img, ppd=0)
