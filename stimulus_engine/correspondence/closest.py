"""Closest points on a triangle mesh, as (triangle, barycentric) pairs, with boundary flags.

A k-d tree over the target's vertices and triangle centroids proposes candidate triangles
(those around the ``k`` nearest vertices plus the ``k`` nearest centroids); the exact
point-triangle projection (Ericson, *Real-Time Collision Detection*, 5.1.5) picks the best.
The result is exact whenever the closest triangle touches one of the candidates, which holds
on the dense, near-coincident meshes the registration works with.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from stimulus_engine.mesh_ops import boundary_edge_mask, boundary_vertex_mask, face_normals, vertex_faces

__all__ = [
    "SurfaceIndex",
    "ClosestPoints",
    "closest_point_on_triangles",
    "project_to_triangles",
]


def project_to_triangles(
    ap: np.ndarray, ab: np.ndarray, ac: np.ndarray, aa: np.ndarray, bb: np.ndarray, cc: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest point of ``a + ap`` on triangle ``(a, a + ab, a + ac)``, row by row.

    Ericson's Voronoi-region test (*Real-Time Collision Detection*, 5.1.5) written with the
    per-triangle scalars ``aa = ab·ab``, ``bb = ab·ac``, ``cc = ac·ac`` (precomputed once per
    mesh): two dot products per row instead of six, and the squared distance from the same
    scalars without forming the point. Degenerate triangles give their first corner.

    Returns
    -------
    v, w : (K,) arrays
        Barycentric weights of the second and third corner (the first is ``1 - v - w``).
    dist2 : (K,) array
        Squared distance (for choosing among candidates; cancellation limits it to about
        1e-8 of the triangle size — recompute from the point where it matters).
    """
    d1 = np.einsum("ij,ij->i", ab, ap)
    d2 = np.einsum("ij,ij->i", ac, ap)
    pp = np.einsum("ij,ij->i", ap, ap)
    d3, d4 = d1 - aa, d2 - bb  # ab·bp, ac·bp
    d5, d6 = d1 - bb, d2 - cc  # ab·cp, ac·cp
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    e43, e56 = d4 - d3, d5 - d6
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v, w = vb / denom, vc / denom  # inside the face
        # regions in reverse order of Ericson's tests, so the first matching one wins
        m = (va <= 0) & (e43 >= 0) & (e56 >= 0)  # edge BC
        t = e43 / (e43 + e56)
        v, w = np.where(m, 1.0 - t, v), np.where(m, t, w)
        m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)  # edge AC
        v, w = np.where(m, 0.0, v), np.where(m, d2 / (d2 - d6), w)
        m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)  # edge AB
        v, w = np.where(m, d1 / (d1 - d3), v), np.where(m, 0.0, w)
    for m, (vv, ww) in (
        ((d6 >= 0) & (d5 <= d6), (0.0, 1.0)),  # vertex C
        ((d3 >= 0) & (d4 <= d3), (1.0, 0.0)),  # vertex B
        ((d1 <= 0) & (d2 <= 0), (0.0, 0.0)),  # vertex A
    ):
        v, w = np.where(m, vv, v), np.where(m, ww, w)
    bad = ~(np.isfinite(v) & np.isfinite(w))
    v[bad], w[bad] = 0.0, 0.0  # degenerate triangle: its first corner
    dist2 = v * v * aa + w * w * cc + 2.0 * v * w * bb - 2.0 * v * d1 - 2.0 * w * d2 + pp
    return v, w, np.maximum(dist2, 0.0)


