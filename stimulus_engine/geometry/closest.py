"""Closest points on a triangle mesh, as (triangle, barycentric) pairs, with boundary flags.

With Numba installed (the ``fast`` extra), a bounding-volume hierarchy over the triangles
answers exactly, for any point (:mod:`.triangle_bvh`). Without it, k-d trees over the
target's vertices and triangle centroids propose candidate triangles (those around the
``k_vertices`` nearest vertices plus the ``k`` nearest centroids) and the exact point-triangle
projection (Ericson, *Real-Time Collision Detection*, 5.1.5) picks the best: exact whenever
the closest triangle touches one of the candidates, which holds on the dense, near-coincident
meshes the registration works with (on the 19k -> 10k benchmark pair, all but one of 19k
points 0.01 off the surface).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from scipy.spatial import cKDTree

from stimulus_engine.geometry import triangle_bvh
from stimulus_engine.geometry.mesh_ops import boundary_edge_mask, face_normals, vertex_faces

__all__ = [
    "SurfaceIndex",
    "ClosestPoints",
    "closest_point_on_triangles",
    "lift_out",
    "project_to_triangles",
]


#: queries of at least this many points are split over the cores (NumPy and the k-d tree
#: release the GIL: two threads answer 19k queries in half the time on two cores)
_PARALLEL_MIN = 8192


_THREADS = min(os.cpu_count() or 1, 8)


@lru_cache(maxsize=1)
def _pool() -> ThreadPoolExecutor:
    return ThreadPoolExecutor(_THREADS, thread_name_prefix="closest")


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
    return _project(np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap), np.einsum("ij,ij->i", ap, ap),
                    aa, bb, cc)


def _project(d1, d2, pp, aa, bb, cc):
    """:func:`project_to_triangles` from the dot products ``d1 = ab·ap``, ``d2 = ac·ap`` and
    ``pp = ap·ap``."""
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
        if m.any():
            t = e43[m] / (e43[m] + e56[m])
            v[m], w[m] = 1.0 - t, t
        m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)  # edge AC
        if m.any():
            v[m], w[m] = 0.0, d2[m] / (d2[m] - d6[m])
        m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)  # edge AB
        if m.any():
            v[m], w[m] = d1[m] / (d1[m] - d3[m]), 0.0
    for m, (vv, ww) in (
        ((d6 >= 0) & (d5 <= d6), (0.0, 1.0)),  # vertex C
        ((d3 >= 0) & (d4 <= d3), (1.0, 0.0)),  # vertex B
        ((d1 <= 0) & (d2 <= 0), (0.0, 0.0)),  # vertex A
    ):
        v[m], w[m] = vv, ww
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
        Nearest centroids whose triangles are tested per query.
    k_vertices : int
        Nearest vertices whose surrounding triangles are tested per query.
    compiled : bool
        Answer with the exact, compiled bounding-volume hierarchy of :mod:`.triangle_bvh` when
        Numba is installed (k and k_vertices are then unused); False, or without Numba: the
        k-d tree candidates, picked among with NumPy.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, k: int = 3, k_vertices: int = 2, compiled: bool = True):
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)
        self.k = k
        self.k_vertices = k_vertices
        #: the compiled hierarchy answers (else the NumPy path)
        self.compiled = compiled and triangle_bvh.compiled
        # NumPy path: vertex -> incident faces, padded with -1 (candidates: faces around the 2
        # nearest vertices and the k nearest centroids)
        self._vf = None if self.compiled else vertex_faces(self.faces, len(self.vertices))
        self._n_faces = len(self.faces)
        self._build()

    @cached_property
    def boundary(self) -> np.ndarray:
        """(F, 3) bool: the edge opposite each corner has no neighbouring face."""
        return boundary_edge_mask(self.faces)

    @cached_property
    def boundary_vertices(self) -> np.ndarray:
        """(N,) bool: the ends of the boundary edges (mesh_ops.boundary_vertex_mask, without
        counting the edges again)."""
        out = np.zeros(len(self.vertices), dtype=bool)
        for k in range(3):
            out[self.faces[self.boundary[:, k]][:, [(k + 1) % 3, (k + 2) % 3]]] = True
        return out

    @cached_property
    def face_normals(self) -> np.ndarray:
        """(F, 3) unit normals at the current vertex positions."""
        return face_normals(self.vertices, self.faces)[0]

    def _build(self) -> None:
        tri = self.vertices[self.faces]
        if self.compiled:
            self._bvh = triangle_bvh.build_bvh(tri)
        else:
            # sliding-midpoint trees: built in half the time of median-balanced ones, and
            # queried as fast on mesh vertices and centroids
            self._vtree = cKDTree(self.vertices, balanced_tree=False)
            self._ctree = cKDTree(tri.mean(axis=1), balanced_tree=False)
        # per-triangle data of the projection kernel, one row per triangle (one gather per
        # query): corner a, ab, ac, ab·ab, ab·ac, ac·ac
        ab, ac = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        self._fdata = np.concatenate(
            [tri[:, 0], ab, ac, np.einsum("ij,ij->i", ab, ab)[:, None], np.einsum("ij,ij->i", ab, ac)[:, None],
             np.einsum("ij,ij->i", ac, ac)[:, None]], axis=1)
        self.__dict__.pop("face_normals", None)  # computed again when asked for

    def update(self, vertices: np.ndarray) -> None:
        """New vertex positions, same triangulation."""
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self._build()

    def closest(self, points: np.ndarray, chunk: int = 65536) -> tuple[np.ndarray, np.ndarray]:
        """Closest triangle and barycentric weights for each of ``points`` (Q, 3), in chunks."""
        face, v, w = self._closest(points, chunk)
        return face, np.stack([1.0 - v - w, v, w], axis=1)

    def _closest(self, points: np.ndarray, chunk: int, hint: np.ndarray | None = None):
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        hint = np.full(len(p), -1, dtype=np.int64) if hint is None else np.asarray(hint, dtype=np.int64)
        if _THREADS > 1 and len(p) >= _PARALLEL_MIN:
            n_parts = max(_THREADS, -(-len(p) // chunk))
            parts = list(_pool().map(self._query, np.array_split(p, n_parts), np.array_split(hint, n_parts)))
        elif len(p) <= chunk:
            return self._query(p, hint)
        else:
            parts = [self._query(p[a : a + chunk], hint[a : a + chunk]) for a in range(0, len(p), chunk)]
        return tuple(np.concatenate(x) for x in zip(*parts))

    def distance(self, points: np.ndarray, chunk: int = 65536) -> np.ndarray:
        """Distance of each of ``points`` (Q, 3) to the surface (what :meth:`query` gives, without
        its points, flags and normals)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        face, v, w = self._closest(p, chunk)
        fd = self._fdata[face]
        d = fd[:, 0:3] + v[:, None] * fd[:, 3:6] + w[:, None] * fd[:, 6:9] - p
        return np.sqrt(np.einsum("ij,ij->i", d, d))

    def query(self, points: np.ndarray, chunk: int = 65536, hint: np.ndarray | None = None) -> ClosestPoints:
        """Closest surface point for each of ``points`` (Q, 3), with distances, boundary flags
        and normals. ``hint``: a triangle near each point (e.g. its closest one before it
        moved a little), where the compiled search starts: the same answer, found sooner."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        face, v, w = self._closest(p, chunk, hint)
        fd = self._fdata[face]
        pts = fd[:, 0:3] + v[:, None] * fd[:, 3:6] + w[:, None] * fd[:, 6:9]
        bary = np.stack([1.0 - v - w, v, w], axis=1)
        eps = 1e-9
        on_boundary = ((bary < eps) & self.boundary[face]).any(axis=1)
        # a closest point at a vertex (two zero weights) is on the boundary if the vertex is
        at_vertex = bary > 1 - eps
        hit = at_vertex.any(axis=1)
        if hit.any():
            on_boundary[hit] |= (at_vertex[hit] & self.boundary_vertices[self.faces[face[hit]]]).any(axis=1)
        d = pts - p
        return ClosestPoints(
            face=face,
            bary=bary,
            points=pts,
            distance=np.sqrt(np.einsum("ij,ij->i", d, d)),
            on_boundary=on_boundary,
            normals=self.face_normals[face],
        )

    def _query(self, p: np.ndarray, hint: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self.compiled:
            return self._bvh.closest(p, self._fdata, hint)
        kv = min(self.k_vertices, len(self.vertices))
        vi = np.zeros((len(p), 0), dtype=np.int64)
        if kv > 0:
            vi = np.asarray(self._vtree.query(p, k=kv, workers=-1)[1]).reshape(len(p), -1)
        kc = min(self.k, self._n_faces)
        ci = np.zeros((len(p), 0), dtype=np.int64)
        if kc > 0 or kv == 0:
            ci = np.asarray(self._ctree.query(p, k=max(kc, 1), workers=-1)[1]).reshape(len(p), -1)
        parts = [self._vf[vi].reshape(len(p), -1), ci]
        # (Q, K) candidate triangles, -1 = none; neighbouring vertices share triangles, so
        # duplicates in a row are dropped before the (costly) exact projections
        cand = np.sort(np.concatenate(parts, axis=1), axis=1)
        cand[:, 1:][cand[:, 1:] == cand[:, :-1]] = -1
        keep = cand >= 0
        q_idx = np.nonzero(keep)[0]  # still grouped by query, in order
        f_idx = cand[keep]
        fd = self._fdata[f_idx]
        ap = p[q_idx] - fd[:, 0:3]
        v, w, d2 = _project(
            np.einsum("ij,ij->i", fd[:, 3:6], ap), np.einsum("ij,ij->i", fd[:, 6:9], ap), np.einsum("ij,ij->i", ap, ap),
            fd[:, 9], fd[:, 10], fd[:, 11],
        )
        counts = keep.sum(axis=1)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        mins = np.minimum.reduceat(d2, starts)
        # first candidate of each query reaching its minimum (candidates are grouped by query)
        is_min = np.flatnonzero(d2 == np.repeat(mins, counts))
        qm = q_idx[is_min]
        sel = is_min[np.concatenate([[True], qm[1:] != qm[:-1]])]
        return f_idx[sel], v[sel], w[sel]


def lift_out(points: np.ndarray, index: SurfaceIndex, vertex_normals: np.ndarray, lift: float,
             reach: float = np.inf, at_border: bool = False) -> np.ndarray:
    """``points`` moved out along the surface's (interpolated) normal to ``lift`` over the
    surface of ``index``, where they are lower than that over it or under it, within ``reach``
    of it; points whose nearest surface point is on its border are left unless ``at_border``
    (their side of an open surface is uncertain there).

    Parameters
    ----------
    points : (Q, 3) array
    index : SurfaceIndex
        The surface (its current vertex positions).
    vertex_normals : (N, 3) array
        Unit normals at the surface's vertices (outward).
    lift, reach : float
        Clearance wanted, and the farthest surface that counts.
    at_border : bool
        Also move points nearest the surface's border.

    Returns
    -------
    (Q, 3) array
    """
    hit = index.query(points)
    n = np.einsum("qk,qkd->qd", hit.bary, vertex_normals[index.faces[hit.face]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    height = np.einsum("qd,qd->q", points - hit.points, n)
    push = (at_border | ~hit.on_boundary) & (height < lift) & (hit.distance < reach)
    out = np.array(points, np.float64, copy=True)
    out[push] += (lift - height[push])[:, None] * n[push]
    return out
