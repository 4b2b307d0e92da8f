"""Cutting a scan's surface apart along a facial line (lips, closed lids), seen along +z.

Each side's rim is laid on its own arc (on one line when the arcs are closed), the triangles
around are evened out, and every vertex near the line learns its side, so that the two sides can
be bound to different parts of a rig (:func:`stimulus_engine.characters.scan_surface.bind_scan`).
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.geometry.polyline2d import closest_on_polygon, inside_polygon, relax_around

__all__ = ["cut_along"]


def _side(v: np.ndarray, upper: np.ndarray, lower: np.ndarray, band: float | None = None) -> np.ndarray:
    """+1 above the line, -1 below, 0 beyond the corners (x outside the line's span) or further
    than ``band`` from it."""
    mid = 0.5 * (upper + lower)
    order = np.argsort(mid[:, 0])
    x0, x1 = mid[order[0], 0], mid[order[-1], 0]
    y = np.interp(v[:, 0], mid[order, 0], mid[order, 1])
    side = np.where(v[:, 1] > y, 1, -1)
    side[(v[:, 0] <= x0) | (v[:, 0] >= x1)] = 0
    if band is not None:
        side[np.abs(v[:, 1] - y) > band] = 0
    return side


def cut_along(vertices: np.ndarray, faces: np.ndarray, upper: np.ndarray, lower: np.ndarray, *, reach: float,
              closed_gap: float = 0.1, band: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cut a surface apart along a line, or open between two arcs (seen along +z).

    Parameters
    ----------
    vertices : (S, 3) array
    faces : (F, 3) int array
    upper, lower : (K, 3) arrays
        The upper and lower arc, both from the same corner to the other, sampled alike. Arcs
        nowhere further apart than ``closed_gap`` of their width are taken as closed: both
        sides of the cut are laid on the line between them, so the cut does not show.
    reach : float
        Only vertices this close to the arcs' centre are cut or moved.
    band : float, optional
        Only vertices this close to the line (vertically) get a side (default: all within reach).

    Returns
    -------
    keep : (F,) bool array
        The triangles that stay (False across the line and between open arcs).
    vertices : (S, 3) array
        A copy with each side's rim on its arc.
    side : (S,) int array
        +1 for the vertices near the line above it, -1 below, 0 elsewhere.
    """
    v = np.asarray(vertices, np.float64).copy()
    f = np.asarray(faces, np.int64)
    width = float(np.ptp(upper[:, 0]))
    if np.max(np.linalg.norm(upper - lower, axis=1)) < closed_gap * width:  # closed: one line
        upper = lower = 0.5 * (upper + lower)
    near = np.linalg.norm(v - upper.mean(axis=0), axis=1) < reach
    side = np.where(near, _side(v, upper, lower, band), 0)
    opening = np.vstack([upper, lower[::-1][1:-1]])
    inside = np.zeros(len(v), bool)
    inside[near] = inside_polygon(v[near, :2], opening[:, :2])
    s = side[f]
    cut = (((s == 1).any(axis=1) & (s == -1).any(axis=1)) | inside[f].any(axis=1)) & near[f].all(axis=1)
    keep = ~cut
    rim = np.zeros(len(v), bool)
    rim[f[cut].ravel()] = True
    kept = np.zeros(len(v), bool)
    kept[f[keep].ravel()] = True
    rim &= kept & ~inside
    for sign, arc in ((1, upper), (-1, lower)):
        idx = np.flatnonzero(rim & (side == sign))
        if len(idx):
            k, t = closest_on_polygon(v[idx, :2], arc[:, :2], closed=False)
            v[idx] = arc[k] + t[:, None] * (arc[k + 1] - arc[k])
        relax_around(v, f[keep & (s == sign).any(axis=1)], arc, fixed=np.flatnonzero(rim),
                     near=near & (side == sign), closed=False, band=width / 10)
    return keep, v, side
