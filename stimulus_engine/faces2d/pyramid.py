"""Laplacian pyramids: an image as band-pass layers (finest first) and a low-pass residual, and back.

Used where texture (fine detail) is handled apart from shape and colour: the composite's texture
restore (:mod:`~stimulus_engine.faces2d.composite`) and the prototype transform's texture
weight (:mod:`~stimulus_engine.faces2d.transform`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["LUMA", "laplacian_pyramid", "collapse_pyramid", "band_amplitudes"]


def laplacian_pyramid(image: np.ndarray, levels: int) -> list[np.ndarray]:
    """``levels`` band-pass images (finest first, each ``image − up(down(image))`` at its scale), then
    the low-pass residual; :func:`collapse_pyramid` inverts it exactly (up to float rounding)."""
    import cv2

    bands, cur = [], np.asarray(image, np.float32)
    for _ in range(levels):
        down = cv2.pyrDown(cur)
        up = cv2.pyrUp(down, dstsize=(cur.shape[1], cur.shape[0]))
        bands.append(cur - up)
        cur = down
    return bands + [cur]


def collapse_pyramid(bands: list[np.ndarray]) -> np.ndarray:
    """The image of a :func:`laplacian_pyramid` (residual last)."""
    import cv2

    cur = bands[-1]
    for band in reversed(bands[:-1]):
        cur = cv2.pyrUp(cur, dstsize=(band.shape[1], band.shape[0])) + band
    return cur


#: Rec. 601 luma weights (R, G, B) for the bands' local contrast.
LUMA = np.array([0.299, 0.587, 0.114], np.float32)


def band_amplitudes(image: np.ndarray, levels: int) -> list[np.ndarray]:
    """Local contrast of each band-pass layer of the image's luma: ``|band|`` smoothed by a Gaussian of
    2 pixels at the band's own scale (finest first, ``levels`` of them)."""
    import cv2

    grey = np.asarray(image, np.float32) @ LUMA if np.ndim(image) == 3 else np.asarray(image, np.float32)
    return [cv2.GaussianBlur(np.abs(b), (0, 0), 2.0) for b in laplacian_pyramid(grey, levels)[:-1]]
