"""Quality of a correspondence: surface distances, fold-overs and degenerate triangles."""

from __future__ import annotations

import hashlib

import numpy as np

from stimulus_engine.geometry.closest import SurfaceIndex
from stimulus_engine.geometry.mesh_ops import face_normals

__all__ = ["FoldCheck", "surface_distances", "flipped_triangles", "against_target_triangles", "degenerate_triangles", "fit_metrics"]


def surface_distances(
    points: np.ndarray, target_vertices: np.ndarray, target_faces: np.ndarray, index: SurfaceIndex | None = None
) -> np.ndarray:
    """Distance of each point to the target surface (exact point-triangle distance)."""
    index = index if index is not None else SurfaceIndex(target_vertices, target_faces)
    return index.distance(points)


def _local_folds(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Triangles facing against the mean of their three (area-weighted) vertex normals.

    :func:`~stimulus_engine.geometry.mesh_ops.vertex_normals` with the triangles' cross products
    computed once (for the sign, a triangle's unnormalised cross product does as well as its
    unit normal), coordinate by coordinate."""
    faces = np.asarray(faces)
    nv = len(vertices)
    p = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).T)[:, faces.T]  # (xyz, corner, F)
    a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    cross = np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
    vn = np.stack([np.bincount(faces.ravel(), weights=np.repeat(c, 3), minlength=nv) for c in cross])
    vn /= np.maximum(np.sqrt(np.einsum("cv,cv->v", vn, vn)), 1e-300)
    corner_sum = vn[:, faces[:, 0]] + vn[:, faces[:, 1]] + vn[:, faces[:, 2]]
    return np.einsum("cf,cf->f", cross, corner_sum) < 0


def flipped_triangles(vertices: np.ndarray, faces: np.ndarray, reference_vertices: np.ndarray) -> np.ndarray:
    """Fold-overs created by the deformation: triangles that face against their neighbourhood
    (the mean of their vertex normals) in ``vertices`` but did not in ``reference_vertices``
    (the undeformed source). Boolean mask (F,).

    Comparing with the source itself would count regions that legitimately turn round (a
    model's inner lips laid onto a scan's closed mouth); this counts only folds.
    """
    return _local_folds(vertices, faces) & ~_local_folds(reference_vertices, faces)


class FoldCheck:
    """Fold-overs and collapsed triangles of deformations of one mesh, with the undeformed
    mesh's own folds and areas computed once (a deformation is checked many times while it
    is repaired, and again when it is measured).

    Parameters
    ----------
    faces : (F, 3) int array
    reference : (N, 3) array
        The undeformed vertices.
    rel : float
        See :func:`degenerate_triangles`.
    """

    def __init__(self, faces: np.ndarray, reference: np.ndarray, rel: float = 1e-4) -> None:
        self.faces = np.asarray(faces, dtype=np.int64)
        self.reference = np.asarray(reference, dtype=np.float64)
        self.rel = rel
        self._folds = _local_folds(self.reference, self.faces)
        self._area = face_normals(self.reference, self.faces)[1]
        self._collapsed = _shrunk(self._area, self._area, rel)  # already degenerate in the reference
        self._last: tuple = (None, None, None, None)  # (digest, local folds, normals, areas)

    def _of(self, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Local folds, face normals and areas of ``vertices``, kept for the same positions
        (the repair's last check and the metrics look at the same final vertices)."""
        v = np.ascontiguousarray(vertices, dtype=np.float64)
        digest = hashlib.blake2b(v.data, digest_size=16).digest()
        if digest != self._last[0]:
            self._last = (digest, _local_folds(v, self.faces), *face_normals(v, self.faces))
        return self._last[1:]

    def flipped(self, vertices: np.ndarray) -> np.ndarray:
        """:func:`flipped_triangles` against the reference."""
        return self._of(vertices)[0] & ~self._folds

    def degenerate(self, vertices: np.ndarray) -> np.ndarray:
        """:func:`degenerate_triangles` against the reference."""
        return _shrunk(self._of(vertices)[2], self._area, self.rel)

    def normals(self, vertices: np.ndarray) -> np.ndarray:
        """Unit face normals of ``vertices``."""
        return self._of(vertices)[1]

    def bad(self, vertices: np.ndarray) -> np.ndarray:
        """Folded, or collapsed where the reference was not."""
        return self.flipped(vertices) | (self.degenerate(vertices) & ~self._collapsed)


