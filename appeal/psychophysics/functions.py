"""Psychometric function families in psignifit 4's parameterisation.

Every family is a sigmoid ``S(x; m, w)`` with threshold ``m`` (the stimulus at which the sigmoid
part reaches ``pc``, 0.5 by default) and width ``w`` (the stimulus range over which it rises from
``alpha`` to ``1 - alpha``, 5 % to 95 % by default), as in Schütt, Harmeling, Macke & Wichmann
(2016), *Vision Research* 122, 105–123. The psychometric function adds a guess rate ``gamma`` and a
lapse rate ``lam``::

    psi(x) = gamma + (1 - gamma - lam) * S(x; m, w)

Families: ``"logistic"``, ``"norm"`` (cumulative Gaussian) and ``"weibull"`` (a Gumbel sigmoid on
log stimulus: ``x`` must be positive and ``m``, ``w`` are in natural-log units, as psignifit's
Weibull is a Gumbel on the log axis).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import special, stats

from appeal.errors import AppealInputError

__all__ = ["FAMILIES", "sigmoid", "sigmoid_inverse", "psi", "psi_inverse", "slope", "check_family"]

#: The families this module knows.
FAMILIES: tuple[str, ...] = ("logistic", "norm", "weibull")


def check_family(family: str) -> str:
    """Return ``family`` if it is known, else raise a one-line :class:`AppealInputError`."""
    if family not in FAMILIES:
        raise AppealInputError(f"psychometric family '{family}' is not one of {', '.join(FAMILIES)}")
    return family


def _standardise(x: NDArray, family: str) -> NDArray:
    if family == "weibull":
        x = np.asarray(x, dtype=float)
        if np.any(x <= 0):
            raise AppealInputError("the Weibull family needs positive stimulus levels (it is a Gumbel on log x)")
        return np.log(x)
    return np.asarray(x, dtype=float)


def _z(u: NDArray, m: ArrayLike, w: ArrayLike, family: str, pc: float, alpha: float) -> NDArray:
    """The argument of the standard distribution for standardised stimulus ``u``."""
    u, m, w = np.asarray(u, float), np.asarray(m, float), np.asarray(w, float)
    if family == "norm":
        c = stats.norm.ppf(1 - alpha) - stats.norm.ppf(alpha)
        return c * (u - m) / w + stats.norm.ppf(pc)
    if family == "logistic":
        c = 2 * np.log(1 / alpha - 1)
        return c * (u - m) / w - np.log(1 / pc - 1)
    c = np.log(-np.log(alpha)) - np.log(-np.log(1 - alpha))
    return c * (u - m) / w + np.log(-np.log(1 - pc))


def sigmoid(x: ArrayLike, threshold: ArrayLike, width: ArrayLike, family: str = "logistic",
            pc: float = 0.5, alpha: float = 0.05) -> NDArray:
    """The sigmoid part ``S(x; m, w)`` of a psychometric function, in ``[0, 1]``.

    Parameters
    ----------
    x : array_like
        Stimulus levels (positive for ``"weibull"``).
    threshold, width : array_like
        ``m`` and ``w``; broadcast against ``x``.
    family : str
        One of :data:`FAMILIES`.
    pc : float
        The value of ``S`` at the threshold (psignifit's ``thresh_PC``).
    alpha : float
        ``w`` spans ``S`` from ``alpha`` to ``1 - alpha`` (psignifit's ``width_alpha``).

    Returns
    -------
    numpy.ndarray
    """
    check_family(family)
    z = _z(_standardise(x, family), threshold, width, family, pc, alpha)
    if family == "norm":
        return special.ndtr(z)
    if family == "logistic":
        return special.expit(z)
    return -np.expm1(-np.exp(np.minimum(z, 700.0)))


def sigmoid_inverse(p: ArrayLike, threshold: ArrayLike, width: ArrayLike, family: str = "logistic",
                    pc: float = 0.5, alpha: float = 0.05) -> NDArray:
    """The stimulus at which ``S`` equals ``p`` (in ``(0, 1)``); the inverse of :func:`sigmoid`."""
    check_family(family)
    p = np.asarray(p, float)
    m, w = np.asarray(threshold, float), np.asarray(width, float)
    if family == "norm":
        c = stats.norm.ppf(1 - alpha) - stats.norm.ppf(alpha)
        u = m + w * (special.ndtri(p) - stats.norm.ppf(pc)) / c
    elif family == "logistic":
        c = 2 * np.log(1 / alpha - 1)
        u = m + w * (special.logit(p) + np.log(1 / pc - 1)) / c
    else:
        c = np.log(-np.log(alpha)) - np.log(-np.log(1 - alpha))
        u = m + w * (np.log(-np.log1p(-p)) - np.log(-np.log(1 - pc))) / c
    return np.exp(u) if family == "weibull" else u


def psi(x: ArrayLike, threshold: ArrayLike, width: ArrayLike, gamma: ArrayLike = 0.5, lam: ArrayLike = 0.0,
        family: str = "logistic", pc: float = 0.5, alpha: float = 0.05) -> NDArray:
    """The psychometric function ``gamma + (1 - gamma - lam) * S(x; m, w)``.

    Parameters
    ----------
    x, threshold, width : array_like
        As in :func:`sigmoid`.
    gamma : array_like
        Guess rate (``1/n`` for n-AFC; 0.5 for 2AFC).
    lam : array_like
        Lapse rate.
    family, pc, alpha
        As in :func:`sigmoid`.

    Returns
    -------
    numpy.ndarray
        The probability of a correct (or "yes") response.
    """
    gamma, lam = np.asarray(gamma, float), np.asarray(lam, float)
    return gamma + (1 - gamma - lam) * sigmoid(x, threshold, width, family, pc, alpha)


def psi_inverse(p: ArrayLike, threshold: ArrayLike, width: ArrayLike, gamma: ArrayLike = 0.5,
                lam: ArrayLike = 0.0, family: str = "logistic", pc: float = 0.5, alpha: float = 0.05) -> NDArray:
    """The stimulus at which the psychometric function equals ``p`` (e.g. 0.75 correct in 2AFC).

    ``p`` must lie strictly between ``gamma`` and ``1 - lam``.
    """
    gamma, lam, p = np.asarray(gamma, float), np.asarray(lam, float), np.asarray(p, float)
    if np.any((p <= gamma) | (p >= 1 - lam)):
        raise AppealInputError(f"percent correct {p} is outside the function's range ({gamma}, {1 - lam})")
    return sigmoid_inverse((p - gamma) / (1 - gamma - lam), threshold, width, family, pc, alpha)


def slope(x: ArrayLike, threshold: ArrayLike, width: ArrayLike, gamma: ArrayLike = 0.5, lam: ArrayLike = 0.0,
          family: str = "logistic", pc: float = 0.5, alpha: float = 0.05, h: float = 1e-6) -> NDArray:
    """The derivative of the psychometric function at ``x`` (central difference, step ``h``)."""
    x = np.asarray(x, float)
    return (psi(x + h, threshold, width, gamma, lam, family, pc, alpha)
            - psi(x - h, threshold, width, gamma, lam, family, pc, alpha)) / (2 * h)
