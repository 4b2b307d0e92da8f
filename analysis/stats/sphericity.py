"""Sphericity: Mauchly's test and the Greenhouse–Geisser / Huynh–Feldt epsilons (as car)."""

from __future__ import annotations

import numpy as np
from scipy import special

__all__ = ["mauchly", "gg_epsilon", "hf_epsilon", "is_singular"]


def is_singular(S: np.ndarray) -> bool:
    """True when the error SSP matrix ``S`` is rank-deficient (car then skips Mauchly)."""
    d = S.shape[0]
    if d == 0:
        return True
    tol = np.abs(S).max() * d * np.finfo(float).eps * 1e3
    return bool(np.linalg.matrix_rank(S, tol=tol) < d)


def gg_epsilon(S: np.ndarray) -> float:
    """Greenhouse–Geisser epsilon of an error SSP matrix in an orthonormal contrast basis.

    ``(tr S)² / (d · tr S²)`` — the trace formula, also defined when ``S`` is singular
    (more effect df than error df). NaN for one-df effects.
    """
    d = S.shape[0]
    if d < 2:
        return float("nan")
    tr = np.trace(S)
    return float(tr * tr / (d * np.sum(S * S)))


def hf_epsilon(gg: float, error_df: float, d: int) -> float:
    """Huynh–Feldt epsilon from GG as car computes it (not capped at 1)."""
    if d < 2 or not np.isfinite(gg):
        return float("nan")
    return float(((error_df + 1) * d * gg - 2) / (d * (error_df - d * gg)))


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
        NaN for one-df effects and for singular ``S``.
    """
    d = S.shape[0]
    if d < 2 or is_singular(S):
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
