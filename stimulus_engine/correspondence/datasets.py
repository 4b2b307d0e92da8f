"""The real-data pair of the issue: the ICT face region onto the menpo3d james scan.

ICT's face region has openings at the eyes and the mouth (boundary loops whose rims curl
inwards towards the eyeballs and the mouth cavity); james is a closed scan surface there. By
default the rims are tied to james's eyelid and inner-lip landmark lines
(:func:`rim_to_curve_correspondences`, thesis §3.2.1 / Fig. 3.5): without them the joint fairing
pulls the openings wide and the registration folds the rims over.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from stimulus_engine.correspondence.boundary import nearest_boundary_vertices, rim_to_curve_correspondences
from stimulus_engine.correspondence.landmark_sets import LANDMARK_SUBSET_16, read_ljson, reorder_landmarks
from stimulus_engine.correspondence.points import Correspondences, SurfacePoints, parse_points
from stimulus_engine.geometry.ict_topology import ict_regions
from stimulus_engine.geometry.mesh_io import load_mesh, select_region
from stimulus_engine.geometry.mesh_ops import boundary_loops

__all__ = ["ict_james_pair", "RIM_CURVES"]

#: iBUG indices of the closed landmark curves the ICT openings are tied to, in curve order:
#: right eye (corner, upper lid, corner, lower lid), left eye, inner lips (corner, upper, corner,
#: lower). Each curve's landmarks are used as anchors (the ICT rim vertex nearest to ICT's
#: landmark ↔ james's landmark) and are therefore not held out.
RIM_CURVES: dict[str, tuple[int, ...]] = {
    "right_eye": tuple(range(36, 42)),
    "left_eye": tuple(range(42, 48)),
    "mouth": tuple(range(60, 68)),
}


def _rim_anchors(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Boundary vertices for a closed landmark curve ``corner, side A..., corner, side B...``.

    The corners (points 0 and P/2) take their nearest boundary vertices; they split that loop
    into two arcs, and each side's points take their nearest vertex on the arc closer to that
    side (the upper and lower lid or lip are close together, so a plain nearest vertex may
    fall on the wrong arc).
    """
    p = len(points)
    half = p // 2
    c0, c1 = nearest_boundary_vertices(vertices, faces, points[[0, half]])
    loop = next(lp for lp in boundary_loops(faces) if c0 in lp)
    i0, i1 = int(np.flatnonzero(loop == c0)[0]), int(np.flatnonzero(loop == c1)[0])
    arcs = [np.roll(loop, -i0)[1: (i1 - i0) % len(loop)], np.roll(loop, -i1)[1: (i0 - i1) % len(loop)]]
    out = np.empty(p, dtype=np.int64)
    out[0], out[half] = c0, c1
    sides = [np.arange(1, half), np.arange(half + 1, p)]

    def nearest(side, arc):
        d = np.linalg.norm(vertices[arc][None] - points[side][:, None], axis=2)
        return arc[d.argmin(axis=1)], float(d.min(axis=1).sum())

    (a0, e0), (b1, e1) = nearest(sides[0], arcs[0]), nearest(sides[1], arcs[1])
    (a1, f0), (b0, f1) = nearest(sides[0], arcs[1]), nearest(sides[1], arcs[0])
    out[sides[0]], out[sides[1]] = (a0, b1) if e0 + e1 <= f0 + f1 else (a1, b0)
    return out


def ict_james_pair(
    data_dir: str | Path,
    region: str = "narrow_face",
    subset: np.ndarray = LANDMARK_SUBSET_16,
    rims: bool = True,
    rim_step: int = 1,
    rim_smooth: bool = True,
) -> tuple[trimesh.Trimesh, trimesh.Trimesh, Correspondences, tuple[np.ndarray, np.ndarray]]:
    """ICT neutral face ``region`` (source) and james (target) with landmark correspondences.

    Parameters
    ----------
    data_dir : path-like
        The ``shared/data`` folder (with ``meshes/ict-facekit`` and ``meshes/menpo3d-james``).
    region : str
        An :func:`ict_regions` name.
    subset : array of int
        iBUG indices used as point correspondences.
    rims : bool
        Also tie ICT's eye and mouth opening rims to james's eyelid and inner-lip landmark
        curves (:data:`RIM_CURVES`), one correspondence per ``rim_step``-th rim vertex.
    rim_step : int
        Use every ``rim_step``-th rim vertex (the anchors always).
    rim_smooth : bool
        Curves through the landmarks as Catmull-Rom splines with corners at the eye and mouth
        corners (False: straight chords between the landmarks).

    Returns
    -------
    source, target, corr, (held_source_vertices, held_target_points)
        ``corr`` holds the ``subset`` landmarks first, then the rim correspondences. The held-out
        landmarks (iBUG order) are those used neither in ``subset`` nor as rim anchors: 52 without
        rims, 34 with them (jaw, brows, nose, outer lips).
    """
    m = Path(data_dir) / "meshes"
    ict = load_mesh(m / "ict-facekit" / "generic_neutral_mesh.obj.gz")
    regions = ict_regions(m / "ict-facekit" / "vertex_indices.json")
    src, ids = select_region(ict, regions[region])
    remap = np.full(len(ict.vertices), -1)
    remap[ids] = np.arange(len(ids))
    lm_src = remap[regions["landmarks"]]
    james = load_mesh(m / "menpo3d-james" / "james.obj")
    pts, order = read_ljson(m / "menpo3d-james" / "james.ljson")
    lm_t = reorder_landmarks(pts, order)
    subset = np.asarray(subset, dtype=np.int64)
    corr = Correspondences(SurfacePoints.from_vertices(lm_src[subset]), parse_points(lm_t[subset], james))
    used = set(subset.tolist())
    if rims:
        from stimulus_engine.geometry.closest import SurfaceIndex

        index = SurfaceIndex(james.vertices, james.faces)
        vs = np.asarray(src.vertices)
        for curve in RIM_CURVES.values():
            c = np.asarray(curve)
            anchors = _rim_anchors(vs, src.faces, vs[lm_src[c]])
            corr = corr.concat(rim_to_curve_correspondences(
                vs, src.faces, james.vertices, james.faces, anchors, lm_t[c], step=rim_step, index=index,
                smooth=rim_smooth, corners=(0, len(c) // 2),
            ))
            used |= set(curve)
    held = np.setdiff1d(np.arange(68), np.fromiter(used, dtype=np.int64))
    return src, james, corr, (lm_src[held], lm_t[held])
