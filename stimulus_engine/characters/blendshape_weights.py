"""Blendshape weights of marker frames by Eq. 4.16, scale-free and non-negative (thesis §4.4).

The solver behind :mod:`~stimulus_engine.characters.retarget` (its notes say where it departs from
the thesis and why), also used by the range-of-motion alignment to explain training frames
(:mod:`~stimulus_engine.characters.blendshape_transfer`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["RETARGET_MU", "RETARGET_NU", "retarget_energy", "retarget_frames"]

#: Weight of the geometric prior, relative to the fit (module notes, 1). Measured on synthetic actors
#: (0.2 mm noise, the actor's true blendshapes): weight RMS 0.040 at 0.01, 0.048 at 0.03, 0.07–0.08 at 0.1,
#: 0.10–0.11 at 0.3 (a prior shrinks every weight alike; it matters where blendshapes are imperfect).
RETARGET_MU = 0.01
#: Weight of the L1 sparsity, relative to the fit: at 0.2 the RMS was 0.040–0.043 (0.067 without it, the
#: cross-talk of similar blendshapes; 0.059 at 0.6, 0.078 at 1.0, each weight then lowered by ν/2K).
RETARGET_NU = 0.2


def _system(blendshapes: np.ndarray, prior: np.ndarray | None, mu: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The scale-free normal matrix ``BᵀB/(Mσ²) + μ P/p̄`` (K × K), ``B`` flattened (K, 3M), and ``Mσ²``."""
    b = np.asarray(blendshapes, np.float64)
    k = b.shape[0]
    bf = b.reshape(k, -1)
    scale = float(np.mean(np.sum(bf ** 2, axis=1)))  # M σ²: a typical blendshape's squared motion
    if not scale > 0:
        raise ValueError("blendshapes: every blendshape is zero at the markers")
    gram = bf @ bf.T / scale
    if prior is not None and mu:
        p = np.asarray(prior, np.float64)
        gram = gram + mu * p / max(float(np.mean(np.diag(p))), 1e-300)
    return gram, bf, scale


def retarget_energy(weights: np.ndarray, frames: np.ndarray, blendshapes: np.ndarray, prior: np.ndarray | None,
                    mu: float = RETARGET_MU, nu: float = RETARGET_NU) -> np.ndarray:
    """E_Retarget (Eq. 4.16, scale-free: module notes) of each frame's ``weights`` (F, K): the value
    the solver minimises."""
    w = np.atleast_2d(np.asarray(weights, np.float64))
    gram, bf, scale = _system(blendshapes, prior, mu)
    a = np.asarray(frames, np.float64).reshape(len(w), -1)
    fit = np.sum((a - w @ bf) ** 2, axis=1) / scale
    pri = np.einsum("fk,kl,fl->f", w, gram - bf @ bf.T / scale, w)
    return fit + pri + nu * np.abs(w).sum(axis=1) / len(bf)


def retarget_frames(frames: np.ndarray, blendshapes: np.ndarray, prior: np.ndarray | None = None, *,
                    mu: float = RETARGET_MU, nu: float = RETARGET_NU, nonnegative: bool = True,
                    iterations: int = 30, tol: float = 1e-6, eps: float = 1e-4) -> np.ndarray:
    """Blendshape weights of each frame by Eq. 4.16 (scale-free, module notes).

    Parameters
    ----------
    frames : (F, M, 3) array
        Marker displacements from the actor's neutral, ``δa_f``.
    blendshapes : (K, M, 3) array
        The actor's personalised sparse delta blendshapes ``δb_k``.
    prior : (K, K) array, optional
        :func:`bending_prior` of the target rig (None: no geometric prior).
    mu, nu : float
        Weights of the prior and of the sparsity term, relative to the fit.
    nonnegative : bool
        Weights ``w ≥ 0``, solved exactly by non-negative least squares (default); False: the
        thesis's unconstrained problem by iteratively reweighted least squares.
    iterations : int
        Most reweighting rounds (``nonnegative=False``).
    tol : float
        Stop when no weight changes by more than this (``nonnegative=False``).
    eps : float
        Floor of ``|w_k|`` in the reweighting (``nonnegative=False``).

    Returns
    -------
    (F, K) array
    """
    from scipy.optimize import nnls

    gram, bf, scale = _system(blendshapes, prior, mu)
    k = len(bf)
    a = np.asarray(frames, np.float64).reshape(-1, bf.shape[1])
    rhs = a @ bf.T / scale  # (F, K)
    gram = gram + 1e-9 * np.trace(gram) / k * np.eye(k)
    if nonnegative:  # min wᵀGw − 2(r − ν/2K)ᵀw, w ≥ 0  ==  min ‖Rw − R⁻ᵀ(r − ν/2K)‖², w ≥ 0 with G = RᵀR
        upper = np.linalg.cholesky(gram).T
        y = np.linalg.solve(upper.T, (rhs - nu / (2 * k)).T).T
        return np.array([nnls(upper, row)[0] for row in y]).reshape(len(a), k)
    w = np.linalg.solve(gram, rhs.T).T
    if nu == 0:
        return w
    half = nu / (2 * k)
    idx = np.arange(k)
    for _ in range(iterations):
        sys = np.broadcast_to(gram, (len(a), k, k)).copy()
        sys[:, idx, idx] += half / np.maximum(np.abs(w), eps)
        new = np.linalg.solve(sys, rhs[..., None])[..., 0]
        done = np.max(np.abs(new - w)) < tol
        w = new
        if done:
            break
    return w
