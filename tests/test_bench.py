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
