"""Sparse symmetric positive-definite solves: factorisation reuse, ordering reuse, and
preconditioned conjugate gradients on a nearby factorisation.

SuperLU (SciPy) in symmetric mode with no pivoting is the direct solver: about as fast as
CHOLMOD on these bi-Laplacian systems (~20k unknowns) and it ships with SciPy. Three ways of
not paying for a factorisation twice:

* :class:`ReusableSolver` keeps the last factorisation and reuses it while the matrix is
  unchanged (same stiffness weight and the same set of fitted vertices);
* a fill-reducing ordering depends only on the sparsity pattern: :class:`Factor` remembers
  it and a later factorisation of a matrix with the same pattern skips the ordering step
  (or uses a geometric nested-dissection ordering from :mod:`.ordering`);
* :func:`pcg` solves a matrix *close* to one already factorised (the fairing matrix after
  the Voronoi areas moved a little) with that factorisation as preconditioner: a few
  triangular solves instead of a new factorisation.
"""

from __future__ import annotations

import hashlib

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

__all__ = ["Factor", "ReusableSolver", "factorize", "pcg", "pattern_key"]


def pattern_key(matrix: sp.spmatrix) -> bytes:
    """Hash of a sparse matrix's shape and sparsity pattern (CSC)."""
    m = sp.csc_matrix(matrix)
    m.sort_indices()
    h = hashlib.blake2b(digest_size=16)
    h.update(repr(m.shape).encode())
    h.update(np.ascontiguousarray(m.indptr, dtype=np.int64).tobytes())
    h.update(np.ascontiguousarray(m.indices, dtype=np.int64).tobytes())
    return h.digest()


