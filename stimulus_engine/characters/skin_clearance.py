"""Parts kept behind a scan's skin in every pose: the mouth's inside and the eyeballs.

A scan's skin is bound to the rig's skin, while the parts behind it (the rig's teeth, gums and
tongue; the eyeballs behind the cut lids) move with the rig's own parts: a stylised shape (a
smaller mouth, a shorter jaw), an expression or an eyeball turned to the camera can bring a
tooth out over the lips or the chin, or an eyeball through a thin lower lid (a grey patch of
sclera on the james scan's left lower lid). :func:`behind_skin` moves such a part back (-z,
away from the viewer) until none of it lies in front of the skin.
"""

from __future__ import annotations

import numpy as np

__all__ = ["behind_skin", "eyes_behind_skin", "inside_behind_skin"]


def behind_skin(vertices: np.ndarray, faces: np.ndarray, face_part: np.ndarray, part_names: tuple[str, ...],
                moving: np.ndarray, gap: float = 0.05) -> np.ndarray:
    """``vertices`` with the vertex set ``moving`` shifted back (-z) until none of it is in front of the skin.

    A vertex is *in front of the skin* where a ray from it away from the viewer (-z) first meets
    a ``skin`` triangle that faces the viewer; the set moves back, as a whole, by the deepest
    such distance plus ``gap`` (the rig's units: centimetres).

    Parameters
    ----------
    vertices : (N, 3) array
        A pose of a drawn topology (+z towards the viewer).
    faces, face_part, part_names
        Its triangles and their parts (``skin`` is the surface that may not be pierced).
    moving : int array
        The vertices to keep behind it.

    Returns
    -------
    (N, 3) array
        A copy.
    """
    import trimesh

    from stimulus_engine.geometry.mesh_ops import face_normals

    v = np.array(vertices, np.float64, copy=True)
    moving = np.asarray(moving, np.int64)
    if "skin" not in part_names or not len(moving):
        return v
    skin = faces[face_part == part_names.index("skin")]
    front = trimesh.Trimesh(v, skin[face_normals(v, skin)[0][:, 2] > 0], process=False)
    loc, ray, _ = front.ray.intersects_location(v[moving], np.tile([0.0, 0.0, -1.0], (len(moving), 1)),
                                                multiple_hits=False)
    if len(ray):
        v[moving, 2] -= float((v[moving][ray, 2] - loc[:, 2]).max()) + gap
    return v


def inside_behind_skin(vertices: np.ndarray, faces: np.ndarray, face_part: np.ndarray, part_names: tuple[str, ...],
                       inside: tuple[str, ...] = ("mouth", "teeth", "tongue"), gap: float = 0.05) -> np.ndarray:
    """The mouth's inside parts, together (so they keep their shape), kept behind the skin."""
    ids = [part_names.index(p) for p in inside if p in part_names]
    moving = np.unique(faces[np.isin(face_part, ids)]) if ids else np.zeros(0, np.int64)
    return behind_skin(vertices, faces, face_part, part_names, moving, gap)


def eyes_behind_skin(vertices: np.ndarray, faces: np.ndarray, face_part: np.ndarray, part_names: tuple[str, ...],
                     landmarks: dict[str, np.ndarray], gap: float = 0.02) -> np.ndarray:
    """Each eyeball (landmark sets ``eye_right``, ``eye_left``) kept behind the lids on its own."""
    v = np.asarray(vertices, np.float64)
    for side in ("right", "left"):
        if f"eye_{side}" in landmarks:
            v = behind_skin(v, faces, face_part, part_names, landmarks[f"eye_{side}"], gap)
    return v
