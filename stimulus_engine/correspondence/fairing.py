"""Joint fairing of source and target (eq. 3.7-3.10).

Both meshes are smoothed *together* into featureless, geometrically similar base meshes
``B^s``, ``B^t``: the bi-Laplacian (thin-plate) energy of both (3.8), a strong term pulling
corresponding reference points together (3.9), and a weak term holding each coincident pair
near the mid-point of its original positions (3.10)::

    E = λ1/(ΣA^s + ΣA^t) (Σ A_i^s ||Δv_i^s||² + Σ A_j^t ||Δv_j^t||²)
        + λ2/M Σ ||r_m^s - r_m^t||² + λ3/M Σ ||½(r_m^s + r_m^t) - ½(r̂_m^s + r̂_m^t)||²

With the cotangent weights fixed (from the input meshes) and the Voronoi areas updated every
iteration (Kazhdan et al. 2012), each iteration is one sparse SPD solve of size N^s + N^t
(three right-hand sides, x/y/z, one multi-RHS solve), refactorising numerically with the
symbolic analysis kept (CHOLMOD): the matrix's pattern is fixed once, and each iteration only
computes its values (a sparse map of the inverse areas plus the constant constraint part,
:func:`~.laplacian.bilaplacian_map`); with SuperLU the first two iterations are factorised (the
second reuses the first's fill-reducing ordering) and from the third on, when the areas change
little, the solve is preconditioned conjugate gradients on the last factorisation.

The elimination order puts the target's reference unknowns last and each mesh's other
unknowns before them in nested-dissection order (:func:`~.ordering.coupled_ordering`): the
meshes are then eliminated independently, and the numeric factorisation of the 19k + 10k
system takes 48 ms instead of 74 with CHOLMOD's AMD. The source's part of that order serves
the registration's matrices on the same mesh (:attr:`FairingResult.source_ordering`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from stimulus_engine.correspondence.points import Correspondences
from stimulus_engine.correspondence.laplacian import bilaplacian_map, fairing_operator, voronoi_areas
from stimulus_engine.correspondence.ordering import coupled_ordering
from stimulus_engine.correspondence.solve import ReusableSolver

__all__ = ["FairingResult", "joint_fairing"]

#: Tiny pull towards the input positions so components without reference points stay defined.
_TIKHONOV = 1e-9

#: :func:`~.ordering.coupled_ordering` (the target's reference unknowns eliminated last, as one
#: dense block) while they are at most this many times the square root of all unknowns (about
#: the size of a mesh's top separator; 481 of 29k unknowns in ``benchmarks/correspond.py``);
#: else the solver's own ordering
_MAX_COUPLED = 4.0


@dataclass
class FairingResult:
    """Base meshes ``source`` (N^s, 3) and ``target`` (N^t, 3) and per-iteration energies."""

    source: np.ndarray
    target: np.ndarray
    energies: list[float] = field(default_factory=list)
    factorizations: int = 0
    pcg_solves: int = 0
    pcg_iterations: int = 0
    #: a fill-reducing ordering of the source's unknowns (nested dissection), for the
    #: registration's matrices on the same mesh; None if the solver chose its own
    source_ordering: np.ndarray | None = None
    #: the source block of the bi-Laplacian map (:func:`~.laplacian.bilaplacian_map`):
    #: ``(pattern, M)`` with ``M @ (1 / areas)`` the lower triangle of ``Lsᵀ A⁻¹ Ls`` on
    #: ``pattern`` (which also holds the reference points' couplings): the registration's
    #: matrices on the same mesh, without sparse products
    source_bilaplacian: tuple | None = None


def joint_fairing(
    source_vertices: np.ndarray,
    source_faces: np.ndarray,
    target_vertices: np.ndarray,
    target_faces: np.ndarray,
    corr: Correspondences,
    lambda1: float = 0.1,
    lambda2: float = 100.0,
    lambda3: float = 1.0,
    iterations: int = 5,
    source_laplacian: sp.spmatrix | None = None,
    target_laplacian: sp.spmatrix | None = None,
    tolerance: float = 0.0,
    areas: tuple[np.ndarray, np.ndarray] | None = None,
) -> FairingResult:
    """Fair source and target jointly (eq. 3.7-3.10).

    Parameters
    ----------
    source_vertices, target_vertices : (N, 3) arrays
        Aligned input meshes (same frame, e.g. after :func:`umeyama`).
    source_faces, target_faces : (F, 3) int arrays
    corr : Correspondences
        Reference point pairs (eq. 3.1).
    lambda1, lambda2, lambda3 : float
        Smoothness, coincidence and position weights (thesis: 0.1, 100, 1; λ1 = 10 for
        extreme pairs that do not unfold).
    iterations : int
        Solves; the Voronoi areas are recomputed from the previous solution before each
        solve after the first (5-10 in the thesis).
    source_laplacian, target_laplacian : sparse matrices, optional
        Precomputed cotangent matrices of the inputs.
    tolerance : float
        Stop before ``iterations`` once an area update moved no vertex more than this (same
        units as the meshes): the thesis's "no noticeable changes". 0 always runs them all.
    areas : (source areas, target areas), optional
        The inputs' Voronoi areas, if already computed (the first solve's weights).

    Returns
    -------
    FairingResult
    """
    xs = np.asarray(source_vertices, dtype=np.float64)
    xt = np.asarray(target_vertices, dtype=np.float64)
    ns, nt = len(xs), len(xt)
    m = len(corr)
    ls = source_laplacian if source_laplacian is not None else fairing_operator(xs, source_faces)
    lt = target_laplacian if target_laplacian is not None else fairing_operator(xt, target_faces)
    cs = corr.source.matrix(ns)
    ct = corr.target.matrix(nt)
    diff = sp.hstack([cs, -ct]).tocsr()
    mean = sp.hstack([cs, ct]).tocsr()
    c0 = 0.5 * (cs @ xs + ct @ xt)
    x_hat = np.vstack([xs, xt])
    constraint = ((lambda2 / m) * (diff.T @ diff) + (lambda3 / (4.0 * m)) * (mean.T @ mean)).tocsr()
    rhs_c = (lambda3 / (2.0 * m)) * (mean.T @ c0)
    # the matrix keeps one sparsity pattern: the bi-Laplacian's values are a linear map of the
    # inverse areas, the constraint's are fixed (no sparse products per iteration)
    lap = sp.block_diag([ls, lt], format="csr")
    pattern, bilap = bilaplacian_map(lap, constraint)
    c_pos, c_val = pattern.positions(constraint)
    fixed = np.zeros(pattern.nnz)
    fixed[c_pos] = c_val
    diag = pattern.diagonal
    x = x_hat.copy()
    res = FairingResult(xs, xt)
    block, inside = pattern.leading(ns)
    res.source_bilaplacian = (block, bilap[inside][:, :ns])
    # the target's reference unknowns last, each mesh by nested dissection before them
    coupled = ns + np.unique(corr.target.vertices[corr.target.weights != 0])
    if len(coupled) <= _MAX_COUPLED * np.sqrt(ns + nt):
        order = coupled_ordering(pattern.structure(), x_hat, ns, coupled)
        res.source_ordering = order[:ns]
    else:
        order = None
    solver = ReusableSolver(order)
    for it in range(max(1, iterations)):
        if it == 0 and areas is not None:
            a_s, a_t = areas
        else:
            a_s = voronoi_areas(x[:ns], source_faces)
            a_t = voronoi_areas(x[ns:], target_faces)
        w1 = lambda1 / (a_s.sum() + a_t.sum())
        inv_a = 1.0 / np.concatenate([a_s, a_t])
        q = bilap @ inv_a  # lower triangle of blockdiag(Lsᵀ As⁻¹ Ls, Ltᵀ At⁻¹ Lt)
        scale = w1 * float(np.median(abs(q[diag]))) + 1e-300
        h = w1 * q + fixed
        h[diag] += _TIKHONOV * scale
        rhs = rhs_c + (_TIKHONOV * scale) * x_hat
        # the first update moves the areas most and gets its own factorisation; later ones
        # move them only a little: conjugate gradients preconditioned with the last
        # factorisation (refactorised only if that does not converge quickly). Intermediate
        # iterates only feed the next areas, so they are solved less tightly than the last.
        last = it == max(1, iterations) - 1
        x_prev = x
        x = solver.solve(solver.make_key(it), lambda h=h: pattern.matrix(h), rhs, near=it >= 2, x0=x,
                         rtol=1e-10 if last else 1e-7)
        # the energy (3.7, without its constant and the Tikhonov pull) at the solution of
        # H x = b: xᵀ(w1 Q + C)x = xᵀ(b - τx), so E = -xᵀ rhs_c + τ(xᵀx̂ - xᵀx), three dot
        # products instead of the operator products
        tau = _TIKHONOV * scale
        res.energies.append(float(-np.vdot(x, rhs_c) + tau * (np.vdot(x, x_hat) - np.vdot(x, x))))
        if it >= 1 and np.sqrt(np.einsum("ij,ij->i", x - x_prev, x - x_prev).max()) < tolerance:
            break
    res.factorizations = solver.factorizations
    res.pcg_solves = solver.pcg_solves
    res.pcg_iterations = solver.pcg_iterations
    res.source, res.target = x[:ns], x[ns:]
    return res
