"""The bench's helpers that need no GL (bench.py)."""

import math

import numpy as np
import pytest

from prefilter.bench import equal_time_size


@pytest.mark.parametrize("size", [(256, 256), (512, 384), (640, 360), (300, 200)])
@pytest.mark.parametrize("ratio", [0.7, 1.0, 1.3, 2.0, 4.0])
def test_equal_time_size_is_the_largest_render_of_the_same_aspect_within_the_budget(size, ratio):
    w, h = size
    big_w, big_h = equal_time_size(size, ratio)
    assert big_w * h == big_h * w  # the same aspect exactly: the camera's view is unchanged
    assert (big_w, big_h) >= (w, h)
    if ratio >= 1.0:
        assert big_w * big_h <= ratio * w * h + 1e-9
        step = (w // math.gcd(w, h), h // math.gcd(w, h))  # the next size of that aspect is over budget
        assert (big_w + step[0]) * (big_h + step[1]) > ratio * w * h
    else:
        assert (big_w, big_h) == (w, h)
    if ratio == 4.0:
        assert (big_w, big_h) == (2 * w, 2 * h)


def _comparison(point, naive, reference):
    from types import SimpleNamespace

    from prefilter.gl.render import REFERENCE
    from prefilter.metrics import compare

    images = {"point": point, "naive": naive, "texture-filter": naive, REFERENCE: reference}
    mask = np.ones(reference.shape[:2], bool)
    metrics = {m: compare(images[m], reference, mask) for m in ("point", "naive", "texture-filter")}
    return SimpleNamespace(images=images, mask=mask, metrics=metrics)


def test_the_resolved_oracle_keeps_point_where_the_microsurface_changes_nothing_and_is_exact_elsewhere():
    from prefilter.bench import RESOLVED_TOLERANCE, resolved_oracle
    from prefilter.metrics import compare

    rng = np.random.default_rng(3)
    reference = rng.uniform(0.1, 0.9, (48, 64, 3))
    point = np.clip(reference + rng.normal(0.0, 0.1, reference.shape), 0.0, 1.0)
    # everything resolved: the oracle is point itself
    everything = resolved_oracle(_comparison(point, point + 0.5 * RESOLVED_TOLERANCE, reference))
    assert everything["resolved_share"] == 1.0
    whole = np.ones((48, 64), bool)
    assert everything["flip"] == pytest.approx(float(compare(point, reference, whole)["flip"]))
    # nothing resolved: the oracle is the reference
    nothing = resolved_oracle(_comparison(point, point + 2.0 * RESOLVED_TOLERANCE, reference))
    assert nothing["resolved_share"] == 0.0 and nothing["flip"] == pytest.approx(0.0, abs=1e-6)
    # the left quarter resolved (one channel off by more than the tolerance elsewhere)
    naive = point.copy()
    naive[:, 16:, 1] += 3.0 * RESOLVED_TOLERANCE
    part = resolved_oracle(_comparison(point, naive, reference))
    assert part["resolved_share"] == pytest.approx(0.25)
    assert 0.0 < part["flip"] < everything["flip"]


def test_the_samples_study_scores_each_setting_against_the_presets_own_reference():
    """bench's shading-samples study on micro-slopes-sphere (which shades once): the preset's own row
    first, its FLIP from the main table, then 2, 3 and 4 samples, each scored against the same reference as an
    independent render of that setting, with the three targets read off its numbers; every setting's time
    is the median of its rounds' ratios to naive, within their range."""
    from dataclasses import replace

    from prefilter.bench import samples_study
    from prefilter.compare import compare_scene
    from prefilter.gl.render import REFERENCE, Renderer, composite
    from prefilter.metrics import compare
    from prefilter.scene import resolve_scene

    scene = resolve_scene("micro-slopes-sphere")
    result = compare_scene(scene, size=(64, 64), spp=4, modes=["naive", "texture-filter", "surface-filter"])
    study = samples_study(scene, result, frames=5)
    assert [r["shading_samples"] for r in study] == [1, 2, 3, 4]
    assert study[0]["flip"] == result.metrics["surface-filter"]["flip"]
    material = replace(scene.objects[0].material, shading_samples=4)
    renderer = Renderer(replace(scene, objects=[replace(scene.objects[0], material=material)]), (64, 64))
    try:
        image = composite(renderer.render("surface-filter"), scene.background)
    finally:
        renderer.release()
    assert study[3]["flip"] == pytest.approx(compare(image, result.images[REFERENCE], result.mask)["flip"])
    naive, texture = result.metrics["naive"]["flip"], result.metrics["texture-filter"]["flip"]
    for r in study:
        assert r["vs_naive"] == pytest.approx(r["flip"] / naive)
        assert r["targets"]["flip_le_third_naive"] == (r["flip"] <= naive / 3.0)
        assert r["targets"]["flip_le_half_texture_filter"] == (r["flip"] <= 0.5 * texture)
        assert r["targets"]["time_le_1.5_naive"] == (r["time_vs_naive"] <= 1.5)
        low, high = r["time_vs_naive_range"]
        assert 0.0 < low <= r["time_vs_naive"] <= high
