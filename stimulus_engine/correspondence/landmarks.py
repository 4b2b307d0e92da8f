"""Correspondence constraints (§3.2.1): surface reference points and how users give them.

A reference point is a barycentric combination of one triangle's vertices (eq. 3.1). A plain
vertex is the combination ``(i, i, i)`` with weights ``(1, 0, 0)``. :class:`SurfacePoints` holds
M such points and turns them into the sparse M x N matrix ``C`` with ``C @ V`` = their positions,
which is how the fairing and registration energies use them.

Users give points as JSON entries (``appeal stimuli correspond --landmarks``): a vertex index,
a 3D point ``[x, y, z]`` that is snapped to the closest surface point (it must lie within
``snap_tolerance`` of the bounding-box diagonal), or ``{"face": f, "bary": [a, b, c]}``.

Boundary loops (Fig. 3.5): from one or more corresponding points on a source and a target
boundary loop, every other source loop vertex gets the target loop point at the same relative
arc length (piecewise between consecutive anchors), a point on a target boundary edge.
Where the target has no hole (a scan's closed lips and eyelids against a model's mouth and eye
openings), :func:`rim_to_curve_correspondences` maps a source boundary loop the same way onto
a closed curve drawn on the target surface through given points (e.g. the lip or eyelid
landmarks), :func:`surface_polyline`.

68-point landmark sets come in different orders; :func:`reorder_landmarks` converts between
them using the table in ``stimulus_engine/data/landmark_orderings.json``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from appeal.errors import AppealInputError

__all__ = [
    "SurfacePoints",
    "Correspondences",
    "parse_points",
    "parse_pairs",
    "load_pairs_file",
    "boundary_loops",
    "boundary_correspondences",
    "rim_to_curve_correspondences",
    "surface_polyline",
    "nearest_boundary_vertices",
    "landmark_orderings",
    "reorder_landmarks",
    "read_ljson",
    "LANDMARK_SUBSET_16",
]

_ORDERINGS = Path(__file__).resolve().parent.parent / "data" / "landmark_orderings.json"


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


def _snap(mesh, points: np.ndarray, where: str, tolerance: float) -> SurfacePoints:
    from stimulus_engine.correspondence.closest import SurfaceIndex

    cp = SurfaceIndex(mesh.vertices, mesh.faces).query(points)
    diag = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    far = cp.distance > tolerance * diag
    if far.any():
        k = int(np.flatnonzero(far)[0])
        raise AppealInputError(
            f"{where}[{k}]: point {np.round(points[k], 4).tolist()} is off the surface "
            f"({cp.distance[k]:.4g} away; expected within {tolerance:.1%} of the bounding-box "
            f"diagonal {diag:.4g})"
        )
    return SurfacePoints.from_faces(mesh.faces, cp.face, cp.bary)


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
    return Correspondences(src, tgt)


def load_pairs_file(path, source_mesh, target_mesh) -> Correspondences:
    """Read a pairs JSON file (see :func:`parse_pairs`)."""
    from stimulus_engine.mesh_io import read_json

    return parse_pairs(read_json(path, "landmark pairs file"), source_mesh, target_mesh, where=str(path))


# --------------------------------------------------------------------------------------------
# Boundary loops
# --------------------------------------------------------------------------------------------


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Boundary loops as ordered vertex arrays, oriented like the faces' half-edges.

    Both meshes of a consistently oriented pair (normals pointing out of the face) then
    traverse corresponding loops in the same direction.
    """
    faces = np.asarray(faces, dtype=np.int64)
    he = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    key = he[:, 0] * (faces.max() + 1) + he[:, 1]
    rev = he[:, 1] * (faces.max() + 1) + he[:, 0]
    border = he[~np.isin(key, rev)]
    nxt: dict[int, int] = {}
    for a, b in border:
        nxt.setdefault(int(a), int(b))
    loops, seen = [], set()
    for start in sorted(nxt):
        if start in seen:
            continue
        loop = [start]
        seen.add(start)
        cur = nxt[start]
        while cur != start and cur in nxt and cur not in seen:
            loop.append(cur)
            seen.add(cur)
            cur = nxt[cur]
        if cur == start and len(loop) >= 3:
            loops.append(np.asarray(loop, dtype=np.int64))
    loops.sort(key=len, reverse=True)
    return loops


