"""Masks: an oval or the landmark hull of the face, with a soft edge (WebMorph's *Mask* / webmorphR's
``mask_oval``).

A mask is an ``(h, w)`` float32 array: 1 inside, 0 outside and a linear ramp ``feather`` pixels wide
centred on the outline (signed distance to the outline / ``feather`` + 0.5, clipped). The outline
comes from the template's face points (:func:`face_points`):

* ``"hull"`` — their convex hull;
* ``"oval"`` — the ellipse inscribed in their bounding box (as webmorphR's ``mask_oval``).

:func:`apply_mask` puts the masked face on a background colour, or returns RGBA with the mask as
alpha (a transparent PNG).
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

__all__ = ["MASK_KINDS", "FACE_189", "face_points", "face_mask", "apply_mask"]

MASK_KINDS = ("oval", "hull")

#: FRL/WebMorph 189-point template: the face outline (temples, cheeks, jaw and chin, 109–114 and
#: 125–133) and the hairline across the forehead (134–144); ears, hair and neck are left out.
FACE_189 = tuple(range(109, 115)) + tuple(range(125, 145))


def face_points(points: np.ndarray) -> np.ndarray:
    """The points that outline the face: :data:`FACE_189` of a 189-point template, every point of
    another (dlib's 68 reach from the jaw up to the brows)."""
    p = np.asarray(points, np.float64)
    return p[list(FACE_189)] if len(p) == 189 else p


def face_mask(shape: tuple[int, int], points: np.ndarray, kind: str = "oval", feather: float = 10.0,
              subset: Sequence[int] | None = None) -> np.ndarray:
    """A soft face mask.

    Parameters
    ----------
    shape : (h, w)
        Image size.
    points : (n, 2) array
        The image's template points.
    kind : {"oval", "hull"}
        The outline (see the module docstring).
    feather : float
        Width in pixels of the soft edge (0: a hard edge).
    subset : sequence of int, optional
        Template points to use instead of :func:`face_points`.

    Returns
    -------
    (h, w) float32 array in [0, 1]
    """
    if kind not in MASK_KINDS:
        raise ValueError(f"mask kind must be one of {MASK_KINDS} (got {kind!r})")
    h, w = int(shape[0]), int(shape[1])
    p = np.asarray(points, np.float64)[list(subset)] if subset is not None else face_points(points)
    hard = np.zeros((h, w), np.uint8)
    if kind == "hull":
        hull = cv2.convexHull(np.round(p).astype(np.int32))
        cv2.fillConvexPoly(hard, hull, 1, lineType=cv2.LINE_8)
    else:
        lo, hi = p.min(0), p.max(0)
        centre, axes = (lo + hi) / 2, (hi - lo) / 2
        cv2.ellipse(hard, (int(round(centre[0])), int(round(centre[1]))),
                    (max(1, int(round(axes[0]))), max(1, int(round(axes[1])))), 0, 0, 360, 1, -1)
    if feather <= 0:
        return hard.astype(np.float32)
    inside = cv2.distanceTransform(hard, cv2.DIST_L2, 5)
    outside = cv2.distanceTransform(1 - hard, cv2.DIST_L2, 5)
    signed = np.where(hard > 0, inside - 0.5, 0.5 - outside)
    return np.clip(signed / float(feather) + 0.5, 0.0, 1.0).astype(np.float32)


def apply_mask(image: np.ndarray, mask: np.ndarray, fill: Sequence[float] | None = (1.0, 1.0, 1.0)) -> np.ndarray:
    """``image`` (float RGB) over ``fill`` through ``mask``; ``fill=None`` gives RGBA with the mask as alpha."""
    img = np.asarray(image, np.float32)[..., :3]
    m = np.asarray(mask, np.float32)[..., None]
    if fill is None:
        return np.concatenate([img, m], axis=2)
    bg = np.asarray(fill, np.float32)[:3].reshape(1, 1, 3)
    return (img * m + bg * (1.0 - m)).astype(np.float32)