def closest_point_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest point of each ``p`` on triangle ``(a, b, c)`` (all (K, 3)); returns bary (K, 3).

    See :func:`project_to_triangles`; degenerate triangles fall back to their first corner.
    """
    ab, ac = b - a, c - a
    v, w, _ = project_to_triangles(
        p - a, ab, ac, np.einsum("ij,ij->i", ab, ab), np.einsum("ij,ij->i", ab, ac), np.einsum("ij,ij->i", ac, ac)
    )
    return np.stack([1.0 - v - w, v, w], axis=1)


@dataclass
class ClosestPoints:
    """Closest points: ``face`` (Q,), ``bary`` (Q, 3), ``points`` (Q, 3), ``distance`` (Q,),
    ``on_boundary`` (Q,) and the target ``normals`` (Q, 3) at those points (face normals)."""

    face: np.ndarray
    bary: np.ndarray
    points: np.ndarray
    distance: np.ndarray
    on_boundary: np.ndarray
    normals: np.ndarray


class SurfaceIndex:
    """Closest-point queries on a fixed triangulation whose vertex positions may change.

    Parameters
    ----------
    vertices : (N, 3) array
    faces : (F, 3) int array
    k : int
        Nearest vertices and centroids whose triangles are tested per query.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, k: int = 3, k_vertices: int = 2):
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)
        self.k = k
        self.k_vertices = k_vertices
        # vertex -> incident faces, padded with -1 (candidates: faces around the 2 nearest
        # vertices and the k nearest centroids)
        self._vf = vertex_faces(self.faces, len(self.vertices))
        self.boundary = boundary_edge_mask(self.faces)
        self.boundary_vertices = boundary_vertex_mask(self.faces, len(self.vertices))
        self._n_faces = len(self.faces)
        self._build()

    def _build(self) -> None:
        tri = self.vertices[self.faces]
        self._tri = tri
        self._vtree = cKDTree(self.vertices)
        self._ctree = cKDTree(tri.mean(axis=1))
        # per-triangle data of the projection kernel
        self._a = tri[:, 0]
        self._ab, self._ac = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        self._dots = np.stack(
            [np.einsum("ij,ij->i", self._ab, self._ab), np.einsum("ij,ij->i", self._ab, self._ac),
             np.einsum("ij,ij->i", self._ac, self._ac)], axis=1)
        self.face_normals = face_normals(self.vertices, self.faces)[0]

    def update(self, vertices: np.ndarray) -> None:
        """New vertex positions, same triangulation."""
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self._build()

    def closest(self, points: np.ndarray, chunk: int = 65536) -> tuple[np.ndarray, np.ndarray]:
        """Closest triangle and barycentric weights for each of ``points`` (Q, 3), in chunks."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        face = np.empty(len(p), dtype=np.int64)
        bary = np.empty((len(p), 3))
        for a in range(0, len(p), chunk):
            face[a : a + chunk], bary[a : a + chunk] = self._query(p[a : a + chunk])
        return face, bary

    def query(self, points: np.ndarray, chunk: int = 65536) -> ClosestPoints:
        """Closest surface point for each of ``points`` (Q, 3), with distances, boundary flags
        and normals."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        face, bary = self.closest(p, chunk)
        pts = np.einsum("ij,ijk->ik", bary, self._tri[face])
        eps = 1e-9
        on_edge = (bary < eps) & self.boundary[face]
        # a closest point at a vertex (two zero weights) is on the boundary if the vertex is
        at_vertex = (bary > 1 - eps) & self.boundary_vertices[self.faces[face]]
        return ClosestPoints(
            face=face,
            bary=bary,
            points=pts,
            distance=np.linalg.norm(pts - p, axis=1),
            on_boundary=on_edge.any(axis=1) | at_vertex.any(axis=1),
            normals=self.face_normals[face],
        )

    def _query(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        parts = []
        kv = min(self.k_vertices, len(self.vertices))
        if kv > 0:
            _, vi = self._vtree.query(p, k=kv, workers=-1)
            parts.append(self._vf[np.asarray(vi).reshape(len(p), -1)].reshape(len(p), -1))
        kc = min(self.k, self._n_faces)
        if kc > 0 or not parts:
            _, ci = self._ctree.query(p, k=max(kc, 1), workers=-1)
            parts.append(np.asarray(ci).reshape(len(p), -1))
        # (Q, K) candidate triangles, -1 = none; neighbouring vertices share triangles, so
        # duplicates in a row are dropped before the (costly) exact projections
        cand = np.sort(np.concatenate(parts, axis=1), axis=1)
        cand[:, 1:][cand[:, 1:] == cand[:, :-1]] = -1
        q_idx = np.repeat(np.arange(len(p)), cand.shape[1])
        f_idx = cand.ravel()
        keep = f_idx >= 0
        q_idx, f_idx = q_idx[keep], f_idx[keep]  # still grouped by query, in order
        dots = self._dots[f_idx]
        v, w, d2 = project_to_triangles(
            p[q_idx] - self._a[f_idx], self._ab[f_idx], self._ac[f_idx], dots[:, 0], dots[:, 1], dots[:, 2]
        )
        counts = np.bincount(q_idx, minlength=len(p))
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        mins = np.minimum.reduceat(d2, starts)
        # first candidate of each query reaching its minimum (candidates are grouped by query)
        is_min = np.flatnonzero(d2 == np.repeat(mins, counts))
        qm = q_idx[is_min]
        sel = is_min[np.concatenate([[True], qm[1:] != qm[:-1]])]
        v, w = v[sel], w[sel]
        return f_idx[sel], np.stack([1.0 - v - w, v, w], axis=1)
