"""The bench's helpers that need no GL (bench.py)."""

import math

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
