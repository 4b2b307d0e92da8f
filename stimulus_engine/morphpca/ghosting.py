"""A ghosting score for face averages: how much of the features' edge energy an average keeps.

Averaging faces whose features are not in correspondence doubles them (two half-contrast
eyebrows, nostrils, mouths) or smears them; either way the average loses edge energy around
the features. :func:`ghosting_index` compares the gradient energy in a window around each
feature landmark of the average with the same windows in the faces that went into it:
0 = the average's features are as crisp as the inputs', 0.5 ≈ every edge doubled into two of
half contrast, 1 = no structure left. Only landmarks near the eyes, nose and mouth count
(within 1.2 eye distances of the faceframe's centre), so hair and face outline, which vary
between people, do not.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["feature_points", "edge_energy", "ghosting_index"]


def feature_points(points: np.ndarray, frame: np.ndarray, reach: float = 1.2) -> np.ndarray:
    """Indices of the landmarks within ``reach`` eye distances of the faceframe's centroid."""
    f = np.asarray(frame, float)
    eye_distance = float(np.linalg.norm(f[1] - f[0]))
    d = np.linalg.norm(np.asarray(points, float) - f.mean(axis=0), axis=1)
    return np.flatnonzero(d <= reach * eye_distance)


def edge_energy(image: np.ndarray, points: np.ndarray, radius: int) -> np.ndarray:
    """Mean squared luminance gradient in a ``(2 radius + 1)²`` window around each point."""
    img = np.asarray(image, np.float32)
    grey = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY) if img.ndim == 3 else img
    gx = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3) / 8.0
    gy = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=3) / 8.0
    energy = cv2.boxFilter(gx * gx + gy * gy, -1, (2 * radius + 1, 2 * radius + 1))
    h, w = grey.shape
    xy = np.round(np.asarray(points, float)).astype(int)
    x, y = np.clip(xy[:, 0], 0, w - 1), np.clip(xy[:, 1], 0, h - 1)
    return energy[y, x]


def ghosting_index(average: np.ndarray, average_points: np.ndarray, images, image_points, frame: np.ndarray,
                   radius: float = 0.08) -> float:
    """1 − (edge energy of the average around its feature landmarks) / (the inputs' mean around theirs).

    Parameters
    ----------
    average : (h, w, 3) float image
    average_points : (K, 2)
        The landmarks on the average (e.g. ``MorphModel.landmarks``).
    images : sequence of (h, w, 3) images, and image_points (n, K, 2)
        The faces averaged and their landmarks.
    frame : (3, 2)
        A faceframe of the average (eyes, philtrum): picks the feature landmarks and the scale.
    radius : float
        Window size (2 × half-size + 1) as a fraction of the image width.

    Returns
    -------
    float
        The median over the feature landmarks (0 = crisp, ~0.5 = doubled, 1 = blank).
    """
    idx = feature_points(average_points, frame)
    r = max(1, int(round(radius * np.shape(average)[1] / 2)))
    ea = edge_energy(average, np.asarray(average_points)[idx], r)
    ei = np.mean([edge_energy(img, np.asarray(p)[idx], r) for img, p in zip(images, image_points)], axis=0)
    return float(np.median(1.0 - ea / np.maximum(ei, 1e-12)))
