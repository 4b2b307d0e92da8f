"""A rig's eyelashes kept rooted on its lids in every shape and pose.

Lash cards are a part of their own, moved neither as skin nor rigidly: carried along with the
smooth displacement that fits the ICT rig onto a mesh, Lee Perry-Smith's upper lashes floated a
few millimetres above the lid, and a stylised shape or an expression lifted them up to 1.3 mm
off. :func:`seat_lashes` puts every lash vertex back at its offset from the lid, in the frame of
the skin triangle under it.
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.characters.rig import FaceRig

__all__ = ["seat_lashes"]


def _frames(tri: np.ndarray) -> np.ndarray:
    """Per triangle (T, 3, 3) an orthonormal frame as rows: first edge, across, normal."""
    e1 = tri[:, 1] - tri[:, 0]
    n = np.cross(e1, tri[:, 2] - tri[:, 0])
    e1 /= np.maximum(np.linalg.norm(e1, axis=1, keepdims=True), 1e-12)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return np.stack([e1, np.cross(n, e1), n], axis=1)


def seat_lashes(rig: FaceRig, v0: np.ndarray, new_v: np.ndarray) -> np.ndarray:
    """``new_v`` with the rig's lash cards seated on its lids as they sit on ``v0``'s.

    Each lash vertex keeps its offset from its closest point on the rig's skin in ``v0``, in
    that skin triangle's frame and scaled with the eye's width.

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
    from stimulus_engine.geometry.closest import SurfaceIndex

    new_v = np.array(new_v, np.float64, copy=True)
    if "lashes" not in rig.part_names or "skin" not in rig.part_names:
        return new_v
    lash = np.unique(rig.faces[rig.face_part == rig.part_names.index("lashes")])
    skin = rig.faces[rig.face_part == rig.part_names.index("skin")]
    if not len(lash):
        return new_v
    hit = SurfaceIndex(v0, skin).query(v0[lash])
    tri0, tri1 = v0[skin[hit.face]], new_v[skin[hit.face]]
    scale = np.ones(len(lash))
    sides = [s for s in ("right", "left") if all(f"eye_{s}{k}" in rig.landmarks for k in ("", "_outer", "_inner"))]
    if sides:  # each lash grows with the width of the eye it is nearer to
        lm0, lm1 = rig.landmark_points(v0), rig.landmark_points(new_v)

        def width(lm: dict, s: str) -> float:
            return float(np.linalg.norm(lm[f"eye_{s}_outer"] - lm[f"eye_{s}_inner"]))

        nearer = np.argmin([np.linalg.norm(v0[lash] - lm0[f"eye_{s}"], axis=1) for s in sides], axis=0)
        scale = np.array([width(lm1, s) / width(lm0, s) for s in sides])[nearer]
    local = np.einsum("nij,nj->ni", _frames(tri0), v0[lash] - hit.points)
    new_v[lash] = np.einsum("nk,nkd->nd", hit.bary, tri1) + scale[:, None] * np.einsum("nij,ni->nj", _frames(tri1), local)
    return new_v
