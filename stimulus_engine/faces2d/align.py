"""Landmarked face photographs in, and aligned on the pupils (WebMorph's *Align*).

A :class:`Face` is an RGB image (float32 in [0, 1]) with its template: the ``.tem`` beside the
image file (WebMorph/Psychomorph, e.g. the 189-point FRL template) or, when there is none, dlib's
68 detected landmarks (:func:`stimulus_engine.morphpca.keypoints.detect_landmarks`). All faces of
one call must share a template type (same point count): averaging and morphing pair point *i*
of one face with point *i* of another.

:func:`align_face` moves an image by the similarity transform (rotation, uniform scale,
translation) that puts its two pupils exactly on two target positions, into an output of a
given size; uncovered areas get a background colour and the template moves with the image.
The pupils are points 0 and 1 of a ``.tem`` (WebMorph's convention) and the eye centres
(means of points 36–41 and 42–47) of a 68-point template.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.faces2d.template import Template, read_template

__all__ = ["Face", "read_face", "load_faces", "eye_points", "align_matrix", "align_face", "default_eyes",
           "same_size"]

DLIB_68 = 68


@dataclass(frozen=True, eq=False)
class Face:
    """An image (``(h, w, 3)`` float32 RGB in [0, 1]), its template and where both came from.

    ``source`` is ``"tem"`` (read from ``tem_path``) or ``"dlib68"`` (detected)."""

    image: np.ndarray
    template: Template
    path: Path
    source: str
    tem_path: Path | None = None

    @property
    def points(self) -> np.ndarray:
        return self.template.points

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)``."""
        return int(self.image.shape[1]), int(self.image.shape[0])


def read_rgb(path: str | Path) -> np.ndarray:
    """An image file as ``(h, w, 3)`` float32 RGB in [0, 1] (one-line error naming the file)."""
    path = Path(path)
    if not path.is_file():
        raise AppealInputError(f"{path}: image file not found")
    data = np.fromfile(str(path), np.uint8)
    bgr = cv2.imdecode(data, cv2.IMREAD_COLOR) if data.size else None
    if bgr is None:
        raise AppealInputError(f"{path}: not a readable image (expected a PNG or JPEG photograph)")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0


def read_face(path: str | Path, *, detect: bool = True) -> Face:
    """An image and its template: the ``.tem`` beside it, else (``detect``) dlib's 68 landmarks.

    Raises
    ------
    AppealInputError
        Unreadable image, malformed ``.tem``, no ``.tem`` and ``detect`` off, or no face found.
    """
    path = Path(path)
    image = read_rgb(path)
    tem = path.with_suffix(".tem")
    if tem.is_file():
        return Face(image, read_template(tem), path, "tem", tem)
    if not detect:
        raise AppealInputError(f"{path}: no template {tem.name} beside the image")
    from stimulus_engine.morphpca.keypoints import detect_landmarks

    return Face(image, Template(detect_landmarks(image, str(path))), path, "dlib68")


def _describe(face: Face) -> str:
    return (f"{face.tem_path.name} ({len(face.points)} points)" if face.source == "tem"
            else f"no .tem (detected {len(face.points)} dlib points)")


def load_faces(paths: Sequence[str | Path], *, detect: bool = True) -> list[Face]:
    """:func:`read_face` for each path; all must have the same template type.

    Raises
    ------
    AppealInputError
        As :func:`read_face`, or templates that differ in point count (or some faces with a
        ``.tem`` and others detected): the first odd file is named.
    """
    if not paths:
        raise AppealInputError("no images given (expected image files with a .tem beside each)")
    faces = [read_face(p, detect=detect) for p in paths]
    first = faces[0]
    for f in faces[1:]:
        if len(f.points) != len(first.points) or f.source != first.source:
            raise AppealInputError(f"{f.path}: template mismatch: {_describe(f)}, but {first.path.name} has "
                                   f"{_describe(first)} (all images of one call must use the same template type)")
    return faces


def same_size(faces: Sequence[Face], what: str = "this step") -> tuple[int, int]:
    """The faces' common ``(width, height)``; a one-line error naming the first image of another size."""
    size = faces[0].size
    for f in faces[1:]:
        if f.size != size:
            raise AppealInputError(f"{f.path}: image is {f.size[0]}x{f.size[1]} but {faces[0].path.name} is "
                                   f"{size[0]}x{size[1]} ({what} needs one size: run 'appeal faces align' first)")
    return size


def eye_points(points: np.ndarray) -> np.ndarray:
    """The two pupils ``(2, 2)`` of a template: points 0, 1 (``.tem``) or the eye centres (68 points),
    image-left first."""
    p = np.asarray(points, np.float64)
    eyes = np.array([p[36:42].mean(0), p[42:48].mean(0)]) if len(p) == DLIB_68 else p[:2].copy()
    return eyes[np.argsort(eyes[:, 0])]


def align_matrix(eyes: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The 2×3 similarity transform taking the two ``eyes`` ``(2, 2)`` exactly onto ``target`` ``(2, 2)``."""
    a, b = np.asarray(eyes, np.float64), np.asarray(target, np.float64)
    za, zb = complex(*(a[1] - a[0])), complex(*(b[1] - b[0]))
    if abs(za) < 1e-9:
        raise ValueError("the two eye points coincide")
    s = zb / za  # rotation + scale as one complex factor
    m = np.array([[s.real, -s.imag], [s.imag, s.real]])
    t = b[0] - m @ a[0]
    return np.hstack([m, t[:, None]])


def default_eyes(faces: Sequence[Face], size: tuple[int, int] | None = None) -> np.ndarray:
    """WebMorph's default targets: the mean pupil positions of ``faces``; for another output ``size``
    ``(w, h)`` the same positions as fractions of the first image's width and height."""
    mean = np.mean([eye_points(f.points) for f in faces], axis=0)
    if size is None:
        return mean
    w0, h0 = faces[0].size
    return mean / [w0, h0] * [size[0], size[1]]


def align_face(image: np.ndarray, points: np.ndarray, eyes: np.ndarray, size: tuple[int, int],
               fill: Sequence[float] | None = (1.0, 1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Rotate, scale and translate ``image`` so its pupils land on ``eyes``.

    Parameters
    ----------
    image : (h, w, 3) array
        Float RGB in [0, 1].
    points : (n, 2) array
        The image's template points (pupils found by :func:`eye_points`).
    eyes : (2, 2) array
        Target pupil positions (x, y) in output pixels, image-left first.
    size : (width, height)
        Output size.
    fill : 3 floats in [0, 1], or None
        Colour of output pixels the image does not cover; None repeats the image's edge pixels
        (no frame lines where aligned images are later averaged).

    Returns
    -------
    (image, points)
        The aligned ``(height, width, 3)`` float32 image and the moved points.
    """
    m = align_matrix(eye_points(points), eyes)
    img = np.asarray(image, np.float32)
    if fill is None:
        out = cv2.warpAffine(img, m, (int(size[0]), int(size[1])), flags=cv2.INTER_CUBIC,
                             borderMode=cv2.BORDER_REPLICATE)
    else:
        out = cv2.warpAffine(img, m, (int(size[0]), int(size[1])), flags=cv2.INTER_CUBIC,
                             borderMode=cv2.BORDER_CONSTANT, borderValue=tuple(float(c) for c in fill[:3]))
    moved = np.asarray(points, np.float64) @ m[:, :2].T + m[:, 2]
    return np.clip(out, 0.0, 1.0), moved
