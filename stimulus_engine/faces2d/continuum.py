"""Continua between two faces (WebMorph's *Continuum*): A → B in n steps.

Step *t* (from 0 to 1) has the shape ``(1 - t) A + t B`` (templates interpolated point by point);
both end images are warped onto that shape and cross-dissolved with weights ``1 - t`` and ``t``.
Shape and colour move together (one weight); the end steps reproduce A and B (warped onto their
own templates, i.e. resampled through a near-identity spline).
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.faces2d.composite import blend
from stimulus_engine.faces2d.warp import warp_to_points

__all__ = ["morph", "continuum", "continuum_weights"]


def continuum_weights(steps: int) -> np.ndarray:
    """``steps`` evenly spaced weights from 0 (A) to 1 (B)."""
    if steps < 2:
        raise ValueError(f"a continuum needs at least 2 steps (got {steps})")
    return np.linspace(0.0, 1.0, int(steps))


def morph(image_a: np.ndarray, points_a: np.ndarray, image_b: np.ndarray, points_b: np.ndarray, t: float, *,
          colour_space: str = "srgb") -> tuple[np.ndarray, np.ndarray]:
    """The face a fraction ``t`` of the way from A to B (shape and colour).

    Parameters
    ----------
    image_a, image_b : (h, w, 3) float arrays
        Same size (align them first).
    points_a, points_b : (n, 2) arrays
        Their templates' points.
    t : float
        0 = A, 1 = B (values outside [0, 1] extrapolate).
    colour_space : {"srgb", "linear"}
        Where the cross-dissolve mixes colours.

    Returns
    -------
    (image, points)
    """
    pa, pb = np.asarray(points_a, np.float64), np.asarray(points_b, np.float64)
    shape = (1.0 - t) * pa + t * pb
    if t == 0.0:
        return blend([warp_to_points(image_a, pa, shape)], [1.0], colour_space), shape
    if t == 1.0:
        return blend([warp_to_points(image_b, pb, shape)], [1.0], colour_space), shape
    wa, wb = warp_to_points(image_a, pa, shape), warp_to_points(image_b, pb, shape)
    return blend([wa, wb], [1.0 - t, t], colour_space), shape


def continuum(image_a: np.ndarray, points_a: np.ndarray, image_b: np.ndarray, points_b: np.ndarray, steps: int, *,
              colour_space: str = "srgb") -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`morph` at ``steps`` evenly spaced weights from A (first) to B (last)."""
    return [morph(image_a, points_a, image_b, points_b, float(t), colour_space=colour_space)
            for t in continuum_weights(steps)]
