"""Curves drawn on a surface: a polyline or Catmull-Rom spline through given points, every
sample snapped to the closest surface point (the eyelid and inner-lip curves that a source's
eye and mouth rims are mapped onto by
:func:`~stimulus_engine.correspondence.boundary.rim_to_curve_correspondences`).
"""

from __future__ import annotations

import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.geometry.closest import SurfaceIndex

__all__ = ["surface_polyline"]


def _catmull_rom(p: np.ndarray, t: np.ndarray, closed: bool, corners) -> np.ndarray:
    """Samples (len(segments), len(t), 3) of the uniform Catmull-Rom spline through ``p``; at
    ``corners`` (and the ends of an open curve) the tangent is one-sided (a cusp)."""
    n = len(p)
    sharp = np.zeros(n, dtype=bool)
    sharp[list(corners)] = True
    if not closed:
        sharp[[0, -1]] = True
    i = np.arange(n if closed else n - 1)
    p1, p2 = p[i], p[(i + 1) % n]
    p0 = np.where(sharp[i][:, None], p1, p[(i - 1) % n])
    p3 = np.where(sharp[(i + 1) % n][:, None], p2, p[(i + 2) % n])
    t = t[None, :, None]
    return 0.5 * (2 * p1[:, None] + (p2 - p0)[:, None] * t + (2 * p0 - 5 * p1 + 4 * p2 - p3)[:, None] * t**2
                  + (3 * p1 - p0 - 3 * p2 + p3)[:, None] * t**3)


def surface_polyline(
    vertices: np.ndarray, faces: np.ndarray, points: np.ndarray, samples: int = 8, closed: bool = True,
    index=None, smooth: bool = False, corners=(),
) -> tuple[np.ndarray, np.ndarray]:
    """A curve on the surface through ``points``: each chord (or, with ``smooth``, each piece
    of a Catmull-Rom spline through the points) split into ``samples`` pieces and every sample
    snapped to the closest surface point.

    Parameters
    ----------
    vertices, faces : arrays
        The surface.
    points : (P, 3) array
        The knots, in order (they are snapped too).
    samples : int
        Pieces per chord (>= 1).
    closed : bool
        Also join the last knot to the first.
    index : SurfaceIndex, optional
        A prebuilt closest-point index of the surface.
    smooth : bool
        A uniform Catmull-Rom spline through the points instead of straight chords.
    corners : sequence of int
        With ``smooth``: points where the curve keeps a corner (eye and mouth corners).

    Returns
    -------
    curve : (P * samples (+1 if open), 3) array
        Snapped sample positions; knot ``k`` is ``curve[k * samples]``.
    arc : same length
        Cumulative arc length along the snapped samples (0 at knot 0); for a closed curve
        the total length is ``arc[-1] + |curve[0] - curve[-1]|``.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) < 2:
        raise AppealInputError(f"curve: expected at least 2 points (got {len(p)})")
    if samples < 1:
        raise AppealInputError(f"curve: samples: expected an integer >= 1 (got {samples})")
    t = np.arange(samples) / samples
    if smooth:
        dense = _catmull_rom(p, t, closed, corners).reshape(-1, 3)
    else:
        nxt = np.roll(p, -1, axis=0) if closed else p[1:]
        start = p if closed else p[:-1]
        dense = (start[:, None, :] + t[None, :, None] * (nxt - start)[:, None, :]).reshape(-1, 3)
    if not closed:
        dense = np.vstack([dense, p[-1:]])
    idx = index if index is not None else SurfaceIndex(vertices, faces)
    curve = idx.query(dense).points
    seg = np.linalg.norm(np.diff(curve, axis=0), axis=1)
    return curve, np.concatenate([[0.0], np.cumsum(seg)])
