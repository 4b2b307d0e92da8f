"""A rig's eyelashes kept rooted on its lids in every shape and pose.

Lash cards are a part of their own, moved neither as skin nor rigidly: carried along with the
smooth displacement that fits the ICT rig onto a mesh, Lee Perry-Smith's upper lashes floated a
few millimetres above the lid, and a stylised shape or an expression lifted them up to 1.3 mm
off. :func:`seat_lashes` puts every lash card back at its offset from the lid point under its
root, in a smooth frame there (the skin's normal, the eye's corner-to-corner axis).
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.characters.rig import FaceRig

__all__ = ["LASH_GROWTH", "seat_lashes"]

#: A lash grows with its eye's width to this power: an eye twice as wide (a design's cartoon eye) has
#: lashes 1.4x as long, not 2x (at full scale a cartoon's lash cards reached a third of the eye's
#: height above the lid, a dark arc apart from it).
LASH_GROWTH = 0.5


def _frames(normals: np.ndarray, across: np.ndarray) -> np.ndarray:
    """Per point (P, 3, 3) an orthonormal frame as rows: ``across`` in the tangent plane, the
    third axis, the normal."""
    n = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    t = across - np.einsum("pk,pk->p", across, n)[:, None] * n
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
    return np.stack([t, np.cross(n, t), n], axis=1)


def seat_lashes(rig: FaceRig, v0: np.ndarray, new_v: np.ndarray) -> np.ndarray:
    """``new_v`` with the rig's lash cards seated on its lids as they sit on ``v0``'s.

    Each lash vertex keeps its offset from the lid point under its root (the nearest lash vertex
    lying on the skin in ``v0``), in the frame of the skin's smooth normal there and the nearer
    eye's corner-to-corner axis, scaled with that eye's width (to the power :data:`LASH_GROWTH`).

    Parameters
    ----------
    rig : FaceRig
        Its ``lashes`` and ``skin`` parts.
    v0 : (N, 3) array
        Where the lashes sit right (the rig's own neutral, or a character's).
    new_v : (N, 3) array
        Another shape or pose of the same topology.

    Returns
    -------
    (N, 3) array
        A copy with the lash vertices re-seated (``new_v`` itself without lashes).
    """
    from scipy.spatial import cKDTree

    from stimulus_engine.geometry.closest import SurfaceIndex
    from stimulus_engine.geometry.mesh_ops import vertex_normals

    new_v = np.array(new_v, np.float64, copy=True)
    if "lashes" not in rig.part_names or "skin" not in rig.part_names:
        return new_v
    lash = np.unique(rig.faces[rig.face_part == rig.part_names.index("lashes")])
    skin = rig.faces[rig.face_part == rig.part_names.index("skin")]
    if not len(lash):
        return new_v
    hit = SurfaceIndex(v0, skin).query(v0[lash])
    # each lash follows its root (the lash vertex nearest it that lies on the lid): one card,
    # one lid point and frame; bound vertex by vertex, a card's tips followed other triangles
    # than its root and came apart where a stylised lid shears
    roots = np.flatnonzero(hit.distance <= max(float(np.percentile(hit.distance, 10)), 1e-9))
    own = roots[cKDTree(v0[lash[roots]]).query(v0[lash])[1]]
    hit_face, hit_bary, hit_point = hit.face[own], hit.bary[own], hit.points[own]
    sides = [s for s in ("right", "left") if all(f"eye_{s}{k}" in rig.landmarks for k in ("", "_outer", "_inner"))]
    scale = np.ones(len(lash))
    across0 = across1 = np.tile([1.0, 0.0, 0.0], (len(lash), 1))  # without eye landmarks: the rig's x axis
    if sides:  # each lash grows and turns with the eye it is nearer to
        lm0, lm1 = rig.landmark_points(v0), rig.landmark_points(new_v)
        nearer = np.argmin([np.linalg.norm(v0[lash] - lm0[f"eye_{s}"], axis=1) for s in sides], axis=0)
        axis0 = np.array([lm0[f"eye_{s}_outer"] - lm0[f"eye_{s}_inner"] for s in sides])
        axis1 = np.array([lm1[f"eye_{s}_outer"] - lm1[f"eye_{s}_inner"] for s in sides])
        scale = (np.linalg.norm(axis1, axis=1) / np.linalg.norm(axis0, axis=1))[nearer] ** LASH_GROWTH
        across0, across1 = axis0[nearer], axis1[nearer]
    # smooth frames (interpolated vertex normals, the eye's corner-to-corner axis): a frame from
    # one triangle's edge turned with every shear of a stylised lid, flinging the tips over the eye
    normal0 = np.einsum("nk,nkd->nd", hit_bary, vertex_normals(v0, skin)[skin[hit_face]])
    normal1 = np.einsum("nk,nkd->nd", hit_bary, vertex_normals(new_v, skin)[skin[hit_face]])
    local = np.einsum("nij,nj->ni", _frames(normal0, across0), v0[lash] - hit_point)
    root = np.einsum("nk,nkd->nd", hit_bary, new_v[skin[hit_face]])
    new_v[lash] = root + scale[:, None] * np.einsum("nij,ni->nj", _frames(normal1, across1), local)
    return new_v
