"""Correspondence constraints (§3.2.1): surface reference points and how users give them.

A reference point is a barycentric combination of one triangle's vertices (eq. 3.1). A plain
vertex is the combination ``(i, i, i)`` with weights ``(1, 0, 0)``. :class:`SurfacePoints` holds
M such points and turns them into the sparse M x N matrix ``C`` with ``C @ V`` = their positions,
which is how the fairing and registration energies use them.

Users give points as JSON entries (``appeal stimuli correspond --landmarks``): a vertex index,
a 3D point ``[x, y, z]`` that is snapped to the closest surface point (it must lie within
``snap_tolerance`` of the bounding-box diagonal), or ``{"face": f, "bary": [a, b, c]}``.
Correspondences along boundary loops and rims are made in
:mod:`stimulus_engine.correspondence.boundary`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from appeal.errors import AppealInputError
from stimulus_engine.geometry.closest import SurfaceIndex

__all__ = ["SurfacePoints", "Correspondences", "parse_points", "parse_pairs", "load_pairs_file", "check_spread", "closest_surface_points"]


@dataclass
class SurfacePoints:
    """M points on a mesh: ``vertices`` (M, 3) int and barycentric ``weights`` (M, 3)."""

    vertices: np.ndarray
    weights: np.ndarray

    def __post_init__(self) -> None:
        self.vertices = np.asarray(self.vertices, dtype=np.int64).reshape(-1, 3)
        self.weights = np.asarray(self.weights, dtype=np.float64).reshape(-1, 3)

    def __len__(self) -> int:
        return len(self.vertices)

    @classmethod
    def from_vertices(cls, ids) -> "SurfacePoints":
        """Points at vertices ``ids``."""
        ids = np.asarray(ids, dtype=np.int64).ravel()
        w = np.zeros((len(ids), 3))
        w[:, 0] = 1.0
        return cls(np.repeat(ids[:, None], 3, axis=1), w)

    @classmethod
    def from_faces(cls, faces: np.ndarray, face_ids, bary) -> "SurfacePoints":
        """Points inside triangles ``face_ids`` of ``faces`` with barycentric ``bary``."""
        return cls(np.asarray(faces)[np.asarray(face_ids, dtype=np.int64)], bary)

    def positions(self, vertices: np.ndarray) -> np.ndarray:
        """3D positions (M, 3) on a mesh with these vertex positions."""
        return np.einsum("mk,mkd->md", self.weights, np.asarray(vertices)[self.vertices])

    def matrix(self, n_vertices: int) -> sp.csr_matrix:
        """Sparse (M, n_vertices) matrix ``C`` with ``C @ V == positions(V)``."""
        m = len(self)
        rows = np.repeat(np.arange(m), 3)
        return sp.csr_matrix(
            (self.weights.ravel(), (rows, self.vertices.ravel())), shape=(m, n_vertices)
        )

    def concat(self, other: "SurfacePoints") -> "SurfacePoints":
        """Both point sets, this one first."""
        return SurfacePoints(
            np.concatenate([self.vertices, other.vertices]), np.concatenate([self.weights, other.weights])
        )

    def subset(self, idx) -> "SurfacePoints":
        """The points ``idx``."""
        return SurfacePoints(self.vertices[idx], self.weights[idx])


@dataclass
class Correspondences:
    """Paired reference points ``(r_m^s, r_m^t)`` on the source and the target mesh."""

    source: SurfacePoints
    target: SurfacePoints

    def __post_init__(self) -> None:
        if len(self.source) != len(self.target):
            raise AppealInputError(
                f"landmarks: source and target need the same number of points "
                f"(got {len(self.source)} and {len(self.target)})"
            )

    def __len__(self) -> int:
        return len(self.source)

    def concat(self, other: "Correspondences") -> "Correspondences":
        return Correspondences(self.source.concat(other.source), self.target.concat(other.target))


def closest_surface_points(mesh, points: np.ndarray) -> tuple[SurfacePoints, np.ndarray]:
    """The closest points of ``mesh``'s surface to ``points`` (M, 3), and their distances."""
    cp = SurfaceIndex(mesh.vertices, mesh.faces).query(np.asarray(points, dtype=np.float64))
    return SurfacePoints.from_faces(mesh.faces, cp.face, cp.bary), cp.distance


def _snap(mesh, points: np.ndarray, where: str, tolerance: float) -> SurfacePoints:
    snapped, distance = closest_surface_points(mesh, points)
    diag = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    far = distance > tolerance * diag
    if far.any():
        k = int(np.flatnonzero(far)[0])
        raise AppealInputError(
            f"{where}[{k}]: point {np.round(points[k], 4).tolist()} is off the surface "
            f"({distance[k]:.4g} away; expected within {tolerance:.1%} of the bounding-box "
            f"diagonal {diag:.4g})"
        )
    return snapped


