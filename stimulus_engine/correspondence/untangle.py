"""Local untangling of fold-overs left by the registration.

Where the source has geometry the target lacks (ICT's eye and mouth openings and deep
nostrils against a scan with closed eyelids and shallow nostrils), the closest-point fit
squeezes a patch of the source onto a smaller piece of the target and a few triangles fold
over. :func:`untangle` repairs exactly those patches: the vertices of the folded triangles,
grown by a few rings, are relaxed on the target surface with the rest of the mesh fixed:
a few steps of Laplacian smoothing (each free vertex towards the mean of its neighbours,
each free vertex of a boundary loop — a hole rim — towards the mean of its two rim
neighbours), each followed by a projection back onto the target (closest point). Small
steps keep the points near the surface, so the projection stays local; the relaxation
converges towards a Tutte (harmonic) embedding of the patch, which has no fold-overs. If
folds remain, the patch grows by one ring and the relaxation repeats.

Where the source overhangs the target (the top and sides of a rig's face region beyond
a face mask's border) a fold is of another kind: its vertices had no closest-point match
(pruned: too far, normals apart, or on the target's border) and lie off the target, placed
by the smoothness term alone, which extrapolates the fitted part's compression until it folds.
Pressing them onto the target would collapse them onto its border, and growing the repair into
the fitted part would move what the fit (and the user's landmarks) decided. Given the
``fitted`` vertices, :func:`untangle` therefore first re-places each such overhang on its own:
the patch grows only through unfitted vertices, and its displacement from the source becomes
the harmonic extension (cotangent weights of the source) of the displacements around it, with
every fitted vertex held. The overhang follows the fitted border smoothly and keeps the
source's shape; the fitted part does not move.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from stimulus_engine.correspondence.laplacian import cotangent_laplacian
from stimulus_engine.correspondence.metrics import FoldCheck
from stimulus_engine.geometry.mesh_ops import boundary_neighbours, grow_rings, vertex_adjacency

__all__ = ["UntangleResult", "untangle"]


@dataclass
class UntangleResult:
    """New vertices, the vertices moved, rounds run, fold-overs before/after and the vertices
    left off the target surface by the membrane fallback."""

    vertices: np.ndarray
    moved: np.ndarray
    rounds: int
    folds_before: int
    folds_after: int
    off_surface: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


def untangle(
    vertices: np.ndarray,
    faces: np.ndarray,
    reference: np.ndarray | FoldCheck,
    project: Callable[[np.ndarray], np.ndarray],
    rings: int = 2,
    max_rounds: int = 6,
    steps: int = 10,
    step: float = 0.5,
    membrane_rounds: int = 12,
    membrane_steps: int = 300,
    fitted: np.ndarray | None = None,
    overhang_distance: float = 0.0,
) -> UntangleResult:
    """Remove fold-overs of ``vertices`` (relative to the unfolded ``reference``) locally.

    Parameters
    ----------
    vertices : (N, 3) array
        The registered source.
    faces : (F, 3) int array
    reference : (N, 3) array or FoldCheck
        The undeformed source (what counts as a fold is decided against it, see
        :func:`~stimulus_engine.correspondence.metrics.flipped_triangles`), or a
        :class:`~stimulus_engine.correspondence.metrics.FoldCheck` of it already made.
    project : callable
        Maps (K, 3) points onto the target surface (closest points).
    rings : int
        Rings added around the folded triangles' vertices in the first round.
    max_rounds : int
        Rounds, each with one more ring, until no fold is left.
    steps, step : int, float
        Relaxation steps per round and their size (fraction of the way to the mean).
    membrane_rounds, membrane_steps : int
        The fallback where folds survive the rounds on the surface: rounds (one more ring
        each) of ``membrane_steps`` relaxation steps *without* projection (a membrane spanning
        what the target lacks), after which every relaxed vertex whose projection creates no
        fold is put back onto the target. 0 rounds: no fallback.
    fitted : (N,) bool array, optional
        Vertices whose place the fit decided (a kept closest-point match, a landmark). Bad
        triangles with no fitted vertex and a vertex farther than ``overhang_distance`` from
        the target (an overhang) are repaired first, off the target, moving unfitted vertices
        only (``membrane_rounds`` rounds, one more ring each); the on-surface rounds and their
        fallback then take whatever is still bad. None: no overhang repair.
    overhang_distance : float
        How far from the target (in the meshes' units) a vertex lies off it (the pipeline uses
        its final pruning distance: nothing farther could have been matched).

    Returns
    -------
    UntangleResult
    """
    v = np.array(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    n = len(v)
    check = reference if isinstance(reference, FoldCheck) else FoldCheck(faces, reference)
    if not check.bad(v).any():
        # nothing folded or collapsed: nothing to repair (and no operators to build)
        return UntangleResult(v, np.zeros(n, dtype=bool), 0, 0, 0)
    adjacency = vertex_adjacency(faces, n)
    b, prv, nxt = boundary_neighbours(faces, n)
    # rows of the harmonic operator: interior vertices average their neighbours, hole-rim
    # vertices average their two rim neighbours (the rim stays a faired curve)
    lap = sp.diags(np.asarray(adjacency.sum(axis=1)).ravel()) - adjacency
    if len(b):
        rim = sp.csr_matrix(
            (np.concatenate([np.full(len(b), 2.0), -np.ones(len(b)), -np.ones(len(b))]),
             (np.concatenate([b, b, b]), np.concatenate([b, prv, nxt]))),
            shape=(n, n),
        )
        interior = np.ones(n)
        interior[b] = 0.0
        lap = sp.diags(interior) @ lap + rim
    lap = sp.csr_matrix(lap)
    # per free vertex: the mean of its neighbours (or of its two rim neighbours) is
    # ``v + smooth @ v`` with ``smooth = -D⁻¹ lap``
    deg = lap.diagonal()
    smooth = -(sp.diags(1.0 / np.maximum(deg, 1e-300)) @ lap)
    before = int(check.flipped(v).sum())
    moved = np.zeros(n, dtype=bool)
    overhang = np.zeros(n, dtype=bool)
    rounds = 0
    if fitted is not None:
        # the overhang: re-placed off the target through unfitted vertices only
        v, rounds = _extend_displacement(
            v, faces, check, adjacency, np.asarray(fitted, dtype=bool), project, overhang_distance, rings,
            membrane_rounds, overhang,
        )
        moved |= overhang
    v, r = _relax_rounds(v, faces, check, adjacency, smooth, project, rings, max_rounds, steps, step, moved)
    rounds += r
    membrane = np.zeros(n, dtype=bool)
    if check.bad(v).any() and membrane_rounds:
        # the patch cannot lie on the target without folding (a hole rim squeezed onto a
        # closed surface): relax it as a membrane, off the surface ...
        v_m, r_m = _relax_rounds(
            v, faces, check, adjacency, smooth, None, rings, membrane_rounds, membrane_steps, step, membrane
        )
        rounds += r_m
        # ... then put back onto the target every vertex whose projection folds nothing
        moved |= membrane
        v, membrane = _reproject_where_flat(v_m, faces, check, adjacency, membrane, project)
    after = int(check.flipped(v).sum())
    return UntangleResult(v, moved, rounds, before, after, np.flatnonzero(membrane | overhang))


def _relax_rounds(v, faces, check, adjacency, smooth, project, rings, max_rounds, steps, step, moved):
    """Rounds of relaxation of the bad triangles' vertices grown by ``rings`` (+1 per round);
    each step projected onto the target by ``project`` (None: left where it lands). Marks the
    relaxed vertices in ``moved``; returns the new vertices and the rounds run."""
    v = v.copy()
    bad = check.bad(v)
    rounds = 0
    while bad.any() and rounds < max_rounds:
        seed = np.zeros(len(v), dtype=bool)
        seed[faces[bad].ravel()] = True
        ids = np.flatnonzero(grow_rings(seed, adjacency, rings + rounds))
        s_f = smooth[ids]
        for _ in range(steps):
            # relax towards the neighbours' mean (then back onto the target)
            p = v[ids] + step * (s_f @ v)
            v[ids] = p if project is None else project(p)
        moved[ids] = True
        rounds += 1
        bad = check.bad(v)
    return v, rounds


def _extend_displacement(v, faces, check, adjacency, fitted, project, distance, rings, max_rounds, moved,
                         eps=1e-8):
    """Re-place the overhang (see the module docstring): seeds are the bad triangles with no
    ``fitted`` vertex and a vertex more than ``distance`` from the target; the patch, their
    vertices grown by ``rings`` (+1 per round) through unfitted vertices only, takes the
    harmonic extension of the displacement ``v - reference`` (cotangent Laplacian of the
    reference zero on the patch, every vertex outside it held). Rounds go on while a triangle
    with an unfitted vertex is bad, except the bad triangles that were no seeds to begin with
    (they are on the target: the on-surface repair's). Marks the re-placed vertices in
    ``moved``; returns the new vertices and the rounds run."""
    reference = check.reference
    free = ~fitted
    bad0 = check.bad(v)
    bad = bad0 & free[faces].all(axis=1)
    if not bad.any():
        return v, 0
    cand = np.unique(faces[bad])
    off = np.zeros(len(v), dtype=bool)
    off[cand] = np.linalg.norm(project(v[cand]) - v[cand], axis=1) > distance
    bad &= off[faces].any(axis=1)
    counted = free[faces].any(axis=1) & ~(bad0 & ~bad)
    v = v.copy()
    d = v - reference
    lap = -cotangent_laplacian(reference, faces)
    rounds = 0
    while bad.any() and rounds < max_rounds:
        seed = np.zeros(len(v), dtype=bool)
        seed[faces[bad].ravel()] = True
        patch = grow_rings(seed, adjacency, rings + rounds, free)
        ids, rest = np.flatnonzero(patch), np.flatnonzero(~patch)
        rows = lap[ids]
        # eps keeps a patch that touches no held vertex (a detached overhang) where it is
        a = sp.csc_matrix(rows[:, ids] + eps * sp.identity(len(ids)))
        d[ids] = spsolve(a, eps * d[ids] - rows[:, rest] @ d[rest]).reshape(len(ids), -1)
        v[ids] = reference[ids] + d[ids]
        moved[ids] = True
        rounds += 1
        bad = check.bad(v) & counted
    return v, rounds


def _reproject_where_flat(v, faces, check, adjacency, candidates, project, max_iter=20):
    """Project the ``candidates`` onto the target, except where that makes a new bad triangle:
    the vertices of such triangles (grown by one ring) stay where they are. Returns the new
    vertices and the mask of the vertices left off the surface."""
    base_bad = check.bad(v)
    on = v.copy()
    ids = np.flatnonzero(candidates)
    on[ids] = project(v[ids])
    off = np.zeros(len(v), dtype=bool)
    trial = on
    for _ in range(max_iter):
        trial = np.where(off[:, None], v, on)
        new_bad = check.bad(trial) & ~base_bad
        if not new_bad.any():
            break
        seed = np.zeros(len(v), dtype=bool)
        seed[faces[new_bad].ravel()] = True
        grow = grow_rings(seed, adjacency, 1) & candidates & ~off
        if not grow.any():
            break
        off |= grow
    return trial, off
