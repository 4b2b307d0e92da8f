"""Sparse markers on a rig: the vertices that stand for an actor's optical markers (thesis §4.2).

Retargeting and the range-of-motion alignment of :mod:`~stimulus_engine.characters.blendshape_transfer`
work on ``M`` marker vertices rather than the whole mesh (the thesis's studies used 99 optical
markers). :func:`marker_vertices` picks them on a rig — the rig's landmark vertices of lids, lips,
brows and nose, then vertices spread evenly (farthest-point sampling) over the skin the
blendshapes move — and :func:`marker_mesh` triangulates them for the geometric constraint
(Eq. 4.11): a Delaunay triangulation in the face's frontal plane (a parametrisation of the face,
the thesis's *uv*-domain), whose triangles span the eye and mouth openings and so connect the
upper with the lower lids and lips, the contact edges the thesis adds; sliver triangles along the
outline are dropped.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import Delaunay

from stimulus_engine.characters.rig import FaceRig

__all__ = ["marker_laplacian", "marker_mesh", "marker_vertices", "moving_vertices"]

#: Landmarks whose vertices are always markers (the lids, lips, brows and nose of the face).
_FEATURE_LANDMARKS = (
    "eye_right_outer", "eye_right_inner", "eye_right_top", "eye_right_bottom",
    "eye_left_outer", "eye_left_inner", "eye_left_top", "eye_left_bottom",
    "nasion", "subnasale", "nose_tip", "nose_right", "nose_left",
    "mouth_right", "mouth_left", "mouth_top", "mouth_bottom", "chin", "brow_right", "brow_left",
)


def moving_vertices(rig: FaceRig, fraction: float = 0.02) -> np.ndarray:
    """Skin vertices that some blendshape moves by more than ``fraction`` of the largest motion."""
    if not rig.blendshapes:
        raise ValueError(f"rig '{rig.name}' has no blendshapes")
    motion = np.max([np.linalg.norm(d, axis=1) for d in rig.blendshapes.values()], axis=0)
    skin = np.zeros(len(rig.vertices), bool)
    skin[rig.skin] = True
    return np.flatnonzero(skin & (motion > fraction * motion.max()))


def _farthest_points(points: np.ndarray, start: np.ndarray, n: int) -> np.ndarray:
    """Indices of ``n`` points of ``points`` chosen greedily farthest from ``start`` and each other."""
    d = np.full(len(points), np.inf)
    for p in start:
        d = np.minimum(d, np.linalg.norm(points - p, axis=1))
    out = []
    for _ in range(n):
        i = int(np.argmax(d))
        if not np.isfinite(d[i]) or d[i] <= 0:
            break
        out.append(i)
        d = np.minimum(d, np.linalg.norm(points - points[i], axis=1))
    return np.asarray(out, np.int64)


def marker_vertices(rig: FaceRig, n: int = 120) -> np.ndarray:
    """``n`` marker vertices of ``rig``: its feature landmarks' vertices, then farthest-point samples
    of the moving skin (:func:`moving_vertices`), in that order.

    Parameters
    ----------
    rig : FaceRig
    n : int
        Number of markers (at least the landmark vertices; the thesis's captures had 99).

    Returns
    -------
    (n,) int array
        Vertex indices, distinct.
    """
    feature = np.unique(np.concatenate([np.asarray(rig.landmarks[k]).ravel() for k in _FEATURE_LANDMARKS
                                        if k in rig.landmarks]))
    if len(feature) > n:
        raise ValueError(f"{n} markers are fewer than the rig's {len(feature)} feature landmark vertices")
    cand = np.setdiff1d(moving_vertices(rig), feature)
    extra = _farthest_points(rig.vertices[cand], rig.vertices[feature], n - len(feature))
    return np.concatenate([feature, cand[extra]])


def _frontal_plane(points: np.ndarray) -> np.ndarray:
    """2-D coordinates of ``points`` in the plane of their two main directions (the face's front)."""
    c = points - points.mean(axis=0)
    _, _, vt = np.linalg.svd(c, full_matrices=False)
    return c @ vt[:2].T


def marker_mesh(points: np.ndarray, max_edge_ratio: float = 3.0) -> np.ndarray:
    """Triangles over marker ``points`` (M, 3): Delaunay in their frontal plane, slivers dropped.

    A triangle is dropped when its longest edge is more than ``max_edge_ratio`` times the
    median edge of the triangulation and it lies on the outline (long, thin triangles between
    the outermost markers). Triangles across the eye and mouth openings are kept: they are the
    lid and lip contact edges of the thesis.
    """
    uv = _frontal_plane(np.asarray(points, np.float64))
    tri = Delaunay(uv).simplices.astype(np.int64)
    e = np.stack([np.linalg.norm(uv[tri[:, (k + 1) % 3]] - uv[tri[:, k]], axis=1) for k in range(3)], axis=1)
    med = float(np.median(e))
    while True:
        edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
        _, inv, counts = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
        on_outline = (counts[inv.ravel()] == 1).reshape(3, -1).T.any(axis=1)
        e = np.stack([np.linalg.norm(uv[tri[:, (k + 1) % 3]] - uv[tri[:, k]], axis=1) for k in range(3)], axis=1)
        drop = on_outline & (e.max(axis=1) > max_edge_ratio * med)
        if not drop.any():
            return tri
        tri = tri[~drop]


def marker_laplacian(points: np.ndarray, triangles: np.ndarray) -> sp.csr_matrix:
    """The cotangent Laplacian (Pinkall & Polthier 1993) of the marker mesh, M × M (rows sum to 0)."""
    from stimulus_engine.correspondence.laplacian import cotangent_laplacian

    return cotangent_laplacian(np.asarray(points, np.float64), triangles)
