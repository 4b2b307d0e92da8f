"""Sparse symmetric positive-definite solves: two direct solvers, factorisation reuse,
ordering reuse, and preconditioned conjugate gradients on a nearby factorisation.

Direct solvers (``backend``):

* ``"cholmod"`` — CHOLMOD's supernodal Cholesky (SuiteSparse) through ``cvxopt``, when it is
  installed (``pip install appeal-lab[fast]``; ``make`` installs it). About 5x faster to
  factorise than SuperLU on the bi-Laplacian systems here (29k unknowns: 0.08 s vs 0.5 s;
  ``benchmarks/sparse_solvers.py``), and a matrix with the same sparsity pattern is
  refactorised numerically only (the symbolic analysis is kept).
* ``"superlu"`` — SciPy's SuperLU in symmetric mode with no pivoting (always available; BSD).

``APPEAL_SPARSE_SOLVER=superlu|cholmod`` or the ``backend`` argument chooses; the default is
CHOLMOD when importable. Three ways of not paying for a factorisation twice:

* :class:`ReusableSolver` keeps the last factorisation and reuses it while the matrix is
  unchanged (same stiffness weight and the same set of fitted vertices);
* a new matrix with the same sparsity pattern reuses the previous analysis: SuperLU the
  fill-reducing ordering (or a geometric nested-dissection ordering from :mod:`.ordering`),
  CHOLMOD the whole symbolic factorisation;
* with SuperLU, :func:`pcg` solves a matrix *close* to one already factorised (the fairing
  matrix after the Voronoi areas moved a little) with that factorisation as preconditioner: a
  few triangular solves instead of a new factorisation (with CHOLMOD refactorising is cheaper).

Assembling the matrices costs about as much as refactorising them when it goes through SciPy's
sparse products and sums each time: :class:`LowerPattern` fixes the (sorted, lower-triangular
CSC) pattern of a sum of matrices once, and a new matrix of that pattern is then a vector of
values (:class:`LowerMatrix`) that CHOLMOD takes as it is.
"""

from __future__ import annotations

import hashlib
import os

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from appeal.errors import AppealInputError

__all__ = [
    "Factor",
    "LowerMatrix",
    "LowerPattern",
    "SuperLUFactor",
    "CholmodFactor",
    "ReusableSolver",
    "available_backends",
    "default_backend",
    "factorize",
    "pcg",
    "pattern_key",
]

BACKENDS = ("cholmod", "superlu")


def available_backends() -> tuple[str, ...]:
    """The direct solvers that can run here, fastest first."""
    try:
        from cvxopt import cholmod  # noqa: F401
    except ImportError:
        return ("superlu",)
    return BACKENDS


def default_backend() -> str:
    """``$APPEAL_SPARSE_SOLVER`` if set, else the fastest available backend."""
    env = os.environ.get("APPEAL_SPARSE_SOLVER", "").strip().lower()
    if env:
        return _check_backend(env, "APPEAL_SPARSE_SOLVER")
    return available_backends()[0]


def _check_backend(name: str, where: str = "backend") -> str:
    if name not in BACKENDS:
        raise AppealInputError(f"{where}: unknown sparse solver {name!r}; expected one of {', '.join(BACKENDS)}")
    if name not in available_backends():
        raise AppealInputError(
            f"{where}: sparse solver {name!r} needs the 'cvxopt' package (pip install 'appeal-lab[fast]')"
        )
    return name


def pattern_key(matrix: sp.spmatrix) -> bytes:
    """Hash of a sparse matrix's shape and sparsity pattern (CSC)."""
    m = sp.csc_matrix(matrix)
    m.sort_indices()
    h = hashlib.blake2b(digest_size=16)
    h.update(repr(m.shape).encode())
    h.update(np.ascontiguousarray(m.indptr, dtype=np.int64).tobytes())
    h.update(np.ascontiguousarray(m.indices, dtype=np.int64).tobytes())
    return h.digest()


