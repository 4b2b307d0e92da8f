"""Caricatures and anti-caricatures relative to an average face (Benson & Perrett 1991; WebMorph).

A caricature exaggerates how a face differs from an average (usually a composite of the same sex
and age): with the average's template moved to the face's eye frame (pupils on the face's pupils,
similarity transform), ``points' = avg + (1 + k)(points − avg)`` — ``k = 0.5`` makes every
difference 1.5 times as large, ``k = −0.5`` halves it (an anti-caricature, towards the average),
``k = −1`` gives the average's shape at the face's pupils. The pupils stay where they are.

It is :func:`stimulus_engine.faces2d.transform.transform` from the average (A) to the face itself
(B) with shape weight ``k``: the optional colour and texture weights exaggerate the face's
low-frequency colour difference from the average and its fine-detail amplitude ratio the same way.
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.faces2d.transform import transform

__all__ = ["caricature", "caricature_points"]


def caricature_points(points: np.ndarray, average_points: np.ndarray, k: float) -> np.ndarray:
    """``avg + (1 + k)(points − avg)``, the average's template first moved to the face's eye frame."""
    from stimulus_engine.faces2d.transform import shape_difference

    p = np.asarray(points, np.float64)
    return p + k * shape_difference(p, average_points, p)


def caricature(image: np.ndarray, points: np.ndarray, average_image: np.ndarray, average_points: np.ndarray,
               k: float, *, colour: float = 0.0, texture: float = 0.0,
               colour_sigma: float = 0.12, region: str = "face") -> tuple[np.ndarray, np.ndarray]:
    """A caricature (``k > 0``) or anti-caricature (``k < 0``) of a face relative to an average.

    Parameters
    ----------
    image : (h, w, 3) float array
        The face, RGB in [0, 1].
    points : (n, 2) array
        Its template.
    average_image, average_points
        The average face (e.g. a composite) and its template (same ``n``; any image size).
    k : float
        Shape exaggeration: points move to ``avg + (1 + k)(points − avg)``.
    colour, texture : float
        Exaggeration of the low-frequency colour difference and of the fine-detail amplitude
        (0 = the face's own; see :func:`stimulus_engine.faces2d.transform.transform`).
    colour_sigma : float
        The colour blur as a fraction of the eye distance.
    region : {"face", "image"}
        Where colour and texture change (:func:`stimulus_engine.faces2d.transform.face_region`).

    Returns
    -------
    (image, points)
        The float32 image (same size) and its template.
    """
    return transform(image, points, average_image, average_points, image, points, shape=k, colour=colour,
                     texture=texture, colour_sigma=colour_sigma, region=region)
