"""ElastiFace geometry matching end to end (§3.2): align, joint fairing, register the base
meshes, transfer their correspondences to the originals, register the originals, measure."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import trimesh

from appeal.errors import AppealInputError
from appeal.logs import logger
from stimulus_engine.correspondence.alignment import Similarity, umeyama
from stimulus_engine.geometry.closest import SurfaceIndex
from stimulus_engine.correspondence.fairing import joint_fairing
from stimulus_engine.correspondence.points import Correspondences, SurfacePoints
from stimulus_engine.correspondence.laplacian import fairing_operator, voronoi_areas
from stimulus_engine.correspondence.metrics import FoldCheck, fit_metrics
from stimulus_engine.correspondence.registration import Pruning, nonrigid_register
from stimulus_engine.correspondence.repair import repair_mesh
from stimulus_engine.correspondence.untangle import untangle
from stimulus_engine.geometry.mesh_io import mesh_uv_layout, texture_image, validate_surface
from stimulus_engine.geometry.mesh_ops import edge_face_counts, edge_keys

#: The weights of eq. 3.7-3.13 mix unitless curvature energies with squared distances, so
#: their balance depends on the model's size. Both meshes are scaled so that the target's
#: bounding-box diagonal is this many units: a face measured in centimetres, the scale at which
#: the thesis's weights (λ = 0.1/100/1, μ1 = 10 -> 0.1, fit 300) behave as described.
NORMALISED_DIAGONAL = 25.0

__all__ = ["NORMALISED_DIAGONAL", "CorrespondParams", "CorrespondenceResult", "correspond", "deformed_mesh"]


@dataclass(frozen=True)
class CorrespondParams:
    """Weights and iteration counts (defaults: thesis §3.2.2-3.2.3).

    Distances (``prune_distance_*``, ``crop_target``, ``converge_tolerance``) are relative to
    the target's bounding-box diagonal. ``schedule``: (μ1, at most this many ICP iterations)
    per stiffness stage; a stage ends early (after two iterations) once no vertex moves more
    than ``converge_tolerance`` (the thesis: "typically converges after three to four
    iterations"; 0 always runs the full count). Likewise ``fairing_iterations`` is the most
    area updates of the joint fairing, which stops once they move no vertex more than that.
    ``crop_target``: before fairing, the target is cut down to the triangles within this
    distance of the aligned source (a scan's neck and hair that the
    source does not cover would otherwise float freely in the fairing); None keeps it whole.
    ``untangle``: repair any fold-over left by the registration locally (the folded
    triangles' vertices grown by ``untangle_rings`` rings, re-placed harmonically and
    projected back onto the target; where that still folds — a hole rim squeezed onto a
    closed surface — relaxed as a membrane off the target, re-projected wherever that folds
    nothing; see :mod:`.untangle`). ``metrics["off_surface_vertices"]`` counts those left off.
    """

    lambda1: float = 0.1
    lambda2: float = 100.0
    lambda3: float = 1.0
    fairing_iterations: int = 5
    schedule: tuple[tuple[float, int], ...] = ((10.0, 4), (1.0, 3), (0.1, 3))
    converge_tolerance: float = 2e-4
    mu2: float = 1.0
    mu3: float = 10.0
    final_fit_weight: float = 300.0
    final_other_weight: float = 0.1
    final_iterations: int = 2
    prune_angle: float = 60.0
    prune_distance_base: float = 0.05
    prune_distance_final: float = 0.02
    align: bool = True
    crop_target: float | None = 0.08
    untangle: bool = True
    untangle_rings: int = 2


@dataclass
class CorrespondenceResult:
    """The source deformed onto the target, keeping the source's connectivity and UVs.

    ``vertices`` are in the target's frame; ``faired_source``/``faired_target`` are the base
    meshes ``B^s``/``B^t`` (target vertices cropped away are NaN) and ``registered_base`` is ``B^s`` after registration onto
    ``B^t`` (all in the target's frame). ``alignment`` maps the source into the target frame.
    ``target_face``/``target_bary`` give, for every source vertex, its corresponding point
    on the target (triangle and barycentric weights); ``valid`` marks vertices that had a
    closest-point match (the rest were carried along by the smoothness term).
    """

    vertices: np.ndarray
    faces: np.ndarray
    faired_source: np.ndarray
    faired_target: np.ndarray
    registered_base: np.ndarray
    alignment: Similarity
    target_face: np.ndarray
    target_bary: np.ndarray
    valid: np.ndarray
    metrics: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)


def _check_mesh(mesh: trimesh.Trimesh, role: str) -> None:
    name = mesh.metadata.get("source_path", role)
    validate_surface(mesh, f"{name} ({role})")
    counts = edge_face_counts(mesh.faces)
    if (counts > 2).any():
        n_bad = len(np.unique(edge_keys(mesh.faces)[counts > 2]))
        raise AppealInputError(
            f"{name}: {role} mesh is non-manifold ({n_bad} edges shared by more "
            "than two triangles); expected a manifold surface: remove duplicate faces and non-manifold edges "
            "first (e.g. MeshLab: Filters > Cleaning and Repairing)"
        )


def _near_surface(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, radius: float) -> np.ndarray:
    """Which points lie within ``radius`` of the surface (not merely of its vertices: a coarse
    source's vertices are too far apart, and a MediaPipe-sized mesh lost its border).

    The distance to the nearest vertex bounds the surface distance from above, and from below
    once the longest edge is taken off: only points between the bounds need the exact
    closest-point search (none, when the target lies on the source)."""
    from scipy.spatial import cKDTree

    used = np.unique(faces)
    d_vertex = cKDTree(vertices[used], balanced_tree=False).query(points, workers=-1)[0]
    edges = vertices[faces] - vertices[np.roll(faces, 1, axis=1)]
    longest = float(np.sqrt(np.einsum("fkc,fkc->fk", edges, edges).max())) if len(faces) else 0.0
    near = d_vertex <= radius
    unsure = ~near & (d_vertex - longest <= radius)
    if unsure.any():
        near[unsure] = SurfaceIndex(vertices, faces).query(points[unsure]).distance <= radius
    return near


def _crop(vt: np.ndarray, ft: np.ndarray, vs: np.ndarray, fs: np.ndarray, radius: float, keep_vertices: np.ndarray):
    """Target faces near the source surface (plus those around ``keep_vertices``).

    Returns ``(face_ids, vertex_ids)`` of the kept part (vertex ids sorted)."""
    near = _near_surface(vt, vs, fs, radius)
    # a kept vertex keeps all its triangles (a landmark or tied vertex must not lose its surface)
    keep = np.zeros(len(vt), dtype=bool)
    keep[keep_vertices] = True
    face_ids = np.flatnonzero(near[ft].all(axis=1) | keep[ft].any(axis=1))
    vertex_ids = np.unique(ft[face_ids])
    return face_ids, vertex_ids


def correspond(
    source: trimesh.Trimesh,
    target: trimesh.Trimesh,
    corr: Correspondences,
    params: CorrespondParams = CorrespondParams(),
) -> CorrespondenceResult:
    """Deform ``source`` onto ``target`` through ``corr`` (thesis §3.2).

    Parameters
    ----------
    source, target : trimesh.Trimesh
        Manifold triangle meshes (any tessellation, any proportions).
    corr : Correspondences
        15-20 reference point pairs (nose, eyes, mouth, ears), plus boundary-loop pairs.
    params : CorrespondParams

    Returns
    -------
    CorrespondenceResult
        With ``metrics`` (see :func:`fit_metrics`) and ``seconds`` per stage.
    """
    _check_mesh(source, "source")
    _check_mesh(target, "target")
    if len(corr) < 3:
        raise AppealInputError(f"landmarks: need at least 3 correspondences (got {len(corr)})")
    # the geometry is solved on repaired copies (seams welded, winding made consistent, pieces
    # without landmarks left out) and mapped back: the user's vertices, faces and UVs are kept
    t = time.perf_counter()
    rs = repair_mesh(source.vertices, source.faces, keep_vertices=corr.source.vertices[corr.source.weights > 0])
    rt = repair_mesh(target.vertices, target.faces, keep_vertices=corr.target.vertices[corr.target.weights > 0])
    repair_seconds = time.perf_counter() - t
    if not (rs.changed or rt.changed):
        return _correspond(source.vertices, source.faces, target.vertices, target.faces, corr, params)
    logger.info("repaired for the fit: source %d -> %d vertices (%d riding along), %d faces flipped; target %d -> %d "
                "vertices, %d -> %d faces, %d flipped", len(rs.vertex_map), len(rs.vertices), len(rs.left_out),
                int(rs.flipped.sum()), len(rt.vertex_map), len(rt.vertices), len(target.faces), len(rt.faces),
                int(rt.flipped.sum()))
    corr_r = Correspondences(SurfacePoints(rs.vertex_map[corr.source.vertices], corr.source.weights),
                             SurfacePoints(rt.vertex_map[corr.target.vertices], corr.target.weights))
    res = _correspond(rs.vertices, rs.faces, rt.vertices, rt.faces, corr_r, params)
    res.seconds["repair"] = repair_seconds
    vm = _nearest_kept(np.asarray(source.vertices, dtype=np.float64), rs)
    riders = rs.left_out
    # vertices of left-out pieces move with their nearest fitted vertex (in the aligned frame)
    aligned = res.alignment.apply(np.asarray(source.vertices, dtype=np.float64)[riders])
    kept_aligned = res.alignment.apply(rs.vertices[vm[riders]])
    moved = {k: getattr(res, k)[vm] for k in ("vertices", "faired_source", "registered_base")}
    for k, out in moved.items():
        out[riders] = aligned + getattr(res, k)[vm[riders]] - kept_aligned
    valid = res.valid[vm]
    valid[riders] = False
    face, bary = rt.original_bary(res.target_face[vm], res.target_bary[vm])
    faired_target = np.full((len(rt.vertex_map), 3), np.nan)
    faired_target[rt.vertex_map >= 0] = res.faired_target[rt.vertex_map[rt.vertex_map >= 0]]
    res.metrics.update(n_source_vertices=len(vm), n_target_vertices=len(rt.vertex_map), riding_vertices=len(riders))
    return CorrespondenceResult(
        vertices=moved["vertices"], faces=np.asarray(source.faces), faired_source=moved["faired_source"],
        faired_target=faired_target, registered_base=moved["registered_base"], alignment=res.alignment,
        target_face=face, target_bary=bary, valid=valid, metrics=res.metrics, seconds=res.seconds,
    )


def _nearest_kept(vertices: np.ndarray, repaired) -> np.ndarray:
    """Original vertex -> repaired vertex; a left-out vertex gets its nearest kept one's."""
    vm = repaired.vertex_map.copy()
    out = vm < 0
    if out.any():
        from scipy.spatial import cKDTree

        vm[out] = cKDTree(repaired.vertices).query(vertices[out])[1]
    return vm


def _correspond(source_vertices, source_faces, target_vertices, target_faces, corr: Correspondences,
                params: CorrespondParams) -> CorrespondenceResult:
    """:func:`correspond` on checked, repaired arrays."""
    t_all = time.perf_counter()
    seconds: dict[str, float] = {}
    vs0 = np.asarray(source_vertices, dtype=np.float64)
    vt0 = np.asarray(target_vertices, dtype=np.float64)
    fs = np.asarray(source_faces, dtype=np.int64)
    ft = np.asarray(target_faces, dtype=np.int64)

    t = time.perf_counter()
    if params.align:
        sim = umeyama(corr.source.positions(vs0), corr.target.positions(vt0))
    else:
        sim = Similarity(1.0, np.eye(3), np.zeros(3))
    # work in a normalised frame: target bbox centred, diagonal NORMALISED_DIAGONAL
    used = vt0[np.unique(ft)]  # vertices of no face (or of a dropped island) do not set the frame
    lo, hi = used.min(0), used.max(0)
    centre, diag = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / NORMALISED_DIAGONAL
    if diag <= 0:
        raise AppealInputError("target mesh: all vertices coincide (bounding-box diagonal is 0)")
    vs = (sim.apply(vs0) - centre) / diag
    vt = (vt0 - centre) / diag
    # crop the target to the source's neighbourhood; ``vt_c``/``ft_c`` index the kept part
    if params.crop_target is not None:
        crop_faces, crop_verts = _crop(vt, ft, vs, fs, params.crop_target * NORMALISED_DIAGONAL, np.unique(corr.target.vertices))
    else:
        crop_faces, crop_verts = np.arange(len(ft)), np.arange(len(vt))
    remap = np.full(len(vt), -1, dtype=np.int64)
    remap[crop_verts] = np.arange(len(crop_verts))
    vt_c, ft_c = vt[crop_verts], remap[ft[crop_faces]]
    corr_c = Correspondences(corr.source, SurfacePoints(remap[corr.target.vertices], corr.target.weights))
    # the inputs' Voronoi areas serve the operators, the first fairing solve and the final
    # registration
    a_vs, a_vt = voronoi_areas(vs, fs), voronoi_areas(vt_c, ft_c)
    ls = fairing_operator(vs, fs, a_vs)
    lt = fairing_operator(vt_c, ft_c, a_vt)
    seconds["align"] = time.perf_counter() - t

    t = time.perf_counter()
    fair = joint_fairing(
        vs, fs, vt_c, ft_c, corr_c, params.lambda1, params.lambda2, params.lambda3,
        params.fairing_iterations, ls, lt, tolerance=params.converge_tolerance * NORMALISED_DIAGONAL,
        areas=(a_vs, a_vt),
    )
    seconds["fairing"] = time.perf_counter() - t
    logger.info(
        "joint fairing: %d factorisations, %d CG solves (%d iterations), %.2f s",
        fair.factorizations, fair.pcg_solves, fair.pcg_iterations, seconds["fairing"],
    )

    t = time.perf_counter()
    # the base meshes are smooth and well shaped: fewer closest-triangle candidates suffice
    bt_index = SurfaceIndex(fair.target, ft_c, k=4, k_vertices=1)
    base = nonrigid_register(
        fair.source, fs, ls, voronoi_areas(fair.source, fs), bt_index,
        corr.source, corr_c.target.positions(fair.target), params.schedule, params.mu2, params.mu3,
        Pruning(params.prune_distance_base * NORMALISED_DIAGONAL, params.prune_angle, True),
        tolerance=params.converge_tolerance * NORMALISED_DIAGONAL, ordering=fair.source_ordering,
        bilaplacian_map=fair.source_bilaplacian,
    )
    seconds["register_base"] = time.perf_counter() - t
    logger.info(
        "base registration: %d iterations, %d factorisations, %d reuses, %.2f s",
        base.iterations, base.factorizations, base.reuses, seconds["register_base"],
    )

    t = time.perf_counter()
    # the base correspondences (triangle + barycentric on B^t) carried to the original target
    cp = base.closest
    c_orig = np.einsum("ij,ijk->ik", cp.bary, vt_c[ft_c[cp.face]])
    w = params.final_other_weight
    t_index = SurfaceIndex(vt, ft)
    final = nonrigid_register(
        vs, fs, ls, a_vs, t_index, corr.source, corr.target.positions(vt),
        ((w, max(1, params.final_iterations)),), params.final_fit_weight, w,
        Pruning(params.prune_distance_final * NORMALISED_DIAGONAL, params.prune_angle, True),
        fixed_targets=(c_orig, base.valid), ordering=base.ordering, solver=base.solver,
        bilaplacian_map=fair.source_bilaplacian,
    )
    seconds["register_original"] = time.perf_counter() - t

    t = time.perf_counter()
    v_final = final.vertices
    untangled, off_surface = 0, np.zeros(0, dtype=np.int64)
    folds = FoldCheck(fs, vs)  # the source's own folds and areas, for the repair and the metrics
    if params.untangle:
        # matched vertices and landmarks are held where a fold lies off the target (an overhang)
        fitted = final.valid.copy()
        fitted[corr.source.vertices[corr.source.weights > 0]] = True
        ut = untangle(v_final, fs, folds, lambda p: t_index.query(p).points, rings=params.untangle_rings,
                      fitted=fitted, overhang_distance=params.prune_distance_final * NORMALISED_DIAGONAL)
        v_final, untangled, off_surface = ut.vertices, int(ut.moved.sum()), ut.off_surface
        if ut.rounds:
            logger.info("untangling: %d -> %d fold-overs, %d vertices moved in %d rounds, %d left off the target",
                        ut.folds_before, ut.folds_after, untangled, ut.rounds, len(off_surface))
    seconds["untangle"] = time.perf_counter() - t

    out_v = v_final * diag + centre
    faired_target = np.full_like(vt, np.nan)
    faired_target[crop_verts] = fair.target
    if final.closest is not None:
        tf, tb, valid = final.closest.face.copy(), final.closest.bary.copy(), final.valid
    else:
        tf, tb, valid = crop_faces[cp.face], cp.bary.copy(), base.valid
    if untangled:
        moved = ut.moved
        cp_m = t_index.query(v_final[moved])
        tf[moved], tb[moved] = cp_m.face, cp_m.bary
    if len(off_surface):
        # membrane vertices spanning what the target lacks: carried by their neighbours
        valid = valid.copy()
        valid[off_surface] = False
    seconds["total"] = time.perf_counter() - t_all
    t = time.perf_counter()
    # measured in the normalised frame (relative distances and fold-overs do not depend on it)
    # with the target index already built
    metrics = fit_metrics(v_final, fs, vt, ft, vs, target_index=t_index, folds=folds)
    metrics["target_bbox_diagonal"] = float(np.linalg.norm(hi - lo))
    seconds["metrics"] = time.perf_counter() - t
    metrics["seconds"] = seconds["total"]
    metrics["valid_fraction"] = float(valid.mean())
    metrics["fairing_solves"] = len(fair.energies)
    metrics["registration_iterations"] = base.iterations + final.iterations
    metrics["untangled_vertices"] = untangled
    metrics["off_surface_vertices"] = int(len(off_surface))
    return CorrespondenceResult(
        vertices=out_v,
        faces=fs,
        faired_source=fair.source * diag + centre,
        faired_target=faired_target * diag + centre,
        registered_base=base.vertices * diag + centre,
        alignment=sim,
        target_face=tf,
        target_bary=tb,
        valid=valid,
        metrics=metrics,
        seconds=seconds,
    )


def deformed_mesh(source: trimesh.Trimesh, vertices: np.ndarray) -> trimesh.Trimesh:
    """A copy of ``source`` with new vertex positions; connectivity, UV layout and texture kept."""
    from stimulus_engine.geometry.mesh_io import build_trimesh

    layout = mesh_uv_layout(source)
    uv, fuv = layout if layout is not None else (None, None)
    meta = {k: v for k, v in source.metadata.items() if k not in ("uv_coords", "face_uv")}
    return build_trimesh(np.asarray(vertices, dtype=np.float64), np.asarray(source.faces), uv, fuv, texture_image(source), meta)
