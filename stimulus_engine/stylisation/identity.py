"""Is it still the same person? Face-recognition embeddings of rendered stimuli.

dlib's ResNet face descriptor (``dlib_face_recognition_resnet_model_v1``, weights in the
``face_recognition_models`` wheel, offline): 128 numbers per face, 99.38 % on LFW; two photographs
of one person lie within Euclidean distance 0.6 of each other (dlib's threshold), of two people
beyond it. In a grid's images the face is where the framing puts it (:func:`framing_box`); in
other images dlib's HOG detector finds it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SAME_PERSON", "face_descriptor", "framing_box", "identity_distance"]

#: dlib's same-person threshold on the descriptor distance.
SAME_PERSON = 0.6

_MODEL: dict = {}


def framing_box(width: int, height: int, eye_row: float, face_fraction: float) -> tuple[float, float, float, float]:
    """(left, top, right, bottom) of the box dlib's detector draws around a face framed with its
    eyes ``eye_row`` of the height from the top and its length ``face_fraction`` of it (measured
    on the Exp. 2 renders, 1024 x 768: 0.83 face lengths wide, from 0.23 above the eyes to 0.59
    below)."""
    face, eye = face_fraction * height, eye_row * height
    return (width / 2 - 0.415 * face, eye - 0.234 * face, width / 2 + 0.415 * face, eye + 0.594 * face)


def _recogniser():
    if not _MODEL:
        import dlib
        import face_recognition_models

        _MODEL["net"] = dlib.face_recognition_model_v1(face_recognition_models.face_recognition_model_location())
    return _MODEL["net"]


def face_descriptor(image: np.ndarray, box: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """The 128-d descriptor of the largest face in ``image`` (H, W, 3 uint8 RGB).

    Parameters
    ----------
    image : (H, W, 3) uint8 array
    box : (left, top, right, bottom), optional
        Where the face is (:func:`framing_box` for a grid's images, where every level puts the
        face: the same box for all, and the detector, which misses some stylised faces, is not
        run); by default dlib's HOG detector finds it.

    Returns
    -------
    (128,) array
    """
    import dlib

    from stimulus_engine.morphpca.keypoints import _dlib_models

    m = _dlib_models()
    img = np.ascontiguousarray(np.asarray(image, np.uint8)[..., :3])
    if box is not None:
        rect = dlib.rectangle(*[int(round(c)) for c in box])
    else:
        faces = m["detector"](img, 1)
        if not len(faces):
            raise ValueError("no face found in the image (give the face's box)")
        rect = max(faces, key=lambda r: r.width() * r.height())
    shape = m["predictor"](img, rect)
    return np.asarray(_recogniser().compute_face_descriptor(img, shape, 1), np.float64)


def identity_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Euclidean distance between two descriptors (same person below :data:`SAME_PERSON`)."""
    return float(np.linalg.norm(np.asarray(a, np.float64) - np.asarray(b, np.float64)))