class Factor:
    """A SuperLU factorisation of ``P A Pᵀ`` for a symmetric ordering ``P``.

    ``ordering[k]`` is the original index of the unknown placed at position ``k``; it can be
    handed to :func:`factorize` for the next matrix with the same sparsity pattern.
    """

    def __init__(self, lu, ordering: np.ndarray | None) -> None:
        self._lu = lu
        self.ordering = ordering if ordering is not None else np.argsort(lu.perm_c)
        self._permuted = ordering is not None

    @property
    def shape(self) -> tuple[int, int]:
        return self._lu.shape

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``A⁻¹ rhs`` for one (N,) or several (N, K) right-hand sides."""
        b = np.asarray(rhs, dtype=np.float64)
        if not self._permuted:
            return self._lu.solve(b)
        out = np.empty_like(b)
        out[self.ordering] = self._lu.solve(b[self.ordering])
        return out


def factorize(matrix: sp.spmatrix, ordering: np.ndarray | None = None) -> Factor:
    """SuperLU factorisation of a sparse symmetric positive-definite matrix.

    Symmetric mode with no pivoting (safe for SPD matrices) keeps the fill-reducing ordering
    intact: about 10x faster and half the fill of the default partial pivoting.

    Parameters
    ----------
    matrix : sparse (N, N)
    ordering : (N,) int array, optional
        A symmetric fill-reducing ordering (e.g. ``previous_factor.ordering`` for a matrix of
        the same pattern, or :func:`~stimulus_engine.correspondence.ordering.nested_dissection`);
        by default SuperLU's minimum degree on ``A + Aᵀ``.
    """
    opts = {"diag_pivot_thresh": 0.0, "options": {"SymmetricMode": True}}
    if ordering is None:
        return Factor(splu(sp.csc_matrix(matrix), permc_spec="MMD_AT_PLUS_A", **opts), None)
    ordering = np.asarray(ordering, dtype=np.int64)
    m = sp.csr_matrix(matrix)[ordering][:, ordering]
    return Factor(splu(sp.csc_matrix(m), permc_spec="NATURAL", **opts), ordering)


def pcg(
    matrix: sp.spmatrix,
    rhs: np.ndarray,
    precondition,
    x0: np.ndarray | None = None,
    rtol: float = 1e-10,
    maxiter: int = 25,
) -> tuple[np.ndarray, int, bool]:
    """Preconditioned conjugate gradients, column by column on (N, K) right-hand sides.

    Parameters
    ----------
    matrix : sparse SPD (N, N)
    rhs : (N,) or (N, K) array
    precondition : callable
        ``z = precondition(r)`` for (N, K) ``r`` (e.g. ``Factor.solve`` of a nearby matrix).
    x0 : array like ``rhs``, optional
        Starting point (the previous iterate of an outer loop).
    rtol : float
        Stop when every column's residual norm is at most ``rtol`` times its ``rhs`` norm.
    maxiter : int
        Give up after this many iterations, or earlier when the observed convergence rate
        cannot reach ``rtol`` within ``maxiter`` (the caller should then refactorise).

    Returns
    -------
    x, iterations, converged
    """
    b = np.asarray(rhs, dtype=np.float64)
    vec = b.ndim == 1
    b = b.reshape(len(b), -1)
    x = np.zeros_like(b) if x0 is None else np.array(x0, dtype=np.float64).reshape(b.shape)
    a = sp.csr_matrix(matrix)
    r = b - a @ x
    bn = np.linalg.norm(b, axis=0)
    bn[bn == 0] = 1.0
    r0 = np.linalg.norm(r, axis=0) / bn
    z = precondition(r)
    p = z.copy()
    rz = np.einsum("ij,ij->j", r, z)
    it, ok = 0, False
    while True:
        rel = np.linalg.norm(r, axis=0) / bn
        if (rel <= rtol).all():
            ok = True
            break
        if it >= maxiter:
            break
        if it >= 4:
            # linear convergence rate so far; stop early if it cannot get there in time
            rate = (np.maximum(rel, 1e-300) / np.maximum(r0, 1e-300)) ** (1.0 / it)
            need = np.log(rtol / np.maximum(rel, 1e-300)) / np.log(np.minimum(rate, 1 - 1e-12))
            if (rate >= 1).any() or it + need.max() > maxiter:
                break
        ap = a @ p
        pap = np.einsum("ij,ij->j", p, ap)
        alpha = np.divide(rz, pap, out=np.zeros_like(rz), where=pap != 0)
        x += alpha * p
        r -= alpha * ap
        z = precondition(r)
        rz_new = np.einsum("ij,ij->j", r, z)
        beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz != 0)
        p = z + beta * p
        rz = rz_new
        it += 1
    return (x.ravel() if vec else x), it, ok


class ReusableSolver:
    """Solve ``H x = b`` for a sequence of matrices, refactorising only when ``key`` changes.

    The fill-reducing ordering of the first factorisation (or ``ordering``) is reused for later
    ones: the callers change weights, never the sparsity pattern. ``exact=False`` matrices
    (:meth:`solve` with ``near=True``) are first tried with :func:`pcg` on the current
    factorisation.
    """

    def __init__(self, ordering: np.ndarray | None = None) -> None:
        self._key: bytes | None = None
        self._lu: Factor | None = None
        self.ordering = ordering
        self.factorizations = 0
        self.reuses = 0
        self.pcg_solves = 0
        self.pcg_iterations = 0

    @staticmethod
    def make_key(*parts) -> bytes:
        h = hashlib.blake2b(digest_size=16)
        for p in parts:
            h.update(np.ascontiguousarray(p).tobytes() if isinstance(p, np.ndarray) else repr(p).encode())
        return h.digest()

    def _factor(self, matrix: sp.spmatrix, key: bytes) -> None:
        self._lu = factorize(matrix, self.ordering)
        self.ordering = self._lu.ordering
        self._key = key
        self.factorizations += 1

    def solve(
        self, key: bytes, build, rhs: np.ndarray, near: bool = False, x0: np.ndarray | None = None, rtol: float = 1e-10
    ) -> np.ndarray:
        """``build()`` makes the matrix when ``key`` differs from the last call's.

        With ``near=True`` a new matrix is first solved by :func:`pcg` preconditioned with the
        current factorisation (starting from ``x0``, to relative residual ``rtol``); only if
        that does not converge quickly is it factorised.
        """
        rhs = np.asarray(rhs, dtype=np.float64)
        if key == self._key and self._lu is not None:
            self.reuses += 1
            return self._lu.solve(rhs)
        matrix = build()
        if near and self._lu is not None:
            x, it, ok = pcg(matrix, rhs, self._lu.solve, x0, rtol=rtol)
            self.pcg_iterations += it
            if ok:
                self.pcg_solves += 1
                return x
        self._factor(matrix, key)
        return self._lu.solve(rhs)
