"""Cotangent Laplacian, mixed Voronoi areas and the bi-Laplacian energy matrix (eq. 3.3-3.8).

For a vertex ``i`` the Laplace-Beltrami operator is (eq. 3.4)
``Δv_i = 1/(2 A_i) Σ_j (cot α_ij + cot β_ij)(v_j - v_i)``. We write ``Δ = A⁻¹ L`` with
``L_ij = ½ (cot α_ij + cot β_ij)`` and ``L_ii = -Σ_j L_ij`` (symmetric, negative
semi-definite), so that ``Σ_i A_i ||Δ v_i||² = tr(Vᵀ Lᵀ A⁻¹ L V)``: the matrix
:func:`bilaplacian` returns. Keeping ``L`` fixed and updating only ``A`` follows
Kazhdan et al. (2012), as the thesis does to avoid degenerate cotangent weights.

Boundaries: the cotangent formula is a mean-curvature normal only at interior vertices; at a
boundary vertex it measures the in-plane co-normal, and penalising it would shrink every open
mesh (and make the energy grow with resolution). :func:`fairing_operator` therefore keeps the
cotangent rows at interior vertices and uses the boundary curve's curvature vector
``κ_b = 2/(|e1|+|e2|) ((v_prev - v_b)/|e1| + (v_next - v_b)/|e2|)`` (scaled by the vertex area,
like the interior rows) at boundary vertices: a flat disc with a straight-ish boundary then has
(near) zero energy, the thin-plate surface is free to flatten, and the boundary curve is faired
too. With the boundaries of both meshes tied by boundary-loop correspondences this is the
thesis's thin plate with identical Dirichlet boundaries (§3.2.3); without them (a face region
against a scan of another extent) the boundary stays free.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from stimulus_engine.geometry.mesh_ops import boundary_neighbours

__all__ = [
    "cotangent_laplacian",
    "voronoi_areas",
    "bilaplacian",
    "bilaplacian_map",
    "face_cotangents",
    "fairing_operator",
]

#: Cotangents are clamped to this magnitude so that needle triangles cannot blow up the system.
COT_CLAMP = 1e3


def _triangle_terms(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per triangle: squared lengths of the edges opposite each corner (3, F), the corners'
    cotangents (3, F, clamped) and twice the area (F,), from one cross product per triangle
    (the cotangent at corner k is ``(a·b) / |a×b|`` for its two edges, and ``|a×b|`` is
    twice the area at every corner), coordinate by coordinate (no (F, 3) temporaries)."""
    p = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).T)[:, np.asarray(faces).T]  # (xyz, corner, F)
    e = np.stack([p[:, 2] - p[:, 1], p[:, 0] - p[:, 2], p[:, 1] - p[:, 0]], axis=1)  # edge opposite corner k
    l2 = np.einsum("ckf,ckf->kf", e, e)
    a, b = e[:, 2], -e[:, 1]  # v1 - v0, v2 - v0
    cross = np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
    twice_area = np.sqrt(np.einsum("cf,cf->f", cross, cross))
    # corner k's edges: v_{k+1} - v_k = e_{k+2} and v_{k+2} - v_k = -e_{k+1}
    dot = np.empty_like(l2)
    for k in range(3):  # row by row: no (3, 3, F) copies for the fancy-indexed einsum
        u, w = e[:, (k + 2) % 3], e[:, (k + 1) % 3]
        dot[k] = -(u[0] * w[0] + u[1] * w[1] + u[2] * w[2])
    cot = np.clip(dot / np.maximum(twice_area, 1e-300), -COT_CLAMP, COT_CLAMP)
    return l2, cot, twice_area