class LowerPattern:
    """The lower triangle (CSC, rows sorted in each column) of a sum of symmetric sparse
    matrices, with every diagonal entry in it: the fixed sparsity pattern of a system whose
    values change (weights, areas) while its structure does not.

    ``matrices`` and ``entries`` (lower ``(rows, cols)``) give the structure. :meth:`positions`
    maps a matrix's lower entries into it (distinct positions: ``values[pos] += data``); a
    matrix of this pattern is a values vector (:meth:`matrix`).
    """

    def __init__(self, n: int, *matrices: sp.spmatrix, entries: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        self.n = int(n)
        rows = [np.arange(self.n, dtype=np.int64)]  # the diagonal
        cols = [rows[0]]
        lowers = []
        for m in matrices:
            lower = _lower_csc(m)
            lowers.append(lower)
            rows.append(lower.indices.astype(np.int64))
            cols.append(np.repeat(np.arange(self.n, dtype=np.int64), np.diff(lower.indptr)))
        n_given = sum(len(r) for r in rows)
        if entries is not None:  # more lower entries (rows, cols)
            rows.append(np.asarray(entries[0], dtype=np.int64))
            cols.append(np.asarray(entries[1], dtype=np.int64))
        r, c = np.concatenate(rows), np.concatenate(cols)
        order = _column_major_order(r, c, self.n)
        k = (c * self.n + r)[order]
        first = np.concatenate([[True], k[1:] != k[:-1]])
        self._set_keys(k[first])
        inverse = np.empty(len(k), dtype=np.int64)
        inverse[order] = np.cumsum(first) - 1
        #: positions of ``entries`` in the pattern
        self.entry_positions = inverse[n_given:]
        #: ``(positions, values)`` of each of ``matrices``' lower entries (as :meth:`positions`)
        self.matrix_positions = []
        at = self.n
        for lower in lowers:
            self.matrix_positions.append((inverse[at : at + lower.nnz], lower.data.copy()))
            at += lower.nnz

    def _set_keys(self, key: np.ndarray) -> None:
        """The structure from sorted, distinct keys ``column * n + row``."""
        self._key = key
        col = self._key // self.n
        self.indices = (self._key - col * self.n).astype(np.int64)
        self.indptr = np.searchsorted(col, np.arange(self.n + 1)).astype(np.int64)
        self.diagonal = self.indptr[:-1]  # the diagonal is the first entry of each column
        self.nnz = len(self._key)

    def leading(self, m: int) -> tuple["LowerPattern", np.ndarray]:
        """The pattern of the leading ``m`` x ``m`` block, and the positions of its entries in
        this pattern (in the block pattern's order)."""
        col = self._key // self.n
        row = self._key - col * self.n
        inside = np.flatnonzero((row < m) & (col < m))
        block = object.__new__(LowerPattern)
        block.n = int(m)
        block._set_keys(col[inside] * m + row[inside])
        block.entry_positions = np.zeros(0, dtype=np.int64)
        block.matrix_positions = []
        return block, inside

    def _keys(self, lower: sp.csc_matrix) -> np.ndarray:
        col = np.repeat(np.arange(lower.shape[1], dtype=np.int64), np.diff(lower.indptr))
        return col * self.n + lower.indices.astype(np.int64)

    def positions(self, matrix: sp.spmatrix) -> tuple[np.ndarray, np.ndarray]:
        """``(positions, values)`` of ``matrix``'s lower entries in this pattern."""
        lower = _lower_csc(matrix)
        k = self._keys(lower)
        pos = np.searchsorted(self._key, k)
        if len(k) and (pos.max(initial=0) >= self.nnz or not np.array_equal(self._key[pos], k)):
            raise ValueError("matrix has entries outside the pattern")
        return pos, lower.data.copy()

    def structure(self) -> sp.csc_matrix:
        """The pattern as a lower-triangular matrix of ones (for orderings)."""
        return self.matrix(np.ones(self.nnz)).lower()

    def matrix(self, values: np.ndarray) -> "LowerMatrix":
        return LowerMatrix(self, np.asarray(values, dtype=np.float64))


class LowerMatrix:
    """A symmetric matrix given by its lower triangle's ``values`` on a :class:`LowerPattern`."""

    def __init__(self, pattern: LowerPattern, values: np.ndarray) -> None:
        self.pattern = pattern
        self.values = values
        self.shape = (pattern.n, pattern.n)

    def lower(self) -> sp.csc_matrix:
        p = self.pattern
        return sp.csc_matrix((self.values, p.indices, p.indptr), shape=self.shape)

    def full(self) -> sp.csr_matrix:
        """The whole symmetric matrix."""
        low = self.lower()
        strict = low.copy()
        strict.data = strict.data.copy()
        strict.data[self.pattern.diagonal] = 0.0
        return (low + strict.T).tocsr()

    def diagonal(self) -> np.ndarray:
        return self.values[self.pattern.diagonal]


def _column_major_order(rows: np.ndarray, cols: np.ndarray, n: int) -> np.ndarray:
    """Permutation sorting entries by column, then row: two stable 16-bit radix sorts when the
    indices fit (a third of a comparison sort's time on a bi-Laplacian's ~10⁶ pairs)."""
    if n <= np.iinfo(np.uint16).max + 1:
        order = np.argsort(rows.astype(np.uint16), kind="stable")
        return order[np.argsort(cols.astype(np.uint16)[order], kind="stable")]
    return np.argsort(cols * n + rows, kind="stable")


def _as_scipy(matrix) -> sp.spmatrix:
    return matrix.full() if isinstance(matrix, LowerMatrix) else matrix


class SuperLUFactor:
    """A SuperLU factorisation of ``P A Pᵀ`` for a symmetric ordering ``P``.

    ``ordering[k]`` is the original index of the unknown placed at position ``k``; it can be
    handed to :func:`factorize` for the next matrix with the same sparsity pattern.
    """

    backend = "superlu"
    #: refactorising costs much more than a few preconditioned CG iterations
    cheap_refactor = False

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

    def refactor(self, matrix: sp.spmatrix) -> "SuperLUFactor":
        """Factorise a matrix with the same sparsity pattern, reusing this ordering."""
        return _superlu(matrix, self.ordering)


def _superlu(matrix: sp.spmatrix, ordering: np.ndarray | None) -> SuperLUFactor:
    matrix = _as_scipy(matrix)
    # symmetric mode with no pivoting (safe for SPD matrices) keeps the fill-reducing ordering
    # intact: about 10x faster and half the fill of the default partial pivoting
    opts = {"diag_pivot_thresh": 0.0, "options": {"SymmetricMode": True}}
    if ordering is None:
        return SuperLUFactor(splu(sp.csc_matrix(matrix), permc_spec="MMD_AT_PLUS_A", **opts), None)
    ordering = np.asarray(ordering, dtype=np.int64)
    m = sp.csr_matrix(matrix)[ordering][:, ordering]
    return SuperLUFactor(splu(sp.csc_matrix(m), permc_spec="NATURAL", **opts), ordering)


class CholmodFactor:
    """CHOLMOD supernodal Cholesky ``P A Pᵀ = L Lᵀ`` (through cvxopt).

    :meth:`refactor` with a matrix of the same pattern redoes only the numeric factorisation,
    in place (this factor then solves the new matrix).
    """

    backend = "cholmod"
    cheap_refactor = True

    def __init__(self, matrix: sp.spmatrix, ordering: np.ndarray | None = None) -> None:
        from cvxopt import cholmod, matrix as cmatrix

        lower = _lower_csc(matrix)
        self._n = lower.shape[0]
        self._pattern = (lower.indptr.copy(), lower.indices.copy())
        self._lower_pattern = matrix.pattern if isinstance(matrix, LowerMatrix) else None
        # cvxopt keeps the values in the same (column-major, sorted) order as a sorted CSC
        # matrix: a refactorisation only replaces them
        self._a = _to_cvxopt(lower)
        # a given ordering is used as it is (callers give nested dissections of meshes): by
        # default CHOLMOD would also compute AMD to compare, half the symbolic analysis's time
        _cholmod_options(given=ordering is not None)
        p = None if ordering is None else cmatrix(np.asarray(ordering, dtype=np.int64).tolist(), tc="i")
        self._f = cholmod.symbolic(self._a, p=p) if p is not None else cholmod.symbolic(self._a)
        self.ordering = ordering
        self._numeric()

    @property
    def shape(self) -> tuple[int, int]:
        return (self._n, self._n)

    def _numeric(self) -> None:
        from cvxopt import cholmod

        _cholmod_options()
        try:
            cholmod.numeric(self._a, self._f)
        except ArithmeticError as exc:  # not positive definite
            raise np.linalg.LinAlgError(f"CHOLMOD: matrix is not positive definite ({exc})") from None

    def refactor(self, matrix: sp.spmatrix) -> "CholmodFactor":
        """Numeric refactorisation when the pattern is unchanged, else a new factor."""
        from cvxopt import matrix as cmatrix

        if isinstance(matrix, LowerMatrix) and matrix.pattern is self._lower_pattern:
            # the values of the very pattern this factor was made for: no conversion, no check
            self._a.V = cmatrix(matrix.values)
            self._numeric()
            return self
        lower = _lower_csc(matrix)
        if lower.shape[0] != self._n or not (
            np.array_equal(lower.indptr, self._pattern[0]) and np.array_equal(lower.indices, self._pattern[1])
        ):
            return CholmodFactor(matrix, self.ordering)
        self._a.V = cmatrix(lower.data)
        self._numeric()
        return self

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``A⁻¹ rhs`` for one (N,) or several (N, K) right-hand sides.

        Several columns go through CHOLMOD's sparse-right-hand-side solve, which takes them all
        at once: cvxopt's dense ``solve`` runs one triangular solve pair per column (3 columns:
        12 vs 21 ms on the 29k fairing system, the same numbers to 1e-14)."""
        from cvxopt import cholmod, matrix as cmatrix, sparse

        b = np.asarray(rhs, dtype=np.float64)
        b2 = np.asfortranarray(b.reshape(len(b), -1))
        if b2.shape[1] == 1:
            x = cmatrix(b2)
            cholmod.solve(self._f, x)
            return np.asarray(x).reshape(b.shape)
        xs = cholmod.spsolve(self._f, sparse(cmatrix(b2)))
        out = np.zeros(b2.shape)
        out[np.asarray(xs.I).ravel(), np.asarray(xs.J).ravel()] = np.asarray(xs.V).ravel()
        return out.reshape(b.shape)


#: the public name: whichever factor :func:`factorize` returns
Factor = SuperLUFactor | CholmodFactor


def _cholmod_options(given: bool = False) -> None:
    from cvxopt import cholmod

    cholmod.options["supernodal"] = 2  # always supernodal (BLAS-3 blocks)
    cholmod.options["postorder"] = True
    cholmod.options["nmethods"] = 1 if given else 0  # the given ordering alone, or CHOLMOD's choice


def _lower_csc(matrix: sp.spmatrix) -> sp.csc_matrix:
    if isinstance(matrix, LowerMatrix):
        return matrix.lower()
    lower = sp.tril(sp.csc_matrix(matrix), format="csc")
    lower.sum_duplicates()
    lower.sort_indices()
    return lower


def _to_cvxopt(lower: sp.csc_matrix):
    from cvxopt import matrix as cmatrix, spmatrix

    # cvxopt matrices from NumPy arrays are buffer copies; NumPy arrays passed to spmatrix
    # directly are read element by element
    col = np.repeat(np.arange(lower.shape[1], dtype=np.int64), np.diff(lower.indptr))
    return spmatrix(cmatrix(np.ascontiguousarray(lower.data, dtype=np.float64)),
                    cmatrix(lower.indices.astype(np.int64)), cmatrix(col), size=lower.shape)


def factorize(matrix: sp.spmatrix, ordering: np.ndarray | None = None, backend: str | None = None) -> Factor:
    """Factorisation of a sparse symmetric positive-definite matrix.

    Parameters
    ----------
    matrix : sparse (N, N)
    ordering : (N,) int array, optional
        A symmetric fill-reducing ordering (e.g. ``previous_factor.ordering`` for a matrix of
        the same pattern, or :func:`~stimulus_engine.correspondence.ordering.nested_dissection`);
        by default SuperLU's minimum degree on ``A + Aᵀ`` or CHOLMOD's own choice (AMD).
    backend : {"cholmod", "superlu"}, optional
        Default: :func:`default_backend`.

    Returns
    -------
    SuperLUFactor or CholmodFactor
        With ``solve(rhs)`` and ``refactor(matrix)``.
    """
    backend = default_backend() if backend is None else _check_backend(backend)
    if backend == "cholmod":
        return CholmodFactor(matrix, ordering)
    return _superlu(matrix, ordering)


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
    a = sp.csr_matrix(_as_scipy(matrix))
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
    factorisation when refactorising is expensive (SuperLU).
    """

    def __init__(self, ordering: np.ndarray | None = None, backend: str | None = None) -> None:
        self.backend = default_backend() if backend is None else _check_backend(backend)
        self._key: bytes | None = None
        self._lu: Factor | None = None
        self.ordering = ordering
        #: a caller's fixed matrix pattern (:class:`LowerPattern`), kept with the factorisation
        #: that was analysed for it
        self.pattern: LowerPattern | None = None
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
        # the callers change weights, not the pattern: reuse the ordering / symbolic analysis
        if self._lu is not None:
            self._lu = self._lu.refactor(matrix)
        else:
            self._lu = factorize(matrix, self.ordering, self.backend)
        self.ordering = self._lu.ordering
        self._key = key
        self.factorizations += 1

    def solve(
        self, key: bytes, build, rhs: np.ndarray, near: bool = False, x0: np.ndarray | None = None, rtol: float = 1e-10
    ) -> np.ndarray:
        """``build()`` makes the matrix when ``key`` differs from the last call's.

        With ``near=True`` and a backend whose factorisations are expensive (SuperLU), a new
        matrix is first solved by :func:`pcg` preconditioned with the current factorisation
        (starting from ``x0``, to relative residual ``rtol``); only if that does not converge
        quickly is it factorised.
        """
        rhs = np.asarray(rhs, dtype=np.float64)
        if key == self._key and self._lu is not None:
            self.reuses += 1
            return self._lu.solve(rhs)
        matrix = build()
        if near and self._lu is not None and not self._lu.cheap_refactor:
            x, it, ok = pcg(matrix, rhs, self._lu.solve, x0, rtol=rtol)
            self.pcg_iterations += it
            if ok:
                self.pcg_solves += 1
                return x
        self._factor(matrix, key)
        return self._lu.solve(rhs)
