"""Correspondences along boundary loops (thesis Fig. 3.5).

From one or more corresponding points on a source and a target boundary loop, every other
source loop vertex gets the target loop point at the same relative arc length (piecewise
between consecutive anchors), a point on a target boundary edge
(:func:`boundary_correspondences`). Where the target has no hole (a scan's closed lips and
eyelids against a model's mouth and eye openings), :func:`rim_to_curve_correspondences` maps a
source boundary loop the same way onto a closed curve drawn on the target surface through
given points (e.g. the lip or eyelid landmarks;
:func:`~stimulus_engine.correspondence.curves.surface_polyline`). The loops themselves are
:func:`stimulus_engine.geometry.mesh_ops.boundary_loops`.
"""

from __future__ import annotations

import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.geometry.closest import SurfaceIndex
from stimulus_engine.correspondence.curves import surface_polyline
from stimulus_engine.correspondence.points import Correspondences, SurfacePoints
from stimulus_engine.geometry.mesh_ops import boundary_loops

__all__ = ["boundary_correspondences", "rim_to_curve_correspondences", "nearest_boundary_vertices"]


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


def nearest_boundary_vertices(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """For each 3D point, the index of the nearest vertex on any boundary loop."""
    loops = boundary_loops(faces)
    if not loops:
        raise AppealInputError("boundary anchors: the mesh has no boundary loop")
    b = np.concatenate(loops)
    d = np.linalg.norm(np.asarray(vertices)[b][None, :, :] - np.asarray(points)[:, None, :], axis=2)
    return b[np.argmin(d, axis=1)]
