"""A photograph framed like a rendered image: its eye centres and philtrum on the render's (dlib).

Used by the photo sheet (:mod:`~stimulus_engine.grid.photo_sheet`) and by a grid's ``photographs:``
level (:func:`~stimulus_engine.grid.worker.place_photo`), so a character's photograph lands where
its renders put the face.
"""

from __future__ import annotations

import numpy as np

__all__ = ["photo_like_render"]


def _faceframe(image: np.ndarray, name: str) -> np.ndarray:
    from stimulus_engine.morphpca.keypoints import detect_faceframe

    return detect_faceframe(image, name)  # eye centres and philtrum


def photo_like_render(photo: np.ndarray, render: np.ndarray, background: tuple[int, int, int],
                      name: str = "photo") -> np.ndarray:
    """``photo`` moved, scaled and turned so its eye centres and philtrum fall on ``render``'s
    (least squares), at the render's size."""
    import cv2

    from stimulus_engine.correspondence.alignment import umeyama

    src = _faceframe(photo, name)
    dst = _faceframe(render, "rendered image")
    pad = lambda p: np.c_[p, np.zeros(len(p))]  # noqa: E731 - 2D points as 3D for umeyama
    sim = umeyama(pad(src), pad(dst))
    m = (sim.scale * sim.rotation)[:2, :2]
    affine = np.c_[m, sim.translation[:2]]
    h, w = render.shape[:2]
    return cv2.warpAffine(np.ascontiguousarray(photo[..., :3]), affine, (w, h), flags=cv2.INTER_AREA,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=tuple(int(b) for b in background))
