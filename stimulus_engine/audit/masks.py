"""Which pixels are the face: a mask per stimulus image.

Three kinds, each a boolean ``(H, W)`` array:

* a rendered grid's image (:func:`rendered_face_mask`): the filled face oval of the grid's framing
  (:func:`stimulus_engine.render.vignette.face_oval`, no feather) intersected with the pixels
  that are not the renderer's background colour;
* a photograph (:func:`landmark_face_mask`): the convex hull of its 68 dlib landmarks (jaw line,
  brows: the face from the brows down, without forehead, hair or ears);
* the whole image (:func:`whole_image_mask`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from appeal.errors import AppealInputError

__all__ = ["BACKGROUND_TOLERANCE", "oval_mask", "background_mask", "rendered_face_mask", "find_landmarks",
           "landmarks_or_none", "warn_faceless",
           "grid_render_settings", "landmark_face_mask", "whole_image_mask"]

#: A pixel is background when every channel is within this many 8-bit levels of the background colour.
BACKGROUND_TOLERANCE = 3


def oval_mask(height: int, width: int, oval: tuple[float, ...]) -> np.ndarray:
    """The filled ellipse ``hypot((x + 0.5 - cx) / rx, (y + 0.5 - cy) / ry) <= 1`` (pixel centres)
    of ``oval = (cx, cy, rx, ry, ...)`` in pixels, as :func:`~stimulus_engine.render.vignette.face_oval` gives it."""
    cx, cy, rx, ry = oval[:4]
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    return np.hypot((x + 0.5 - cx) / rx, (y + 0.5 - cy) / ry) <= 1.0


def background_mask(image: np.ndarray, background: tuple[float, float, float],
                    tolerance: int = BACKGROUND_TOLERANCE) -> np.ndarray:
    """Pixels whose every channel lies within ``tolerance`` levels of the background colour:
    ``|pixel - 255 * background| <= tolerance + 0.5`` per channel (``background`` in 0..1 RGB, the
    renderer's clear colour; the half level covers its rounding, 0.5 -> 127.5 -> 128)."""
    bg = np.asarray(background, np.float64) * 255.0
    diff = np.abs(np.asarray(image)[..., :3].astype(np.float64) - bg)
    return np.all(diff <= tolerance + 0.5, axis=-1)


def rendered_face_mask(image: np.ndarray, width: int, height: int, eye_row: float, face_fraction: float,
                       background: tuple[float, float, float], tolerance: int = BACKGROUND_TOLERANCE) -> np.ndarray:
    """The face of a rendered grid image: inside the framing's face oval and not background.

    ``width, height, eye_row, face_fraction, background`` are the grid's ``render`` settings
    (``grid.json``); the oval is scaled to the image's own size when that differs.
    """
    from stimulus_engine.render.vignette import face_oval

    h, w = image.shape[:2]
    cx, cy, rx, ry, _ = face_oval(width, height, eye_row, face_fraction)
    sx, sy = w / width, h / height
    inside = oval_mask(h, w, (cx * sx, cy * sy, rx * sx, ry * sy))
    return inside & ~background_mask(image, background, tolerance)


def grid_render_settings(folder: Path) -> dict[str, Any] | None:
    """A rendered grid's ``render`` settings that frame its faces (``width``, ``height``,
    ``eye_row``, ``face_fraction``, ``background``) from ``folder/grid.json``; None without one."""
    import json

    path = Path(folder) / "grid.json"
    if not path.is_file():
        return None
    try:
        render = json.loads(path.read_text(encoding="utf-8"))["render"]
        return {k: render[k] for k in ("width", "height", "eye_row", "face_fraction", "background")}
    except (ValueError, KeyError, TypeError) as exc:
        raise AppealInputError(f"{path}: not a grid's grid.json with render width/height/eye_row/face_fraction/"
                               f"background ({type(exc).__name__}: {exc})".splitlines()[0]) from None


def find_landmarks(image: np.ndarray, name: str) -> np.ndarray:
    """The 68 dlib landmarks ``(68, 2)`` of the largest face in ``image`` (pixels).

    Raises
    ------
    AppealInputError
        One line naming ``name`` when the detector finds no face.
    """
    from stimulus_engine.morphpca.keypoints import detect_landmarks

    try:
        return detect_landmarks(image, name)
    except AppealInputError:
        raise AppealInputError(f"{name}: no face found by the dlib landmark detector (expected a frontal "
                               "face photograph)") from None


def landmarks_or_none(image: np.ndarray, name: str) -> np.ndarray | None:
    """:func:`find_landmarks`, or None when dlib finds no face (a house, an object, noise)."""
    try:
        return find_landmarks(image, name)
    except AppealInputError:
        return None


def warn_faceless(names: list[str], total: int, treatment: str) -> None:
    """One warning line: how many of ``total`` images have no face, what is done with them
    (``treatment``) and their names (the first eight, then a count)."""
    from appeal.logs import logger

    if names:
        shown = ", ".join(names[:8]) + (f" and {len(names) - 8} more" if len(names) > 8 else "")
        logger.warning("%d of %d images without a face (dlib): %s: %s", len(names), total, treatment, shown)


def landmark_face_mask(shape: tuple[int, int], landmarks: np.ndarray) -> np.ndarray:
    """The filled convex hull of ``landmarks`` ``(N, 2)`` (x, y pixels) in an image of ``shape`` (H, W)."""
    from scipy.spatial import ConvexHull
    from skimage.draw import polygon

    pts = np.asarray(landmarks, np.float64)
    hull = pts[ConvexHull(pts).vertices]
    mask = np.zeros(shape[:2], bool)
    rr, cc = polygon(hull[:, 1], hull[:, 0], shape=shape[:2])
    mask[rr, cc] = True
    return mask


def whole_image_mask(shape: tuple[int, ...]) -> np.ndarray:
    """Every pixel of an image of ``shape`` (H, W, ...)."""
    return np.ones(shape[:2], bool)
