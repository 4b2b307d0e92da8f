"""What real scans bring, made harmless for the geometry of a correspondence (issue 14).

Scans and game meshes split vertices along UV seams (two vertices at one position, so the
surface is cut open there), mix face orientations, and carry small floating islands (a stray
eyelash card, a scanning artefact). The correspondence works on a *repaired copy* of each mesh
and maps its results back, so the user's vertex order, faces and UVs are kept:

* :func:`weld` — vertices at one position (to ``1e-9`` of the bounding-box diagonal) become
  one, so the Laplacian sees one connected surface across seams;
* :func:`consistent_winding` — faces flipped so that neighbours agree (trimesh's
  ``fix_winding``), since normals steer the closest-point search;
* :func:`landmark_pieces` — connected pieces holding no landmark (a scan's stray fragments, a
  rig's eyeballs, teeth and lashes) are left out of the fit: with no reference point their
  fairing energy has a null space (the solve fails, "matrix is not positive definite"), and on
  the target they stretch the frame and attract nothing. Left-out source vertices ride along
  with the nearest fitted vertex.

Measured on a synthetic face (``tests/test_corr_broken_meshes.py``): with one
face in seven split off as along a seam, the fit's valid fraction fell from 0.93 to 0.56 and
the Hausdorff distance rose from 1.1 % to 8.4 % of the diagonal; with half the faces flipped,
to 0.38 and 4.8 %; a 1-triangle island 20 diagonals away made every vertex invalid. Repaired,
each is as the clean mesh. The ICT Face Model's full mesh (eyeballs, teeth, lashes) and the
james scan (9 small islands) as sources stopped the fairing before the pieces were left out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import trimesh

from stimulus_engine.geometry.mesh_ops import argsort_keys, face_normals

__all__ = ["RepairedMesh", "repair_mesh", "weld", "consistent_winding", "landmark_pieces"]


@dataclass
class RepairedMesh:
    """A repaired copy of a mesh and the maps back to the original.

    Attributes
    ----------
    vertices : (M, 3) array
        Welded vertices of the kept faces.
    faces : (G, 3) int array
        Kept faces in repaired vertex indices, consistently wound.
    vertex_map : (N,) int array
        Original vertex -> repaired vertex, -1 for a vertex of no kept face.
    face_ids : (G,) int array
        Repaired face -> original face.
    flipped : (G,) bool array
        Repaired faces whose corner order is the reverse of the original's.
    n_faces : int
        Faces of the original.
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_map: np.ndarray
    face_ids: np.ndarray
    flipped: np.ndarray
    n_faces: int

    @property
    def changed(self) -> bool:
        """False when the repair is the identity (nothing welded, flipped or dropped)."""
        return not (np.array_equal(self.vertex_map, np.arange(len(self.vertex_map)))
                    and np.array_equal(self.face_ids, np.arange(self.n_faces)) and not self.flipped.any())

    @property
    def left_out(self) -> np.ndarray:
        """Original vertices on no kept face."""
        return np.flatnonzero(self.vertex_map < 0)

    def original_bary(self, face: np.ndarray, bary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points on repaired faces (face, barycentric) as points on the original faces."""
        bary = np.where(self.flipped[face][:, None], bary[:, ::-1], bary)
        return self.face_ids[face], bary


def weld(vertices: np.ndarray, rtol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices closer than ``rtol`` x the bounding-box diagonal (on a grid of that size).

    Returns
    -------
    welded : (M, 3) array
        The first original of each merged group, in order of first appearance.
    vertex_map : (N,) int array
        Original vertex -> row of ``welded``.
    """
    v = np.asarray(vertices, dtype=np.float64)
    step = max(float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))) * rtol, np.finfo(float).tiny)
    keys = np.round((v - v.min(axis=0)) / step).astype(np.int64)
    # equal keys are neighbours in lexicographic order (a third of np.unique(axis=0)'s time)
    order = np.lexsort(keys.T[::-1])
    ks = keys[order]
    new = np.ones(len(v), dtype=bool)
    new[1:] = (ks[1:] != ks[:-1]).any(axis=1)
    if new.all():
        return v.copy(), np.arange(len(v))
    starts = np.flatnonzero(new)
    first = np.minimum.reduceat(order, starts)  # each group's first original vertex
    inverse = np.empty(len(v), dtype=np.int64)
    inverse[order] = np.cumsum(new) - 1
    by_appearance = np.argsort(first)  # keep the original order of first appearance
    rank = np.empty_like(by_appearance)
    rank[by_appearance] = np.arange(len(by_appearance))
    return v[first[by_appearance]], rank[inverse]


