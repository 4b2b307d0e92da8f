"""A scan's mouth that can open: the lips cut apart along the detected lip line.

A scan with closed lips is one surface across the mouth; when the rig opens the jaw its upper
lip follows the upper lip and its lower lip the lower one, so the triangles between them
stretch into a smear. Here the scan is cut along its lip line — the inner-lip iBUG points 60–67,
an upper arc (60–64) and a lower one (64–67, 60) — and each side's rim is laid on its own arc:
closed, the cut does not show; opened, the lips part and the rig's mouth inside (socket, teeth,
tongue) shows between them. The vertices above the line are bound to the rig's upper face and
those below to the part the jaw carries, so the lips part exactly along the cut. A scan photographed with parted lips is cut open between the arcs.
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.polyline2d import catmull_rom, closest_on_polygon, inside_polygon, relax_around

__all__ = ["lip_arcs", "cut_lips", "CLOSED_GAP"]

#: Lips whose inner arcs are nowhere further apart than this fraction of the mouth's width are
#: closed: both sides of the cut are laid on the line between the arcs, so they meet.
CLOSED_GAP = 0.1


def lip_arcs(points: np.ndarray, n: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """The upper and lower inner-lip arcs, both from the right mouth corner (iBUG 60) to the left (64).

    Parameters
    ----------
    points : (8, 3) array
        iBUG points 60–67.
    n : int
        Samples per span.

    Returns
    -------
    upper, lower : (4 n + 1, 3) arrays
    """
    p = np.asarray(points, np.float64)
    upper = np.vstack([catmull_rom(p[[0, 1, 2, 3, 4]], n), p[4]])
    lower = np.vstack([catmull_rom(p[[0, 7, 6, 5, 4]], n), p[4]])
    return upper, lower


def _side(v: np.ndarray, upper: np.ndarray, lower: np.ndarray) -> np.ndarray:
    """+1 above the lip line, -1 below, 0 beyond the corners (x outside the line's span)."""
    mid = 0.5 * (upper + lower)
    order = np.argsort(mid[:, 0])
    x0, x1 = mid[order[0], 0], mid[order[-1], 0]
    y = np.interp(v[:, 0], mid[order, 0], mid[order, 1])
    side = np.where(v[:, 1] > y, 1, -1)
    side[(v[:, 0] <= x0) | (v[:, 0] >= x1)] = 0
    return side


def cut_lips(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray,
             reach: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cut a scan apart along its lip line (seen along +z).

    Parameters
    ----------
    vertices : (S, 3) array
    faces : (F, 3) int array
    points : (8, 3) array
        iBUG points 60–67 on the surface.
    reach : float, optional
        Only vertices this close to the mouth are cut or moved (default: the mouth's width).

    Returns
    -------
    keep : (F,) bool array
        The triangles that stay (False across the lip line and between parted lips).
    vertices : (S, 3) array
        A copy with each side's rim on its lip arc.
    side : (S,) int array
        +1 for the vertices around the mouth above the lip line, -1 below, 0 elsewhere: bind
        them to the rig's upper and lower lip (:func:`stimulus_engine.scan_surface.bind_scan`),
        so the lips part where the scan was cut.
    """
    v = np.asarray(vertices, np.float64).copy()
    f = np.asarray(faces, np.int64)
    upper, lower = lip_arcs(points)
    width = float(np.ptp(upper[:, 0]))
    if np.max(np.linalg.norm(upper - lower, axis=1)) < CLOSED_GAP * width:  # closed lips: one line
        upper = lower = 0.5 * (upper + lower)
    reach = width if reach is None else reach
    near = np.linalg.norm(v - upper.mean(axis=0), axis=1) < reach
    side = np.where(near, _side(v, upper, lower), 0)
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
