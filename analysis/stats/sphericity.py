"""Sphericity: Mauchly's test and the Greenhouse–Geisser / Huynh–Feldt epsilons (as car)."""

from __future__ import annotations

import numpy as np
from scipy import special

__all__ = ["mauchly", "gg_epsilon", "hf_epsilon", "is_singular", "error_rank", "sphericity"]

#: Relative tolerance below which a quantity that is zero in exact arithmetic is taken as zero.
RTOL = 1e-9


def error_rank(S: np.ndarray) -> int:
    """Numerical rank of the error SSP matrix ``S`` (0 for an all-zero or empty matrix)."""
    d = S.shape[0]
    scale = np.abs(S).max() if d else 0.0
    if d == 0 or scale == 0:
        return 0
    return int(np.linalg.matrix_rank(S, tol=scale * d * np.finfo(float).eps * 1e3))


def is_singular(S: np.ndarray) -> bool:
    """True when the error SSP matrix ``S`` is rank-deficient (car then skips Mauchly)."""
    d = S.shape[0]
    return d == 0 or error_rank(S) < d


def gg_epsilon(S: np.ndarray) -> float:
    """Greenhouse–Geisser epsilon of an error SSP matrix in an orthonormal contrast basis.

    ``(tr S)² / (d · tr S²)`` — the trace formula, also defined when ``S`` is singular
    (more effect df than error df; with one error df it is the lower bound 1/d). NaN for
    one-df effects and for ``S = 0`` (no error variance).
    """
    d = S.shape[0]
    ss = float(np.sum(S * S))
    if d < 2 or ss == 0:
        return float("nan")
    tr = float(np.trace(S))
    return tr * tr / (d * ss)


def hf_epsilon(gg: float, error_df: float, d: int) -> float:
    """Huynh–Feldt epsilon from GG as car computes it (not capped at 1).

    ``((e + 1)·d·ε_GG − 2) / (d·(e − d·ε_GG))`` with ``e`` error df. NaN where that is
    undefined: one-df effects, an undefined GG ε, and a denominator of zero. The latter
    happens whenever ``e = 1`` (two participants and no between factor: ε_GG = 1/d, so
    the formula is 0/0) and, more rarely, when the error SSP matrix has rank ``e < d``
    with equal non-zero eigenvalues.
    """
    if d < 2 or not np.isfinite(gg):
        return float("nan")
    den = d * (error_df - d * gg)
    if den <= RTOL * d * error_df:
        return float("nan")
    return ((error_df + 1) * d * gg - 2) / den


def mauchly(S: np.ndarray, error_df: float, n_cells: int) -> tuple[float, float]:
    """Mauchly's W and its p value exactly as ``car:::summary.Anova.mlm`` computes them.

    Parameters
    ----------
    S : ndarray, shape (d, d)
        Error SSP matrix of the effect in an orthonormal contrast basis.
    error_df : float
        Error degrees of freedom of the between-subject model (n - rank(X)).
    n_cells : int
        Number of within cells of the whole design (car uses it in its second-order
        correction term).

    Returns
    -------
    W, p : float
        NaN for one-df effects and for singular ``S`` (always so with fewer error df
        than effect df).
    """
    d = S.shape[0]
    if d < 2 or error_df < d or is_singular(S):
        return float("nan"), float("nan")
    sign, logdet = np.linalg.slogdet(S)
    if sign <= 0:
        return float("nan"), float("nan")
    logW = logdet - d * np.log(np.trace(S) / d)
    n = error_df
    rho = 1 - (2 * d**2 + d + 2) / (6 * d * n)
    w2 = (d + 2) * (d - 1) * (d - 2) * (2 * d**3 + 6 * d**2 + 3 * n_cells + 2) / (288 * (n * d * rho) ** 2)
    z = -n * rho * logW
    f = d * (d + 1) / 2 - 1
    p1 = special.chdtrc(f, z)
    p2 = special.chdtrc(f + 4, z)
    return float(np.exp(logW)), float(p1 + w2 * (p2 - p1))


def sphericity(S: np.ndarray, error_df: int, n_cells: int) -> tuple[float, float, float, float, str]:
    """Mauchly's W and p, GG and HF ε of one within effect, and a note on what is undefined.

    Parameters
    ----------
    S : ndarray (d, d), d >= 2
        The effect's error SSP matrix in the orthonormal within basis.
    error_df : int
        Error df of the between-subject model (n − rank X).
    n_cells : int
        Within cells of the whole design (for Mauchly's second-order term).

    Returns
    -------
    W, p_W, gg, hf : float
        NaN where undefined (see :mod:`analysis.stats.sphericity`).
    note : str
        Empty when everything is defined; otherwise why not, in words.
    """
    d = S.shape[0]
    gg = gg_epsilon(S)
    W, pW = mauchly(S, error_df, n_cells)
    hf = hf_epsilon(gg, error_df, d)
    rank = min(error_rank(S), error_df)
    notes = []
    if rank == 0:
        return W, pW, gg, hf, "Mauchly, GG and HF ε undefined"
    if rank < d:
        why = (f"{error_df} error df < {d} effect df" if error_df < d else f"error SSP matrix of rank {rank} < {d}")
        notes.append(f"Mauchly undefined ({why}); ε from the trace formula (car: NA)")
    if np.isnan(hf):
        notes.append("HF ε undefined (0/0 with 1 error df)" if error_df == 1 else
                     "HF ε undefined (error df = d·GG ε)")
    return W, pW, gg, hf, "; ".join(notes)