def against_target_triangles(
    vertices: np.ndarray,
    faces: np.ndarray,
    target_vertices: np.ndarray,
    target_faces: np.ndarray,
    index: SurfaceIndex | None = None,
    vertex_faces_hint: np.ndarray | None = None,
    normals: np.ndarray | None = None,
) -> np.ndarray:
    """Triangles whose normal points against the target's normal at the closest point of their
    centroid (sensitive to scan noise; reported beside :func:`flipped_triangles`).
    ``vertex_faces_hint``: each vertex's closest target triangle, if known (the search for a
    centroid starts at its first corner's); ``normals``: the triangles' unit normals, if known."""
    n = face_normals(vertices, faces)[0] if normals is None else normals
    index = index if index is not None else SurfaceIndex(target_vertices, target_faces)
    hint = None if vertex_faces_hint is None else vertex_faces_hint[np.asarray(faces)[:, 0]]
    cp = index.query(vertices[faces].mean(axis=1), hint=hint)
    return np.einsum("ij,ij->i", n, cp.normals) < 0


def degenerate_triangles(vertices: np.ndarray, faces: np.ndarray, reference_vertices: np.ndarray, rel: float = 1e-4) -> np.ndarray:
    """Triangles whose area shrank below ``rel`` times their area in ``reference_vertices``
    (or whose area is zero). Returns a boolean mask (F,)."""
    return _shrunk(face_normals(vertices, faces)[1], face_normals(reference_vertices, faces)[1], rel)


def _shrunk(area: np.ndarray, reference_area: np.ndarray, rel: float) -> np.ndarray:
    """Triangles whose ``area`` is below ``rel`` times their reference area, or zero."""
    return (area <= rel * np.maximum(reference_area, 1e-300)) | (area <= 1e-300)


def fit_metrics(
    vertices: np.ndarray,
    faces: np.ndarray,
    target_vertices: np.ndarray,
    target_faces: np.ndarray,
    reference_vertices: np.ndarray,
    target_index: SurfaceIndex | None = None,
    folds: FoldCheck | None = None,
) -> dict:
    """Distances relative to the target's bounding-box diagonal, both ways, and fold-overs.

    ``hausdorff_rel``/``mean_dist_rel``/``median_dist_rel`` measure the deformed source
    against the target surface (how well the source was fitted, as in thesis Table 3.1);
    ``hausdorff_sym_rel`` also includes target vertices against the deformed source (it is
    large when the target covers more than the source, e.g. a scan's neck).
    ``target_index``: a :class:`SurfaceIndex` of the target already built (saves building it);
    ``folds``: a :class:`FoldCheck` of ``faces`` and ``reference_vertices`` already made.
    """
    diag = float(np.linalg.norm(np.ptp(target_vertices, axis=0)))
    index = target_index if target_index is not None else SurfaceIndex(target_vertices, target_faces)
    closest = index.query(vertices)
    d_st = closest.distance
    d_ts = surface_distances(target_vertices, vertices, faces)
    folds = folds if folds is not None else FoldCheck(faces, reference_vertices)
    flipped = folds.flipped(vertices)
    against = against_target_triangles(vertices, faces, target_vertices, target_faces, index, closest.face,
                                       folds.normals(vertices))
    degenerate = folds.degenerate(vertices)
    return {
        "hausdorff_rel": float(d_st.max() / diag),
        "mean_dist_rel": float(d_st.mean() / diag),
        "median_dist_rel": float(np.median(d_st) / diag),
        "p99_dist_rel": float(np.percentile(d_st, 99) / diag),
        "hausdorff_sym_rel": float(max(d_st.max(), d_ts.max()) / diag),
        "flipped_triangles": int(flipped.sum()),
        "against_target_triangles": int(against.sum()),
        "degenerate_triangles": int(degenerate.sum()),
        "n_source_vertices": int(len(vertices)),
        "n_target_vertices": int(len(target_vertices)),
        "target_bbox_diagonal": diag,
    }
