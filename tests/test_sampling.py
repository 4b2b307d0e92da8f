"""The bilinear sampler (stimulus_engine.geometry.sampling) against the bilinear formula."""

from __future__ import annotations

import numpy as np

from stimulus_engine.geometry.sampling import sample_points, uv_to_pixels


def _bilinear(image, x, y):
    """Exact float64 bilinear interpolation with clamped coordinates (replicated border)."""
    h, w = image.shape[:2]
    x, y = np.clip(x, 0, w - 1), np.clip(y, 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bot = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bot * fy


def test_sample_points_is_bilinear_with_replicated_border():
    rng = np.random.default_rng(1)
    image = rng.uniform(0, 255, size=(37, 53, 3))
    # more points than cv2.remap takes in one map row (32767), some beyond every border
    xy = rng.uniform(-3, [56, 40], size=(40000, 2))
    got = sample_points(image, xy)
    want = _bilinear(image, xy[:, 0].astype(np.float32).astype(np.float64), xy[:, 1].astype(np.float32).astype(np.float64))
    assert got.shape == (40000, 3)
    np.testing.assert_allclose(got, want, atol=1e-3)  # float32 sums of values up to 255


def test_sample_points_fractions_are_not_quantised():
    ramp = np.tile(np.arange(8, dtype=np.float32), (3, 1))  # value = x
    x = np.linspace(2, 3, 101)
    got = sample_points(ramp, np.column_stack([x, np.ones_like(x)]))
    assert got.shape == (101, 1)
    np.testing.assert_allclose(got[:, 0], x, atol=1e-6)  # not in 1/32-pixel steps


def test_uv_to_pixels_bottom_left_origin():
    px = uv_to_pixels(np.array([[0.0, 0.0], [1.0, 1.0], [0.5, 0.5]]), 4, 2)
    np.testing.assert_array_equal(px, [[-0.5, 1.5], [3.5, -0.5], [1.5, 0.5]])
