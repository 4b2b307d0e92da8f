"""Where the irises sit between the eye corners in an image: a gaze check a person can repeat on a
photograph.

A face that looks into the lens shows each iris between its corners at about the same place in both
eyes; one that looks aside shows both irises pushed the same way, so one sits nearer its outer corner
and the other nearer its inner one. :func:`iris_positions` measures, for each eye, the iris centre's
position along the line from the outer to the inner corner (0 at the outer corner, 1 at the inner),
from dlib's 68 landmarks:

* the eye opening is the polygon of the six eye points (36-41, 42-47), its rows kept to the middle
  :data:`OPENING_ROWS` of its height (the lid margins and lashes are dark too);
* the opening's brightness profile is each column's lightness (CIE L*) over those rows, a low
  percentile (:data:`PROFILE_PERCENTILE`) so that a catch-light across part of the iris's rows
  does not lift it to the sclera's, its first and last :data:`CORNER_SHARE` left out (lash shadow);
* the iris lies between the fall (sclera to iris) and the rise (iris to sclera) that together change
  the profile most, :data:`IRIS_WIDTH` of the eye's width apart, with the profile between them darker
  than just outside either (a pupil and a catch-light inside the iris make strong edges too: without
  that, a pupil's edge paired with the iris's own was taken for the iris); its centre is midway, as a
  share of the corners' horizontal distance.

On the 87 London neutral photographs (``data:london-frl-all``) the irises sit 0.42-0.55 from the
outer corner (2.5-97.5 %) and a face's two eyes differ by at most 0.08 (97.5 %); :func:`gaze_check` allows
0.41-0.56 and 0.08 by default, and 93-94 % of them pass, at their own size or
scaled to a stimulus's (``benchmarks/realistic_level.py``). The measure is a
check of the image a participant sees; :func:`stimulus_engine.characters.gaze.sight_misses` checks
the geometry (each line of sight through the lens).
"""

from __future__ import annotations

import numpy as np

__all__ = ["CORNER_SHARE", "IRIS_WIDTH", "OPENING_ROWS", "PHOTOGRAPH_RANGE", "PHOTOGRAPH_ASYMMETRY", "iris_positions", "gaze_check"]

#: Share of the eye opening's height (about its middle) searched for the iris.
OPENING_ROWS: float = 0.6
#: The iris's width as a share of the eye's (corner to corner), the range searched.
IRIS_WIDTH: tuple[float, float] = (0.25, 0.7)
#: Edges are looked for this share of the eye's width in from either end of the opening: there the
#: polygon's tips average a few pixels of lash and corner shadow (james's outer corner, dark
#: after a pixel of skin, was taken for an iris's fall).
CORNER_SHARE: float = 0.08
#: A column's lightness is this percentile of its pixels in the opening's middle rows: a catch-light
#: covers part of an iris's rows, and in a column mean it lifted the iris to the sclera's lightness
#: (james's ERP right eye: the iris read as two dark bands).
PROFILE_PERCENTILE: float = 30.0
#: Where London's photographed irises sit from the outer corner (both eyes, 2.5th-97.5th percentile).
PHOTOGRAPH_RANGE: tuple[float, float] = (0.41, 0.56)
#: How far apart a photographed face's two eyes measure (97.5th percentile).
PHOTOGRAPH_ASYMMETRY: float = 0.08

_EYES = {"right": (36, 39), "left": (45, 42)}  # the person's eye: (outer, inner) corner landmarks


def _opening(shape: tuple[int, int], points: np.ndarray) -> np.ndarray:
    """Boolean mask of the eye polygon's middle rows."""
    import cv2

    mask = np.zeros(shape, np.uint8)
    cv2.fillPoly(mask, [np.round(points * 4).astype(np.int32)], 1, shift=2)
    top, bottom = points[:, 1].min(), points[:, 1].max()
    mid, half = (top + bottom) / 2, (bottom - top) * OPENING_ROWS / 2
    rows = np.arange(shape[0])[:, None]
    return mask.astype(bool) & (np.abs(rows + 0.5 - mid) <= half)