def parse_points(entries, mesh, where: str = "landmarks", snap_tolerance: float = 0.02) -> SurfacePoints:
    """Turn user entries into surface points on ``mesh``.

    Parameters
    ----------
    entries : list
        Each a vertex index (int), a 3D point ``[x, y, z]`` (snapped to the surface), or
        ``{"face": f, "bary": [a, b, c]}``. A numeric (M, 3) array is read as M 3D points.
    mesh : trimesh.Trimesh
    where : str
        Name used in error messages (e.g. ``"pairs.json: source"``).
    snap_tolerance : float
        Largest allowed distance of a 3D point from the surface, relative to the bbox diagonal.
    """
    n = len(mesh.vertices)
    nf = len(mesh.faces)
    if isinstance(entries, np.ndarray) and entries.ndim == 2 and entries.shape[1] == 3 and entries.dtype.kind == "f":
        return _snap(mesh, entries, where, snap_tolerance)
    if not isinstance(entries, (list, tuple, np.ndarray)) or len(entries) == 0:
        raise AppealInputError(f"{where}: expected a non-empty list of points (got {type(entries).__name__})")
    verts = np.zeros((len(entries), 3), dtype=np.int64)
    weights = np.zeros((len(entries), 3))
    snap_idx, snap_pts = [], []
    for k, e in enumerate(entries):
        here = f"{where}[{k}]"
        if isinstance(e, (bool, np.bool_)):
            raise AppealInputError(f"{here}: expected a vertex index, [x, y, z] or {{face, bary}} (got {e!r})")
        if isinstance(e, (int, np.integer)):
            if not 0 <= int(e) < n:
                raise AppealInputError(f"{here}: vertex index {int(e)} is out of range (mesh has {n} vertices)")
            verts[k] = int(e)
            weights[k, 0] = 1.0
        elif isinstance(e, dict):
            if set(e) != {"face", "bary"}:
                raise AppealInputError(f"{here}: expected keys 'face' and 'bary' (got {sorted(e)})")
            f = e["face"]
            b = np.asarray(e["bary"], dtype=np.float64) if isinstance(e["bary"], (list, tuple)) else None
            if not isinstance(f, int) or not 0 <= f < nf:
                raise AppealInputError(f"{here}: face: expected a triangle index in [0, {nf}) (got {f!r})")
            if b is None or b.shape != (3,) or (b < -1e-9).any() or abs(b.sum() - 1) > 1e-6:
                raise AppealInputError(
                    f"{here}: bary: expected 3 non-negative weights summing to 1 (got {e['bary']!r})"
                )
            verts[k] = mesh.faces[f]
            weights[k] = b
        elif isinstance(e, (list, tuple, np.ndarray)) and len(e) == 3 and all(
            isinstance(x, (int, float, np.floating, np.integer)) and not isinstance(x, bool) for x in e
        ):
            if not all(np.isfinite(float(x)) for x in e):
                raise AppealInputError(f"{here}: expected finite coordinates [x, y, z] (got {list(e)!r})")
            snap_idx.append(k)
            snap_pts.append([float(x) for x in e])
        else:
            raise AppealInputError(
                f"{here}: expected a vertex index, [x, y, z] or {{\"face\": f, \"bary\": [a, b, c]}} (got {e!r})"
            )
    if snap_idx:
        sp_ = _snap(mesh, np.asarray(snap_pts), where, snap_tolerance)
        verts[snap_idx] = sp_.vertices
        weights[snap_idx] = sp_.weights
    return SurfacePoints(verts, weights)


def parse_pairs(data, source_mesh, target_mesh, where: str = "landmarks") -> Correspondences:
    """``{"source": [...], "target": [...]}`` -> :class:`Correspondences` (see :func:`parse_points`)."""
    if not isinstance(data, dict) or set(data) - {"source", "target"} or not {"source", "target"} <= set(data):
        got = sorted(data) if isinstance(data, dict) else type(data).__name__
        raise AppealInputError(f"{where}: expected an object with keys 'source' and 'target' (got {got})")
    s, t = data["source"], data["target"]
    if isinstance(s, list) and isinstance(t, list) and len(s) != len(t):
        raise AppealInputError(
            f"{where}: source and target need the same number of points (got {len(s)} and {len(t)})"
        )
    src = parse_points(s, source_mesh, f"{where}: source")
    tgt = parse_points(t, target_mesh, f"{where}: target")
    for side, pts, mesh in (("source", src, source_mesh), ("target", tgt, target_mesh)):
        v = np.asarray(mesh.vertices, dtype=np.float64)
        check_spread(pts.positions(v), f"{where}: {side}", float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))))
    return Correspondences(src, tgt)


def check_spread(points: np.ndarray, where: str, scale: float, rtol: float = 1e-6) -> None:
    """Raise unless ``points`` span a triangle (the alignment needs 3 points not on one line).

    Parameters
    ----------
    points : (M, 3) array
    where : str
        Names the points in the message.
    scale : float
        The mesh's size (bounding-box diagonal).
    rtol : float
        Spread below ``rtol * scale`` counts as one point; a second singular value of the
        centred points below ``rtol`` times the first counts as one line.
    """
    if len(points) < 3:
        return  # too few: the caller's count check says so
    sv = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    if sv[0] <= rtol * scale or sv[1] <= rtol * sv[0]:
        what = "all at one point" if sv[0] <= rtol * scale else "on one line"
        raise AppealInputError(f"{where}: the {len(points)} points are {what}; expected at least 3 points spanning a triangle")


def load_pairs_file(path, source_mesh, target_mesh) -> Correspondences:
    """Read a pairs JSON file (see :func:`parse_pairs`)."""
    from stimulus_engine.geometry.mesh_io import read_json

    return parse_pairs(read_json(path, "landmark pairs file"), source_mesh, target_mesh, where=str(path))
