"""Faceframes (eye centres + philtrum) and the affine transforms between them (Nagle et al. §3).

A faceframe is a ``(3, 2)`` array of (x, y): left eye centre, right eye centre (as seen in the
image: left = smaller x) and philtrum centre. The affine transform between two faceframes
aligns relative morph vectors (warp and texture) before projection, and generated images
before averaging (§4 step 7).
"""

from __future__ import annotations

import cv2
import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.morphpca.morphvec import deserialise, serialise

__all__ = ["check_faceframe", "faceframe_affine", "similarity_from_eyes", "transform_points", "align_relative_vector",
           "align_image"]


def check_faceframe(frame, what: str = "faceframe") -> np.ndarray:
    """A valid ``(3, 2)`` float faceframe (finite, non-degenerate triangle) or an input error."""
    arr = np.asarray(frame, dtype=np.float64)
    if arr.shape != (3, 2) or not np.all(np.isfinite(arr)):
        raise AppealInputError(f"{what}: expected 3 finite (x, y) points: left eye, right eye, philtrum (got {arr.tolist()})")
    (ax, ay), (bx, by) = arr[1] - arr[0], arr[2] - arr[0]
    area = 0.5 * abs(ax * by - ay * bx)
    if area < 1e-6:
        raise AppealInputError(f"{what}: the 3 points are collinear (expected eyes and philtrum forming a triangle)")
    return arr


def faceframe_affine(src, dst) -> np.ndarray:
    """The 2×3 affine matrix mapping faceframe ``src`` exactly onto ``dst``."""
    return cv2.getAffineTransform(check_faceframe(src, "source faceframe").astype(np.float32),
                                  check_faceframe(dst, "target faceframe").astype(np.float32)).astype(np.float64)


def similarity_from_eyes(src_eyes, dst_eyes) -> np.ndarray:
    """2×3 similarity (rotation, uniform scale, translation) mapping two eye centres onto two others."""
    s = np.asarray(src_eyes, float).reshape(2, 2)
    d = np.asarray(dst_eyes, float).reshape(2, 2)
    vs, vd = s[1] - s[0], d[1] - d[0]
    zs, zd = complex(*vs), complex(*vd)
    if abs(zs) < 1e-9:
        raise AppealInputError("keypoints: the two eye centres coincide (expected distinct eye positions)")
    r = zd / zs
    a, b = r.real, r.imag
    m = np.array([[a, -b, 0.0], [b, a, 0.0]])
    m[:, 2] = d[0] - m[:, :2] @ s[0]
    return m


def transform_points(matrix: np.ndarray, points) -> np.ndarray:
    """Apply a 2×3 affine matrix to ``(..., 2)`` points."""
    p = np.asarray(points, float)
    return p @ matrix[:, :2].T + matrix[:, 2]


def align_relative_vector(relative: np.ndarray, size_from: tuple[int, int], frame_from, size_to: tuple[int, int],
                          frame_to) -> np.ndarray:
    """Move a mean-relative morph vector from one faceframe to another.

    The texture residual and the relative warp (a displacement field, since the mean warp is
    the identity) are resampled through the affine map between the faceframes, and the warp
    vectors are transformed by its linear part. Outside the source frame the residual is 0
    (the target's mean).
    """
    a = faceframe_affine(frame_from, frame_to)
    tex, disp = deserialise(relative, size_from)
    h, w = size_to
    flags, border = cv2.INTER_LINEAR, cv2.BORDER_CONSTANT
    tex2 = cv2.warpAffine(np.ascontiguousarray(tex), a, (w, h), flags=flags, borderMode=border, borderValue=0)
    disp2 = cv2.warpAffine(np.ascontiguousarray(disp), a, (w, h), flags=flags, borderMode=border, borderValue=0)
    disp2 = disp2 @ a[:, :2].T.astype(np.float32)
    return serialise(tex2, disp2)


def align_image(image: np.ndarray, frame_from, frame_to, size: tuple[int, int] | None = None) -> np.ndarray:
    """Warp an image so that faceframe ``frame_from`` lands on ``frame_to`` (border replicated)."""
    a = faceframe_affine(frame_from, frame_to)
    h, w = size if size is not None else image.shape[:2]
    return cv2.warpAffine(np.ascontiguousarray(image, np.float32), a, (w, h), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_REPLICATE)