def face_cotangents(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Cotangent of each triangle's three corner angles, shape (F, 3)."""
    return np.ascontiguousarray(_triangle_terms(vertices, faces)[1].T)


def cotangent_laplacian(vertices: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """The cotangent matrix ``L`` (N x N): ``L_ij = ½(cot α + cot β)``, rows sum to zero."""
    n = len(vertices)
    cot = face_cotangents(vertices, faces)
    # the angle at corner k is opposite to edge (k+1, k+2)
    i = np.concatenate([faces[:, 1], faces[:, 2], faces[:, 0]])
    j = np.concatenate([faces[:, 2], faces[:, 0], faces[:, 1]])
    w = 0.5 * np.concatenate([cot[:, 0], cot[:, 1], cot[:, 2]])
    off = sp.coo_matrix((w, (i, j)), shape=(n, n))
    off = (off + off.T).tocsr()
    diag = np.asarray(off.sum(axis=1)).ravel()
    return (off - sp.diags(diag)).tocsr()


def voronoi_areas(vertices: np.ndarray, faces: np.ndarray, floor: float = 1e-3) -> np.ndarray:
    """Mixed Voronoi area per vertex (Meyer et al. 2003); obtuse triangles split ½ / ¼ / ¼.

    Vertices used by no triangle get the mean area (they are otherwise inert). Areas below
    ``floor`` times the median area are raised to it: the energy weighs each vertex by
    ``1 / A_i``, and a region that the fairing has collapsed (far from every reference point
    a faired real scan's neck or ears flatten to areas ~1e-16 of the median) would otherwise
    make the system numerically singular (CHOLMOD: "not positive definite").
    """
    n = len(vertices)
    faces = np.asarray(faces)
    l2, cot, twice_area = _triangle_terms(vertices, faces)
    # Voronoi part for corner k: 1/8 (|e_{k+1}|² cot_{k+1} + |e_{k+2}|² cot_{k+2})
    lc = l2 * cot
    vor = (lc[[1, 2, 0]] + lc[[2, 0, 1]]) / 8.0
    obtuse_corner = cot < 0  # angle > 90 degrees
    any_obtuse = obtuse_corner.any(axis=0)
    corner_area = np.where(any_obtuse, np.where(obtuse_corner, 0.25, 0.125) * twice_area, vor).T
    out = np.bincount(faces.ravel(), weights=corner_area.ravel(), minlength=n)
    used = np.bincount(faces.ravel(), minlength=n) > 0
    if (~used).any():
        out[~used] = out[used].mean() if used.any() else 1.0
    return np.maximum(out, floor * max(float(np.median(out)), 1e-300))


def bilaplacian(L: sp.spmatrix, areas: np.ndarray) -> sp.csr_matrix:
    """``Lᵀ A⁻¹ L``: the matrix of ``Σ_i A_i ||Δ v_i||²`` (eq. 3.5, 3.8, 3.11)."""
    return (L.T @ sp.diags(1.0 / areas) @ L).tocsr()


def bilaplacian_map(L: sp.spmatrix, *others: sp.spmatrix):
    """The lower-triangle pattern of ``Lᵀ W L + others`` and the linear map from the diagonal
    ``w`` (N,) of ``W`` to the values of ``Lᵀ diag(w) L`` on it.

    Returns ``(pattern, M)``: a :class:`~stimulus_engine.correspondence.solve.LowerPattern`
    (the structure of ``Lᵀ L``, of ``others`` and the diagonal) and a sparse ``M`` with
    ``M @ (1 / areas)`` the lower triangle of :func:`bilaplacian` in the pattern's order: no
    sparse matrix product per new ``areas`` (the joint fairing recomputes them every
    iteration). Entry ``(i, j)`` of ``Lᵀ diag(w) L`` is ``Σ_k L_ki L_kj w_k``: ``M`` has one
    row per pattern entry and one column per ``k``.
    """
    from stimulus_engine.correspondence.solve import LowerPattern

    lc = sp.csr_matrix(L)
    lc.sum_duplicates()
    lc.sort_indices()
    n = lc.shape[0]
    r = np.diff(lc.indptr)
    row_of = np.repeat(np.arange(n, dtype=np.int64), r)  # row k of each stored entry
    # the entry at offset a of its row pairs with offsets 0..a (columns sorted: i >= j)
    offset = np.arange(lc.nnz, dtype=np.int64) - lc.indptr[row_of]
    cnt = offset + 1
    first = np.repeat(np.arange(lc.nnz, dtype=np.int64), cnt)
    second = np.arange(len(first), dtype=np.int64) - np.repeat(np.cumsum(cnt) - cnt - lc.indptr[row_of], cnt)
    i, j = lc.indices[first], lc.indices[second]
    pattern = LowerPattern(n, *others, entries=(i, j))
    m = sp.csr_matrix((lc.data[first] * lc.data[second], (pattern.entry_positions, row_of[first])),
                      shape=(pattern.nnz, n))
    return pattern, m


def fairing_operator(vertices: np.ndarray, faces: np.ndarray, areas: np.ndarray | None = None) -> sp.csr_matrix:
    """``A·Δ`` rows: cotangent rows at interior vertices, boundary-curve curvature rows at
    boundary vertices (see the module notes). ``Σ A_i ||Δv_i||² = ||A^{-1/2} (op @ V)||²``."""
    v = np.asarray(vertices, dtype=np.float64)
    n = len(v)
    lap = cotangent_laplacian(v, faces)
    b, prv, nxt = boundary_neighbours(faces, n)
    if len(b) == 0:
        return lap
    a = voronoi_areas(v, faces) if areas is None else areas
    e1 = np.maximum(np.linalg.norm(v[prv] - v[b], axis=1), 1e-300)
    e2 = np.maximum(np.linalg.norm(v[nxt] - v[b], axis=1), 1e-300)
    s = 2.0 * a[b] / (e1 + e2)
    w1, w2 = s / e1, s / e2
    rows = np.concatenate([b, b, b])
    cols = np.concatenate([prv, nxt, b])
    vals = np.concatenate([w1, w2, -(w1 + w2)])
    curve = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
    interior = np.ones(n)
    interior[b] = 0.0
    return (sp.diags(interior) @ lap + curve).tocsr()