def _iris_centre_x(luma: np.ndarray, opening: np.ndarray, width: float) -> float:
    """Midway between the iris's two edges in the opening's brightness profile (each column's
    :data:`PROFILE_PERCENTILE` over the opening's middle rows): the fall (sclera to iris) and the rise (iris to sclera),
    :data:`IRIS_WIDTH` of the eye's width apart, that together change brightness most."""
    from scipy.ndimage import gaussian_filter1d

    cols = np.flatnonzero(opening.any(axis=0))
    if cols.size < 6:
        return float("nan")
    x0, x1 = cols.min(), cols.max() + 1
    sub, inside = luma[:, x0:x1], opening[:, x0:x1]
    has = inside.any(axis=0)
    seen = np.nanpercentile(np.where(inside[:, has], sub[:, has], np.nan), PROFILE_PERCENTILE, axis=0)
    profile = np.interp(np.arange(has.size), np.flatnonzero(has), seen)
    grad = np.gradient(gaussian_filter1d(profile, max(width / 60.0, 0.5), mode="nearest"))
    lo, hi = IRIS_WIDTH[0] * width, IRIS_WIDTH[1] * width
    cum = np.concatenate([[0.0], np.cumsum(profile)])
    margin = max(int(round(0.05 * width)), 1)
    best, centre = -np.inf, float("nan")
    first, last = int(round(CORNER_SHARE * width)), grad.size - int(round(CORNER_SHARE * width))
    for a in range(first, grad.size):  # a: the fall; b: the rise
        b = np.arange(int(np.ceil(a + lo)), min(int(a + hi) + 1, last))
        if b.size == 0:
            continue
        # the iris is darker than the sclera beside it on both sides (not a pupil beside a catch-light)
        inner = (cum[b] - cum[a]) / (b - a)
        left = (cum[a] - cum[max(a - margin, 0)]) / max(a - max(a - margin, 0), 1) if a > 0 else profile[0]
        right = (cum[np.minimum(b + margin, grad.size)] - cum[b]) / np.maximum(np.minimum(b + margin, grad.size) - b, 1)
        score = np.where((inner < left) & (inner < right), grad[b] - grad[a], -np.inf)
        k = int(np.argmax(score))
        if score[k] > best:
            best, centre = float(score[k]), x0 + (a + b[k]) / 2 + 0.5
    return float(centre)


def iris_positions(rgb: np.ndarray, landmarks: np.ndarray) -> dict[str, float]:
    """Each iris's centre between its eye's corners, 0 at the outer corner and 1 at the inner.

    Parameters
    ----------
    rgb : (H, W, 3) uint8 array
    landmarks : (68, 2) array
        dlib's 68 landmarks of the face (x, y pixels).

    Returns
    -------
    dict
        ``right`` and ``left`` (the person's eyes: the image's left and right), NaN where an eye's
        opening shows no iris.
    """
    from stimulus_engine.audit.measures import lab_image

    lm = np.asarray(landmarks, np.float64)
    if lm.shape != (68, 2):
        raise ValueError(f"expected the 68 dlib landmarks (68, 2), got shape {lm.shape}")
    img = np.asarray(rgb)
    eyes = lm[36:48]
    pad = float(np.ptp(eyes[:, 0])) / 4 + 2
    x0, y0 = (max(int(v - pad), 0) for v in eyes.min(axis=0))
    x1, y1 = (int(v + pad) + 1 for v in eyes.max(axis=0))
    luma = lab_image(img[y0:y1, x0:x1])[..., 0]  # L*, around the eyes only
    lm = lm - (x0, y0)
    out = {}
    for side, (outer, inner) in _EYES.items():
        points = lm[36:42] if side == "right" else lm[42:48]
        x = _iris_centre_x(luma, _opening(luma.shape, points), float(np.linalg.norm(lm[outer] - lm[inner])))
        a, b = lm[outer], lm[inner]
        out[side] = float((x - a[0]) / (b[0] - a[0])) if abs(b[0] - a[0]) > 1e-9 else float("nan")
    return out


def gaze_check(positions: dict[str, float], range_: tuple[float, float] = PHOTOGRAPH_RANGE,
               asymmetry: float = PHOTOGRAPH_ASYMMETRY) -> bool:
    """Whether both irises sit where photographed ones do (within ``range_``) and alike (within
    ``asymmetry`` of each other): the face looks into the lens, not aside."""
    r, l_ = positions["right"], positions["left"]
    return bool(np.isfinite(r) and np.isfinite(l_) and all(range_[0] <= x <= range_[1] for x in (r, l_))
                and abs(r - l_) <= asymmetry)
