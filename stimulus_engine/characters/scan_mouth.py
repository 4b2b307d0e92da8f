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

__all__ = ["lip_arcs", "cut_lips", "inside_behind_skin", "CLOSED_GAP"]

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


def inside_behind_skin(vertices: np.ndarray, faces: np.ndarray, face_part: np.ndarray, part_names: tuple[str, ...],
                       inside: tuple[str, ...] = ("mouth", "teeth", "tongue"), gap: float = 0.05) -> np.ndarray:
    """``vertices`` with the mouth's inside moved back (-z) until none of it is in front of the skin.

    The inside parts move as on the rig, the scan's skin as bound to the rig's: a stylised shape
    (a smaller mouth, a shorter jaw) or an expression can bring a tooth or the gums out in front
    of the lips or the chin. A vertex of the inside is *in front of the skin* where a ray from it
    away from the viewer (-z) first meets a skin triangle that faces the viewer; the whole inside
    moves back by the deepest such distance plus ``gap`` (so teeth that would show through skin
    stay hidden behind it, and the inside keeps its shape).

    Parameters
    ----------
    vertices : (N, 3) array
        A pose of a drawn topology (+z towards the viewer).
    faces, face_part, part_names
        Its triangles and their parts (``skin`` is the surface that may not be pierced).
    inside : tuple of str
        The parts that must stay behind it.
    gap : float
        Clearance behind the skin (the rig's units: centimetres).

    Returns
    -------
    (N, 3) array
        A copy (the same array's values where nothing pokes through).
    """
    import trimesh

    v = np.array(vertices, np.float64, copy=True)
    ids = [part_names.index(p) for p in inside if p in part_names]
    if "skin" not in part_names or not ids:
        return v
    moved = np.unique(faces[np.isin(face_part, ids)])
    skin_faces = faces[face_part == part_names.index("skin")]
    front = trimesh.Trimesh(v, skin_faces, process=False)
    front = trimesh.Trimesh(v, skin_faces[front.face_normals[:, 2] > 0], process=False)
    back = np.tile([0.0, 0.0, -1.0], (len(moved), 1))
    loc, ray, tri = front.ray.intersects_location(v[moved], back, multiple_hits=False)
    if not len(ray):
        return v
    depth = float((v[moved][ray, 2] - loc[:, 2]).max())
    v[moved, 2] -= depth + gap
    return v
