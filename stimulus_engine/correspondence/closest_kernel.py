"""The closest-triangle search over candidate triangles, compiled with Numba when it is there.

:class:`~.closest.SurfaceIndex` proposes candidate triangles per query point (those around
the nearest vertices and the nearest centroids, from k-d trees) and keeps the one whose exact
point-triangle projection is nearest. Written with NumPy, that last step builds a dozen
temporary arrays of (queries × candidates) and costs three times the k-d tree queries; as one
compiled loop per query point it costs a tenth of them (``benchmarks/correspond.py``: the
19k → 10k pair makes ~14 such queries per correspondence).

Numba is optional (``pip install 'appeal-lab[fast]'``; ``make`` installs it):
:func:`best_candidates` is ``None`` without it and :class:`~.closest.SurfaceIndex` uses its
NumPy path, which gives the same triangles (tests compare the two). The compiled function
releases the GIL, so the index's worker threads run it on all cores; it is cached on disk
after its first compilation.
"""

from __future__ import annotations

import numpy as np

__all__ = ["best_candidates", "numba_available"]

try:
    import numba
except ImportError:  # the NumPy path of SurfaceIndex is used
    numba = None


def numba_available() -> bool:
    """Whether the compiled kernel is in use."""
    return numba is not None


def _project_one(fd: np.ndarray, px: float, py: float, pz: float) -> tuple[float, float, float]:
    """Ericson's closest point on one triangle (row ``fd`` of the index's per-triangle data:
    corner a, ab, ac, ab·ab, ab·ac, ac·ac): barycentric ``(v, w)`` of corners b, c and the
    squared distance, with the same region precedence and degenerate fallback as
    :func:`~.closest._project` (vertices before edges before the inside)."""
    apx, apy, apz = px - fd[0], py - fd[1], pz - fd[2]
    d1 = fd[3] * apx + fd[4] * apy + fd[5] * apz
    d2 = fd[6] * apx + fd[7] * apy + fd[8] * apz
    pp = apx * apx + apy * apy + apz * apz
    aa, bb, cc = fd[9], fd[10], fd[11]
    d3, d4 = d1 - aa, d2 - bb
    d5, d6 = d1 - bb, d2 - cc
    if d1 <= 0.0 and d2 <= 0.0:  # vertex A
        v, w = 0.0, 0.0
    elif d3 >= 0.0 and d4 <= d3:  # vertex B
        v, w = 1.0, 0.0
    elif d6 >= 0.0 and d5 <= d6:  # vertex C
        v, w = 0.0, 1.0
    else:
        va = d3 * d6 - d5 * d4
        vb = d5 * d2 - d1 * d6
        vc = d1 * d4 - d3 * d2
        e43, e56 = d4 - d3, d5 - d6
        if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:  # edge AB
            v, w = d1 / (d1 - d3), 0.0
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:  # edge AC
            v, w = 0.0, d2 / (d2 - d6)
        elif va <= 0.0 and e43 >= 0.0 and e56 >= 0.0:  # edge BC
            t = e43 / (e43 + e56)
            v, w = 1.0 - t, t
        else:
            denom = va + vb + vc
            v, w = vb / denom, vc / denom
        if not (np.isfinite(v) and np.isfinite(w)):  # degenerate triangle: its first corner
            v, w = 0.0, 0.0
    dist2 = v * v * aa + w * w * cc + 2.0 * v * w * bb - 2.0 * v * d1 - 2.0 * w * d2 + pp
    return v, w, max(dist2, 0.0)


def _best_candidates(points, vertex_hits, vertex_faces, centroid_hits, fdata):
    """For each point, the nearest of its candidate triangles: the faces around its
    ``vertex_hits`` (rows of ``vertex_faces``, padded with -1) and its ``centroid_hits``.
    Ties go to the lower triangle index. Returns ``(face, v, w)``."""
    n = points.shape[0]
    face = np.empty(n, dtype=np.int64)
    vv = np.empty(n)
    ww = np.empty(n)
    n_around = vertex_hits.shape[1] * vertex_faces.shape[1]
    for q in range(n):
        px, py, pz = points[q, 0], points[q, 1], points[q, 2]
        best_f, best_d, best_v, best_w = -1, np.inf, 0.0, 0.0
        for j in range(n_around + centroid_hits.shape[1]):
            if j < n_around:
                f = vertex_faces[vertex_hits[q, j // vertex_faces.shape[1]], j % vertex_faces.shape[1]]
            else:
                f = centroid_hits[q, j - n_around]
            if f < 0:
                continue
            v, w, d = _project_one(fdata[f], px, py, pz)
            if d < best_d or (d == best_d and f < best_f):
                best_f, best_d, best_v, best_w = f, d, v, w
        face[q], vv[q], ww[q] = best_f, best_v, best_w
    return face, vv, ww


if numba is not None:
    _project_one = numba.njit(cache=True, nogil=True, error_model="numpy")(_project_one)
    best_candidates = numba.njit(cache=True, nogil=True, error_model="numpy")(_best_candidates)
else:
    best_candidates = None