def _loop_params(vertices: np.ndarray, loop: np.ndarray) -> tuple[np.ndarray, float]:
    """Cumulative arc length at each loop vertex (starting at 0) and the loop length."""
    p = vertices[loop]
    seg = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)[:-1]]), float(seg.sum())


def _point_on_loop(vertices, loop, params, total, at: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and weights of the loop point at arc length ``at`` (mod total)."""
    at = at % total
    k = int(np.searchsorted(params, at, side="right") - 1)
    a, b = loop[k], loop[(k + 1) % len(loop)]
    seg = (params[k + 1] if k + 1 < len(params) else total) - params[k]
    t = 0.0 if seg <= 0 else (at - params[k]) / seg
    return np.array([a, b, b]), np.array([1 - t, t, 0.0])


def boundary_correspondences(
    source_vertices: np.ndarray,
    source_faces: np.ndarray,
    target_vertices: np.ndarray,
    target_faces: np.ndarray,
    anchors: list[tuple[int, int]],
) -> Correspondences:
    """Fill boundary-loop correspondences from anchor vertex pairs (Fig. 3.5).

    Parameters
    ----------
    anchors : list of (source_vertex, target_vertex)
        Pairs of boundary vertices; anchors on the same source loop must lie on one target
        loop. Between consecutive anchors, source loop vertices are placed on the target loop
        at the same fraction of the arc length between the anchors.

    Returns
    -------
    Correspondences
        One pair per source loop vertex of every anchored loop (anchors included).
    """
    s_loops = boundary_loops(source_faces)
    t_loops = boundary_loops(target_faces)
    s_of = {int(v): i for i, lp in enumerate(s_loops) for v in lp}
    t_of = {int(v): i for i, lp in enumerate(t_loops) for v in lp}
    by_loop: dict[int, list[tuple[int, int]]] = {}
    for k, (a, b) in enumerate(anchors):
        if int(a) not in s_of:
            raise AppealInputError(f"boundary anchors[{k}]: source vertex {a} is not on a boundary loop")
        if int(b) not in t_of:
            raise AppealInputError(f"boundary anchors[{k}]: target vertex {b} is not on a boundary loop")
        by_loop.setdefault(s_of[int(a)], []).append((int(a), int(b)))
    sv, sw, tv, tw = [], [], [], []
    for li, pairs in by_loop.items():
        s_loop = s_loops[li]
        t_idx = {t_of[b] for _, b in pairs}
        if len(t_idx) != 1:
            raise AppealInputError(
                f"boundary anchors: anchors on one source loop lie on {len(t_idx)} different target loops"
            )
        t_loop = t_loops[t_idx.pop()]
        s_par, s_tot = _loop_params(source_vertices, s_loop)
        t_par, t_tot = _loop_params(target_vertices, t_loop)
        s_pos = {int(v): i for i, v in enumerate(s_loop)}
        t_pos = {int(v): i for i, v in enumerate(t_loop)}
        # anchors sorted along the source loop
        pairs = sorted(pairs, key=lambda p: s_par[s_pos[p[0]]])
        sa = np.array([s_par[s_pos[a]] for a, _ in pairs])
        ta = np.array([t_par[t_pos[b]] for _, b in pairs])
        # unwrap the target anchor parameters so that they increase along the loop
        ta_u = ta.copy()
        for k in range(1, len(ta_u)):
            while ta_u[k] <= ta_u[k - 1]:
                ta_u[k] += t_tot
        sa_ext = np.concatenate([sa, [sa[0] + s_tot]])
        ta_ext = np.concatenate([ta_u, [ta_u[0] + t_tot]])
        for i, v in enumerate(s_loop):
            s = s_par[i]
            s_rel = s if s >= sa[0] else s + s_tot
            k = int(np.searchsorted(sa_ext, s_rel, side="right") - 1)
            k = min(k, len(sa_ext) - 2)
            frac = (s_rel - sa_ext[k]) / (sa_ext[k + 1] - sa_ext[k])
            at = ta_ext[k] + frac * (ta_ext[k + 1] - ta_ext[k])
            vv, ww = _point_on_loop(target_vertices, t_loop, t_par, t_tot, at)
            sv.append([v, v, v])
            sw.append([1.0, 0.0, 0.0])
            tv.append(vv)
            tw.append(ww)
    if not sv:
        raise AppealInputError("boundary anchors: expected at least one (source, target) vertex pair")
    return Correspondences(SurfacePoints(sv, sw), SurfacePoints(tv, tw))


def _catmull_rom(p: np.ndarray, t: np.ndarray, closed: bool, corners) -> np.ndarray:
    """Samples (len(segments), len(t), 3) of the uniform Catmull-Rom spline through ``p``; at
    ``corners`` (and the ends of an open curve) the tangent is one-sided (a cusp)."""
    n = len(p)
    sharp = np.zeros(n, dtype=bool)
    sharp[list(corners)] = True
    if not closed:
        sharp[[0, -1]] = True
    i = np.arange(n if closed else n - 1)
    p1, p2 = p[i], p[(i + 1) % n]
    p0 = np.where(sharp[i][:, None], p1, p[(i - 1) % n])
    p3 = np.where(sharp[(i + 1) % n][:, None], p2, p[(i + 2) % n])
    t = t[None, :, None]
    return 0.5 * (2 * p1[:, None] + (p2 - p0)[:, None] * t + (2 * p0 - 5 * p1 + 4 * p2 - p3)[:, None] * t**2
                  + (3 * p1 - p0 - 3 * p2 + p3)[:, None] * t**3)


def surface_polyline(
    vertices: np.ndarray, faces: np.ndarray, points: np.ndarray, samples: int = 8, closed: bool = True,
    index=None, smooth: bool = False, corners=(),
) -> tuple[np.ndarray, np.ndarray]:
    """A curve on the surface through ``points``: each chord (or, with ``smooth``, each piece
    of a Catmull-Rom spline through the points) split into ``samples`` pieces and every sample
    snapped to the closest surface point.

    Parameters
    ----------
    vertices, faces : arrays
        The surface.
    points : (P, 3) array
        The knots, in order (they are snapped too).
    samples : int
        Pieces per chord (>= 1).
    closed : bool
        Also join the last knot to the first.
    index : SurfaceIndex, optional
        A prebuilt closest-point index of the surface.
    smooth : bool
        A uniform Catmull-Rom spline through the points instead of straight chords.
    corners : sequence of int
        With ``smooth``: points where the curve keeps a corner (eye and mouth corners).

    Returns
    -------
    curve : (P * samples (+1 if open), 3) array
        Snapped sample positions; knot ``k`` is ``curve[k * samples]``.
    arc : same length
        Cumulative arc length along the snapped samples (0 at knot 0); for a closed curve
        the total length is ``arc[-1] + |curve[0] - curve[-1]|``.
    """
    from stimulus_engine.correspondence.closest import SurfaceIndex

    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) < 2:
        raise AppealInputError(f"curve: expected at least 2 points (got {len(p)})")
    if samples < 1:
        raise AppealInputError(f"curve: samples: expected an integer >= 1 (got {samples})")
    t = np.arange(samples) / samples
    if smooth:
        dense = _catmull_rom(p, t, closed, corners).reshape(-1, 3)
    else:
        nxt = np.roll(p, -1, axis=0) if closed else p[1:]
        start = p if closed else p[:-1]
        dense = (start[:, None, :] + t[None, :, None] * (nxt - start)[:, None, :]).reshape(-1, 3)
    if not closed:
        dense = np.vstack([dense, p[-1:]])
    idx = index if index is not None else SurfaceIndex(vertices, faces)
    curve = idx.query(dense).points
    seg = np.linalg.norm(np.diff(curve, axis=0), axis=1)
    return curve, np.concatenate([[0.0], np.cumsum(seg)])


def rim_to_curve_correspondences(
    source_vertices: np.ndarray,
    source_faces: np.ndarray,
    target_vertices: np.ndarray,
    target_faces: np.ndarray,
    source_anchors,
    target_points: np.ndarray,
    samples: int = 8,
    step: int = 1,
    index=None,
    smooth: bool = False,
    corners=(),
) -> Correspondences:
    """Map a source boundary loop onto a closed curve on the target surface (Fig. 3.5 for a
    target without the hole).

    The curve runs through ``target_points`` in the given order (closed, snapped to the
    surface: :func:`surface_polyline`). Anchor ``k`` (a source boundary vertex) corresponds
    to ``target_points[k]``; the source loop vertices between consecutive anchors (in the loop
    direction in which the anchors appear in the given order) get the curve point at the same
    fraction of the arc length between the corresponding knots.

    Parameters
    ----------
    source_anchors : sequence of int
        P >= 2 source vertices on one boundary loop, in the curve's order (either direction
        along the loop).
    target_points : (P, 3) array
        The curve's knots on (or within snapping distance of) the target surface.
    samples : int
        Pieces per chord of the snapped curve.
    step : int
        Use every ``step``-th loop vertex (the anchors are always used).
    index : SurfaceIndex, optional
        A prebuilt closest-point index of the target.
    smooth, corners
        The curve's shape between the points (see :func:`surface_polyline`).

    Returns
    -------
    Correspondences
        Source loop vertices -> points on target triangles.
    """
    from stimulus_engine.correspondence.closest import SurfaceIndex

    anchors = [int(a) for a in source_anchors]
    tp = np.asarray(target_points, dtype=np.float64).reshape(-1, 3)
    if len(anchors) != len(tp):
        raise AppealInputError(
            f"rim anchors: expected as many source anchors as curve points (got {len(anchors)} and {len(tp)})"
        )
    if len(anchors) < 2 or len(set(anchors)) != len(anchors):
        raise AppealInputError(f"rim anchors: expected at least 2 distinct source vertices (got {anchors})")
    loops = boundary_loops(source_faces)
    of = {int(v): i for i, lp in enumerate(loops) for v in lp}
    missing = [a for a in anchors if a not in of]
    if missing:
        raise AppealInputError(f"rim anchors: source vertex {missing[0]} is not on a boundary loop")
    if len({of[a] for a in anchors}) != 1:
        raise AppealInputError("rim anchors: expected all source anchors on one boundary loop")
    n = len(loops[of[anchors[0]]])
    # the loop direction in which the anchors appear in the given order
    for loop in (loops[of[anchors[0]]], loops[of[anchors[0]]][::-1]):
        pos = {int(v): i for i, v in enumerate(loop)}
        k = np.array([pos[a] for a in anchors])
        if np.mod(np.diff(np.append(k, k[0])), n).sum() == n:
            break
    else:
        raise AppealInputError("rim anchors: the anchors are not in order along their boundary loop")
    loop = np.roll(loop, -k[0])
    k = np.mod(k - k[0], n)
    s_par, s_tot = _loop_params(np.asarray(source_vertices, dtype=np.float64), loop)
    idx = index if index is not None else SurfaceIndex(target_vertices, target_faces)
    curve, arc = surface_polyline(target_vertices, target_faces, tp, samples, closed=True, index=idx,
                                  smooth=smooth, corners=corners)
    t_tot = arc[-1] + float(np.linalg.norm(curve[0] - curve[-1]))
    knots = np.append(arc[:: samples], t_tot)
    s_knots = np.append(s_par[k], s_tot)
    keep = np.zeros(n, dtype=bool)
    keep[::step] = True
    keep[k] = True
    seg = np.searchsorted(s_knots, s_par, side="right") - 1
    frac = (s_par - s_knots[seg]) / (s_knots[seg + 1] - s_knots[seg])
    at = knots[seg] + frac * (knots[seg + 1] - knots[seg])
    closed_curve = np.vstack([curve, curve[:1]])
    closed_arc = np.append(arc, t_tot)
    where = np.column_stack([np.interp(at, closed_arc, closed_curve[:, d]) for d in range(3)])
    cp = idx.query(where[keep])
    return Correspondences(
        SurfacePoints.from_vertices(loop[keep]),
        SurfacePoints.from_faces(np.asarray(target_faces), cp.face, cp.bary),
    )


# --------------------------------------------------------------------------------------------
# 68-point landmark orderings
# --------------------------------------------------------------------------------------------


@lru_cache(maxsize=1)
def landmark_orderings() -> dict:
    """The table of 68-point orderings (``stimulus_engine/data/landmark_orderings.json``)."""
    return json.loads(_ORDERINGS.read_text())


def _to_ibug(name: str) -> np.ndarray:
    table = landmark_orderings()
    if name not in table or name.startswith("_") or name == "subsets":
        names = [k for k in table if not k.startswith("_") and k != "subsets"]
        raise AppealInputError(f"landmark ordering '{name}' is unknown (expected one of {', '.join(names)})")
    entry = table[name]
    if "same_as" in entry:
        entry = table[entry["same_as"]]
    return np.asarray(entry["to_ibug"], dtype=np.int64)


def reorder_landmarks(points, source: str, target: str = "ibug68"):
    """Re-order a 68-point landmark array from ordering ``source`` to ordering ``target``.

    ``points`` has 68 rows (any trailing shape): row ``k`` is point ``k`` of ``source``.
    """
    pts = np.asarray(points)
    if len(pts) != 68:
        raise AppealInputError(f"landmarks: expected 68 points for ordering '{source}' (got {len(pts)})")
    s2i = _to_ibug(source)
    t2i = _to_ibug(target)
    ibug = np.empty_like(pts)
    ibug[s2i] = pts
    return ibug[t2i]


#: 16 well-spread iBUG indices (jaw, brow ends, nose, eye and mouth corners) used for
#: registration; the other 52 are held out for checking.
LANDMARK_SUBSET_16 = np.asarray(landmark_orderings()["subsets"]["ibug16"]["ibug"], dtype=np.int64)


def read_ljson(path) -> tuple[np.ndarray, str]:
    """3D points of a menpo LJSON landmark file and the ordering name (``menpo_ljson``)."""
    path = Path(path)
    if not path.exists():
        raise AppealInputError(f"{path}: landmark file not found")
    try:
        d = json.loads(path.read_text())
        groups = d["groups"]
        g = next(iter(groups.values()))
        pts = np.asarray(g["landmarks"]["points"], dtype=np.float64)
        labels = [lab["label"] for lab in g.get("labels", [])]
    except (json.JSONDecodeError, KeyError, StopIteration, TypeError, ValueError) as exc:
        raise AppealInputError(f"{path}: groups.*.landmarks.points: expected a menpo LJSON landmark file ({exc})") from None
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise AppealInputError(f"{path}: landmarks.points: expected 3D points (got shape {pts.shape})")
    ordering = "menpo_ljson" if labels[:2] == ["chin", "leye"] and len(pts) == 68 else "ibug68"
    return pts, ordering


def nearest_boundary_vertices(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """For each 3D point, the index of the nearest vertex on any boundary loop."""
    loops = boundary_loops(faces)
    if not loops:
        raise AppealInputError("boundary anchors: the mesh has no boundary loop")
    b = np.concatenate(loops)
    d = np.linalg.norm(np.asarray(vertices)[b][None, :, :] - np.asarray(points)[:, None, :], axis=2)
    return b[np.argmin(d, axis=1)]
