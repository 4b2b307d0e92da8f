"""Moving a face image's landmarks to new positions: the one warp every 2-D operation uses.

:func:`warp_to_points` is a thin-plate-spline backward warp (:func:`stimulus_engine.morphpca.
landmark_warp.tps_displacement`, border pinned): each output pixel is sampled from where the
spline from the target points to the image's points sends it, so there are no holes.
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.morphpca.flow import grid, warp_image
from stimulus_engine.morphpca.landmark_warp import tps_displacement

__all__ = ["warp_to_points"]


def warp_to_points(image: np.ndarray, points: np.ndarray, target: np.ndarray, *, pin_border: bool = True) -> np.ndarray:
    """``image`` warped so that its ``points`` ``(n, 2)`` land on ``target`` ``(n, 2)`` (same size out).

    Parameters
    ----------
    image : (h, w) or (h, w, c) array
        The image (float or uint8; float out).
    points, target : (n, 2) arrays
        Corresponding (x, y) positions in the image and in the output.
    pin_border : bool
        Keep the image border in place (the warp fades out towards it).

    Returns
    -------
    ndarray
        The warped image, float32, same shape as ``image``.
    """
    h, w = image.shape[:2]
    back = tps_displacement(np.asarray(target, np.float64), np.asarray(points, np.float64), (h, w),
                            pin_border=pin_border)
    return warp_image(np.asarray(image, np.float32), grid(h, w) + back)