def _face_components(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Connected piece of each face (pieces joined by a shared vertex count as one)."""
    from scipy.sparse.csgraph import connected_components

    # each triangle's edges once, one way: connected_components(directed=False) reads the
    # graph as undirected (no symmetrised adjacency to build)
    f = np.asarray(faces, dtype=np.int64)
    rows, cols = f.ravel(), f[:, [1, 2, 0]].ravel()
    graph = sp.csr_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(n_vertices, n_vertices))
    _, labels = connected_components(graph, directed=False)
    return labels[f[:, 0]]


def _wound_consistently(faces: np.ndarray) -> bool:
    """True when no directed edge occurs twice (neighbours traverse their shared edge oppositely)."""
    a, b = faces.ravel(), faces[:, [1, 2, 0]].ravel()
    key = a * (int(faces.max()) + 1) + b
    key = key[argsort_keys(key)]
    return not (key[1:] == key[:-1]).any()


def consistent_winding(vertices: np.ndarray, faces: np.ndarray, labels: np.ndarray | None = None) -> np.ndarray:
    """Faces wound consistently within each connected piece (trimesh's ``fix_winding``, run
    only when some neighbours disagree), each piece facing outwards:
    ``Σ area · n · (centroid_f − centroid)`` > 0, the sign of the volume for a closed piece
    and of the bulge for an open face mask (``fix_winding`` follows whichever face it starts
    from, which may be a flipped one). ``labels``: the connected piece of each face, if known."""
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        return faces.copy()
    if _wound_consistently(faces):
        wound = faces.copy()
    else:
        mesh = trimesh.Trimesh(vertices, faces, process=False, validate=False)
        trimesh.repair.fix_winding(mesh)
        wound = np.asarray(mesh.faces, dtype=np.int64)
    v = np.asarray(vertices, dtype=np.float64)
    centre = (v[wound[:, 0]] + v[wound[:, 1]] + v[wound[:, 2]]) / 3.0
    normal, area = face_normals(v, wound)
    normal_area = normal * area[:, None]
    labels = _face_components(wound, len(vertices)) if labels is None else labels
    n = np.bincount(labels)
    mid = np.stack([np.bincount(labels, weights=centre[:, k]) / np.maximum(n, 1) for k in range(3)], axis=1)
    bulge = np.bincount(labels, weights=np.einsum("ij,ij->i", normal_area, centre - mid[labels]))
    inward = (bulge < 0)[labels]
    wound[inward] = wound[inward][:, ::-1]
    return wound


def landmark_pieces(vertices: np.ndarray, faces: np.ndarray, keep_vertices: np.ndarray,
                    labels: np.ndarray | None = None) -> np.ndarray:
    """Mask of faces in connected pieces that hold one of ``keep_vertices`` (landmarks);
    ``labels``: the connected piece of each face, if known."""
    faces = np.asarray(faces, dtype=np.int64)
    labels = _face_components(faces, len(vertices)) if labels is None else labels
    held = np.isin(faces, np.asarray(keep_vertices, dtype=np.int64)).any(axis=1)
    keep = np.zeros(labels.max() + 1 if len(labels) else 0, dtype=bool)
    keep[np.unique(labels[held])] = True
    return keep[labels]


def repair_mesh(vertices: np.ndarray, faces: np.ndarray, keep_vertices: np.ndarray | None = None) -> RepairedMesh:
    """Weld, drop collapsed faces (and pieces without landmarks), wind consistently.

    Parameters
    ----------
    vertices : (N, 3) array
    faces : (F, 3) int array
    keep_vertices : array of int, optional
        Original vertices of the landmarks: pieces holding none are left out. None keeps all.
    """
    welded, vmap = weld(vertices)
    f = vmap[np.asarray(faces, dtype=np.int64)]
    proper = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    ok = proper.copy()
    # the pieces, once for both steps (dropping a collapsed face could split one: then again)
    labels = _face_components(f, len(welded))
    if keep_vertices is not None:
        ok &= landmark_pieces(welded, f, vmap[np.asarray(keep_vertices, dtype=np.int64)], labels)
    face_ids = np.flatnonzero(ok)
    used = np.flatnonzero(np.bincount(f[face_ids].ravel(), minlength=len(welded)))
    compact = np.full(len(welded), -1, dtype=np.int64)
    compact[used] = np.arange(len(used))
    kept = compact[f[face_ids]]
    wound = consistent_winding(welded[used], kept, labels[face_ids] if proper.all() else None)
    # fix_winding reverses a face's corners or leaves them; anything else would be a bug
    flipped = ~(wound == kept).all(axis=1)
    assert np.array_equal(wound[flipped], kept[flipped][:, ::-1])
    return RepairedMesh(welded[used], wound, compact[vmap], face_ids, flipped, len(faces))
