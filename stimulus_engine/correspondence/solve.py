"""Sparse symmetric solves with factorisation reuse.

SuperLU with the ``MMD_AT_PLUS_A`` ordering is as fast as CHOLMOD on these bi-Laplacian
systems (~20k unknowns) and ships with SciPy. :class:`ReusableSolver` keeps the last
factorisation and reuses it while the matrix is unchanged (same stiffness weight and the same
set of fitted vertices), counting factorisations and reuses for the stage report.
"""

from __future__ import annotations

import hashlib

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

__all__ = ["ReusableSolver", "factorize"]


def factorize(matrix: sp.spmatrix):
    """SuperLU factorisation of a sparse symmetric positive-definite matrix.

    Symmetric mode with no pivoting (safe for SPD matrices) keeps the fill-reducing ordering
    intact: about 10x faster and half the fill of the default partial pivoting.
    """
    return splu(
        sp.csc_matrix(matrix),
        permc_spec="MMD_AT_PLUS_A",
        diag_pivot_thresh=0.0,
        options={"SymmetricMode": True},
    )


class ReusableSolver:
    """Solve ``H x = b`` for a sequence of matrices, refactorising only when ``key`` changes."""

    def __init__(self) -> None:
        self._key: bytes | None = None
        self._lu = None
        self.factorizations = 0
        self.reuses = 0

    @staticmethod
    def make_key(*parts) -> bytes:
        h = hashlib.blake2b(digest_size=16)
        for p in parts:
            h.update(np.ascontiguousarray(p).tobytes() if isinstance(p, np.ndarray) else repr(p).encode())
        return h.digest()

    def solve(self, key: bytes, build, rhs: np.ndarray) -> np.ndarray:
        """``build()`` makes the matrix when ``key`` differs from the last call's."""
        if key != self._key or self._lu is None:
            self._lu = factorize(build())
            self._key = key
            self.factorizations += 1
        else:
            self.reuses += 1
        return self._lu.solve(np.asarray(rhs, dtype=np.float64))
