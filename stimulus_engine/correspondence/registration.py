"""Non-rigid registration (eq. 3.11-3.13).

The source is deformed onto the target by minimising, ICP-style with closest points
re-computed each iteration::

    E = μ1/ΣA Σ A_i ||Δ(v_i - v̂_i)||²  +  μ2/C Σ_j ||v_j - c_j||²  +  μ3/M Σ ||r_m - r̂_m^t||²

bending of the displacement (cotangent weights fixed from the *original* source, Voronoi
areas of the mesh being registered), closest-point fit over the C unpruned vertices, and the
reference points. The stiffness μ1 follows a schedule (10 -> 1 -> 0.1). Closest points are
pruned when too far, when normals disagree, or when they land on the target's boundary
(thesis Fig. 2.3). A factorisation is reused while the matrix (μ1 and the pruning mask) is
unchanged.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from stimulus_engine.geometry.closest import ClosestPoints, SurfaceIndex
from stimulus_engine.correspondence.points import SurfacePoints
from stimulus_engine.correspondence.laplacian import bilaplacian
from stimulus_engine.correspondence.ordering import nested_dissection
from stimulus_engine.correspondence.solve import LowerPattern, ReusableSolver
from stimulus_engine.geometry.mesh_ops import vertex_normals

__all__ = ["Pruning", "RegistrationResult", "prune_mask", "nonrigid_register"]

_CALLS = itertools.count()


@dataclass(frozen=True)
class Pruning:
    """Closest-point pruning: distance (absolute, same units as the meshes), normal angle
    in degrees, and whether matches on the target boundary are dropped."""

    max_distance: float = np.inf
    max_angle: float = 60.0
    boundary: bool = True


@dataclass
class RegistrationResult:
    """Registered vertices, the last closest points and pruning mask, and solver counts."""

    vertices: np.ndarray
    closest: ClosestPoints | None
    valid: np.ndarray
    iterations: int = 0
    factorizations: int = 0
    reuses: int = 0
    history: list[dict] = field(default_factory=list)
    ordering: np.ndarray | None = None
    solver: ReusableSolver | None = None


def prune_mask(points: np.ndarray, normals: np.ndarray, cp: ClosestPoints, pruning: Pruning) -> np.ndarray:
    """True where the closest-point correspondence is kept."""
    ok = cp.distance <= pruning.max_distance
    if pruning.max_angle < 180:
        cos = np.einsum("ij,ij->i", normals, cp.normals)
        ok &= cos >= np.cos(np.deg2rad(pruning.max_angle))
    if pruning.boundary:
        ok &= ~cp.on_boundary
    return ok


def nonrigid_register(
    start: np.ndarray,
    faces: np.ndarray,
    laplacian: sp.spmatrix,
    areas: np.ndarray,
    target: SurfaceIndex,
    ref_source: SurfacePoints,
    ref_target: np.ndarray,
    schedule: tuple[tuple[float, int], ...] = ((10.0, 4), (1.0, 3), (0.1, 3)),
    mu2: float = 1.0,
    mu3: float = 10.0,
    pruning: Pruning = Pruning(),
    fixed_targets: tuple[np.ndarray, np.ndarray] | None = None,
    progress=None,
    reuse_mask: bool = True,
    ordering: np.ndarray | None = None,
    tolerance: float = 0.0,
    solver: ReusableSolver | None = None,
    bilaplacian_map: tuple | None = None,
) -> RegistrationResult:
    """Deform ``start`` onto ``target`` (eq. 3.11-3.13).

    Parameters
    ----------
    start : (N, 3) array
        Undeformed source positions ``v̂`` (the displacement is measured from these).
    faces : (F, 3) int array
    laplacian : sparse (N, N)
        Cotangent matrix of the original source (kept fixed).
    areas : (N,) array
        Voronoi areas of the mesh being registered.
    target : SurfaceIndex
        The target surface.
    ref_source : SurfacePoints
        Reference points on the source; ``ref_target`` (M, 3) their target positions.
    schedule : sequence of (μ1, iterations)
        Stiffness schedule.
    mu2, mu3 : float
        Fit and reference weights.
    pruning : Pruning
    fixed_targets : (points (N, 3), valid (N,)), optional
        Use these correspondences in the first iteration instead of closest points (the
        transfer from the base meshes to the originals).
    progress : callable, optional
        Called with a short description after each iteration.
    reuse_mask : bool
        Decide the pruning mask at the first iteration of each stiffness stage and keep it for
        the stage, so that one factorisation serves the whole stage (closest points are still
        updated every iteration). False re-prunes (and refactorises) every iteration.
    ordering : (N,) int array, optional
        Fill-reducing ordering for the factorisations (the pattern is that of the
        bi-Laplacian, whatever the weights); by default a nested dissection of ``start`` with
        SuperLU and CHOLMOD's own (AMD) otherwise, returned in ``RegistrationResult.ordering``
        for reuse.
    tolerance : float
        A stiffness stage ends (after at least two iterations) once no vertex moved more.
    solver : ReusableSolver, optional
        ``RegistrationResult.solver`` of an earlier registration of the same mesh (same faces
        and reference points): its symbolic factorisation and matrix pattern are reused.
    bilaplacian_map : (LowerPattern, sparse M), optional
        ``laplacian``'s bi-Laplacian as a map from inverse areas to values on a pattern that
        also holds the reference points' couplings (the joint fairing's source block,
        :attr:`~.fairing.FairingResult.source_bilaplacian`): the matrices without sparse
        products or lookups.
    """
    v_hat = np.asarray(start, dtype=np.float64)
    n = len(v_hat)
    w_area = 1.0 / areas.sum()
    cs = ref_source.matrix(n)
    m = max(len(ref_source), 1)
    ref_h = (mu3 / m) * (cs.T @ cs)
    ref_rhs = (mu3 / m) * (cs.T @ ref_target)
    if solver is None:
        solver = ReusableSolver(ordering)
    # one sparsity pattern for every matrix of the schedule (and of a later registration of the
    # same mesh): each factorisation only sets values, no sparse sums or conversions
    q_pos, q_val, pattern = None, None, solver.pattern
    if bilaplacian_map is not None and (pattern is None or pattern is bilaplacian_map[0]):
        try:
            r_pos, r_val = bilaplacian_map[0].positions(ref_h)
            pattern = solver.pattern = bilaplacian_map[0]
            q_pos, q_val = np.arange(pattern.nnz), bilaplacian_map[1] @ (1.0 / areas)
        except ValueError:  # the couplings are not in the map's pattern
            pattern = solver.pattern
    if q_pos is None:
        q = bilaplacian(laplacian, areas)
        try:
            if pattern is None or pattern.n != n:
                raise ValueError
            q_pos, q_val = pattern.positions(q)
            r_pos, r_val = pattern.positions(ref_h)
        except ValueError:
            pattern = solver.pattern = LowerPattern(n, q, ref_h)
            (q_pos, q_val), (r_pos, r_val) = pattern.matrix_positions
    if solver.ordering is None and solver.backend == "superlu":
        solver.ordering = nested_dissection(pattern.structure(), v_hat)
    call = next(_CALLS)  # a solver handed on must not take this call's matrices for its last
    v = v_hat.copy()
    res = RegistrationResult(v, None, np.zeros(n, dtype=bool))
    it = 0
    c = v_hat.copy()
    lap = sp.csr_matrix(laplacian)
    q_vhat = lap.T @ ((lap @ v_hat) / areas[:, None])  # Lᵀ A⁻¹ L v̂
    for mu1, n_iter in schedule:
        q_rhs = (mu1 * w_area) * q_vhat
        for k in range(n_iter):
            if fixed_targets is not None and it == 0:
                c, valid = fixed_targets
                c = np.array(c, dtype=np.float64)
                cp = None
            else:
                # last iteration's triangles start the search (the vertices moved a little)
                cp = target.query(v, hint=None if res.closest is None else res.closest.face)
                ok = prune_mask(v, vertex_normals(v, faces), cp, pruning)
                if k == 0 or not reuse_mask:
                    valid = ok
                    c = cp.points.copy()
                else:
                    # same mask as the stage's first iteration (so the factorisation is reused);
                    # a vertex whose new match is pruned keeps its previous target point
                    c = np.where(ok[:, None], cp.points, c)
            n_valid = max(int(valid.sum()), 1)
            wfit = np.where(valid, mu2 / n_valid, 0.0)
            key = solver.make_key(call, mu1, mu2, n_valid, valid)

            def build(mu1=mu1, wfit=wfit):
                values = np.zeros(pattern.nnz)
                values[q_pos] = (mu1 * w_area) * q_val
                values[r_pos] += r_val
                values[pattern.diagonal] += wfit
                return pattern.matrix(values)

            v_new = solver.solve(key, build, q_rhs + wfit[:, None] * c + ref_rhs)
            move = float(np.sqrt(np.einsum("ij,ij->i", v_new - v, v_new - v).max())) if n else 0.0
            v = v_new
            res.history.append({"mu1": mu1, "valid": int(valid.sum()), "max_move": move})
            res.closest, res.valid = cp, valid
            it += 1
            if progress is not None:
                progress(f"μ1={mu1:g} valid={int(valid.sum())}/{n}")
            if k >= 1 and move < tolerance:
                break
    res.vertices = v
    res.iterations = it
    res.factorizations = solver.factorizations
    res.reuses = solver.reuses
    res.ordering = solver.ordering
    res.solver = solver
    return res
