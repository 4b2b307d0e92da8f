"""How similar an actor's frames are to a rig's blendshapes (thesis §4.3.1–4.3.2, Eqs 4.5–4.8).

All inputs are sparse *delta* representations: a blendshape ``δs_k`` or a frame ``δa_f`` is the
(M, 3) displacement of the M markers from the neutral, flattened to 3M.

- :func:`correlations` — Eq. 4.5: Pearson's coefficient about the neutral (the mean replaced by
  the neutral expression), i.e. the cosine between the two displacement vectors.
- :func:`trust_values` — Eq. 4.6: a blendshape is trusted when it is unlike the blendshapes that
  move more than it does.
- :func:`contrast` — Eq. 4.7: a sigmoid of steepness ``r`` (15 in the thesis) that pushes high
  correlations up and low ones down.
- :func:`similarity` — Eq. 4.8: the trust-weighted mix of the positive correlation and its
  contrast-enhanced value, the weights of the matching energy.
- :func:`key_frames` — §4.3.2: each blendshape's similarity row smoothed by a three-frame
  Gaussian, the rows summed, and the local peaks of that cumulative curve kept.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import find_peaks

__all__ = ["contrast", "correlations", "key_frames", "similarity", "trust_values"]

#: Steepness of the contrast sigmoid (Eq. 4.7; "set to 15 in all our examples").
CONTRAST_STEEPNESS = 15.0


def _flat(d: np.ndarray) -> np.ndarray:
    d = np.asarray(d, np.float64)
    return d.reshape(len(d), -1)


def correlations(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Eq. 4.5: ``ρ = δa·δb / (|δa| |δb|)`` for every pair of rows of ``a`` (P, M, 3) and ``b`` (Q, M, 3).

    Returns (P, Q); a zero displacement correlates 0 with everything.

    Examples
    --------
    >>> correlations(np.array([[[1.0, 0, 0]]]), np.array([[[2.0, 0, 0]], [[0, 1.0, 0]], [[-1.0, 0, 0]]]))
    array([[ 1.,  0., -1.]])
    """
    a, b = _flat(a), _flat(b)
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    num = a @ b.T
    den = np.outer(na, nb)
    return np.divide(num, den, out=np.zeros_like(num), where=den > 0)


def trust_values(blendshapes: np.ndarray) -> np.ndarray:
    """Eq. 4.6: ``t_k = 1 − Σ_{i<k} ρ⁺_ki / max_k Σ_{i<k} ρ⁺_ki`` with the blendshapes ordered by
    decreasing displacement ``|δs_k|`` (returned in the input's order).

    The blendshape that moves most has ``t = 1``; one that resembles larger blendshapes gets a
    low trust.
    """
    s = _flat(blendshapes)
    order = np.argsort(-np.linalg.norm(s, axis=1), kind="stable")
    rho = np.maximum(correlations(blendshapes[order], blendshapes[order]), 0.0)
    sums = np.tril(rho, k=-1).sum(axis=1)
    top = sums.max()
    t_sorted = 1.0 - sums / top if top > 0 else np.ones(len(s))
    out = np.empty(len(s))
    out[order] = t_sorted
    return out


def contrast(rho: np.ndarray, r: float = CONTRAST_STEEPNESS) -> np.ndarray:
    """Eq. 4.7: ``χ(ρ) = e^{rρ⁺} / (e^{r/2} + e^{rρ⁺})`` (a logistic curve through ½ at ρ⁺ = ½).

    Examples
    --------
    >>> np.round(contrast(np.array([0.0, 0.5, 1.0])), 4)
    array([6.000e-04, 5.000e-01, 9.994e-01])
    """
    p = np.maximum(np.asarray(rho, np.float64), 0.0)
    return 1.0 / (1.0 + np.exp(r / 2 - r * p))


def similarity(blendshapes: np.ndarray, frames: np.ndarray, r: float = CONTRAST_STEEPNESS) -> np.ndarray:
    """Eq. 4.8: ``ρ̃_kf = (1 − t_k) ρ⁺_kf + t_k χ(ρ⁺_kf)``, shape (K, F).

    Parameters
    ----------
    blendshapes : (K, M, 3) array
        The rig's sparse delta blendshapes ``δs_k``.
    frames : (F, M, 3) array
        The actor's marker displacements ``δa_f``.
    r : float
        Steepness of the contrast sigmoid.
    """
    rho = np.maximum(correlations(blendshapes, frames), 0.0)
    t = trust_values(blendshapes)[:, None]
    return (1.0 - t) * rho + t * contrast(rho, r)


def key_frames(sim: np.ndarray, sigma: float = 0.5) -> np.ndarray:
    """§4.3.2: indices of the key expressions in a (K, F) similarity table.

    Each row is low-pass filtered with a Gaussian three frames wide (``sigma`` 0.5 frames:
    the kernel's weights beyond one frame are below 2 %), the rows are summed, and the local
    peaks of that cumulative curve are returned (both ends count when they are higher than
    their neighbour). A sequence without peaks (constant) gives its middle frame.
    """
    sim = np.asarray(sim, np.float64)
    cum = gaussian_filter1d(sim, sigma, axis=1, mode="nearest").sum(axis=0)
    padded = np.concatenate([[-np.inf], cum, [-np.inf]])
    peaks, _ = find_peaks(padded, plateau_size=1)
    peaks = peaks - 1
    return peaks if len(peaks) else np.array([len(cum) // 2])
