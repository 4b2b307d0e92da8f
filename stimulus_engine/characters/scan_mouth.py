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

from stimulus_engine.geometry.polyline2d import catmull_rom
from stimulus_engine.characters.scan_cut import cut_along

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


def cut_lips(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray,
             reach: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cut a scan apart along its lip line (seen along +z): :func:`stimulus_engine.characters.scan_cut.cut_along`
    the inner-lip arcs of iBUG points 60–67 (lips closer than :data:`CLOSED_GAP` of the mouth's
    width are closed: one line).

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
    keep, vertices, side
        As :func:`stimulus_engine.characters.scan_cut.cut_along`: bind the sides to the rig's upper and
        lower lip (:func:`stimulus_engine.characters.scan_surface.bind_scan`), so the lips part where the
        scan was cut.
    """
    upper, lower = lip_arcs(points)
    width = float(np.ptp(upper[:, 0]))
    return cut_along(vertices, faces, upper, lower, reach=width if reach is None else reach,
                     closed_gap=CLOSED_GAP)

