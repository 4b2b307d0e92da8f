"""Per-frame retargeting: marker (or vertex) trajectories to blendshape weights (thesis §4.4).

For every frame ``f`` the weights minimise (Eq. 4.16)

``E_Retarget(w) = 1/M ‖δa_f − Σ_k w_k δb_k‖² + μ/N ‖L δV w‖² + ν/K ‖w‖₁``

- the fit (Eq. 4.2) in the actor's space, with the actor's personalised sparse blendshapes
  ``δb_k`` (:mod:`~stimulus_engine.characters.blendshape_transfer`);
- the geometric prior (Eqs 4.14–4.15) in the rig's space: the bending of the posed rig, ``L``
  the cotangent Laplacian of the rig's mesh and ``δV`` its dense delta blendshapes; only the
  K × K matrix ``(LδV)ᵀ(LδV)/N`` is kept (:func:`bending_prior`), as the thesis pre-computes ``LδV``;
- sparsity in weight space, the L1 norm, solved by iteratively reweighted least squares:
  ``|w_k| ≈ w_k² / |w_k⁽ⁱ⁾|`` turns each iteration into one K × K linear system.

μ = 0.3 and ν = 0.6 are the thesis's values for markers in centimetres and a rig scaled to the
actor's head. All frames are solved together (a stack of K × K systems per iteration).
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.characters.rig import FaceRig

__all__ = ["RETARGET_MU", "RETARGET_NU", "bending_prior", "retarget_energy", "retarget_frames", "retarget_performance"]

#: The thesis's weights of the geometric prior and the sparsity term (§4.4).
RETARGET_MU = 0.3
RETARGET_NU = 0.6


def bending_prior(rig: FaceRig, names: list[str]) -> np.ndarray:
    """``(LδV)ᵀ(LδV) / N`` (K × K) of ``rig``'s blendshapes ``names`` (Eq. 4.15), ``L`` the
    cotangent Laplacian of its neutral mesh."""
    from stimulus_engine.correspondence.laplacian import cotangent_laplacian

    lap = cotangent_laplacian(rig.vertices, rig.faces)
    ldv = np.stack([(lap @ rig.blendshapes[n]).ravel() for n in names], axis=1)  # (3N, K)
    return ldv.T @ ldv / len(rig.vertices)


def retarget_energy(weights: np.ndarray, frames: np.ndarray, blendshapes: np.ndarray, prior: np.ndarray | None,
                    mu: float = RETARGET_MU, nu: float = RETARGET_NU) -> np.ndarray:
    """E_Retarget (Eq. 4.16) of each frame's ``weights`` (F, K): the value the solver minimises."""
    w = np.atleast_2d(weights)
    b = np.asarray(blendshapes, np.float64).reshape(len(blendshapes), -1)
    a = np.asarray(frames, np.float64).reshape(len(w), -1)
    m, k = b.shape[1] // 3, b.shape[0]
    fit = np.sum((a - w @ b) ** 2, axis=1) / m
    pri = 0.0 if prior is None else mu * np.einsum("fk,kl,fl->f", w, prior, w)
    return fit + pri + nu * np.abs(w).sum(axis=1) / k


def retarget_frames(frames: np.ndarray, blendshapes: np.ndarray, prior: np.ndarray | None = None, *,
                    mu: float = RETARGET_MU, nu: float = RETARGET_NU, iterations: int = 30,
                    tol: float = 1e-6, eps: float = 1e-4) -> np.ndarray:
    """Blendshape weights of each frame by Eq. 4.16 (IRLS for the L1 term).

    Parameters
    ----------
    frames : (F, M, 3) array
        Marker displacements from the actor's neutral, ``δa_f``.
    blendshapes : (K, M, 3) array
        The actor's personalised sparse delta blendshapes ``δb_k``.
    prior : (K, K) array, optional
        :func:`bending_prior` of the target rig (None: no geometric prior).
    mu, nu : float
        Weights of the prior and of the sparsity term.
    iterations : int
        Most reweighting rounds.
    tol : float
        Stop when no weight changes by more than this.
    eps : float
        Floor of ``|w_k|`` in the reweighting (a weight at zero stays solvable).

    Returns
    -------
    (F, K) array
    """
    b = np.asarray(blendshapes, np.float64)
    k, m = b.shape[0], b.shape[1]
    bf = b.reshape(k, -1)
    a = np.asarray(frames, np.float64).reshape(-1, m * 3)
    gram = bf @ bf.T / m
    if prior is not None:
        gram = gram + mu * np.asarray(prior, np.float64)
    rhs = a @ bf.T / m  # (F, K)
    w = np.linalg.solve(gram + 1e-9 * np.trace(gram) / k * np.eye(k), rhs.T).T
    if nu == 0:
        return w
    half = nu / (2 * k)
    for _ in range(iterations):
        sys = np.broadcast_to(gram, (len(a), k, k)).copy()
        idx = np.arange(k)
        sys[:, idx, idx] += half / np.maximum(np.abs(w), eps)
        new = np.linalg.solve(sys, rhs[..., None])[..., 0]
        done = np.max(np.abs(new - w)) < tol
        w = new
        if done:
            break
    return w


def retarget_performance(rig: FaceRig, neutral: np.ndarray, positions: np.ndarray, vertices: np.ndarray, *,
                         transfer: str = "aligned", mu: float = RETARGET_MU, nu: float = RETARGET_NU) -> np.ndarray:
    """An actor's marker performance as weights of ``rig``'s blendshapes (``sorted(rig.blendshapes)``).

    The actor's sparse blendshapes come from ``rig``'s by ``transfer``: ``aligned`` (E_Align with
    the performance itself as the training sequence, §4.3), ``rbf`` (the thesis's initial guesses)
    (deformation transfer needs the actor's whole mesh, which markers do not give); then every
    frame is retargeted by Eq. 4.16 with the rig's bending prior.

    Parameters
    ----------
    rig : FaceRig
    neutral : (M, 3) array
        The actor's neutral marker positions.
    positions : (F, M, 3) array
        The performance, marker positions.
    vertices : (M,) int array
        The rig vertex under each marker.
    transfer : {"aligned", "rbf"}
    mu, nu : float
        Eq. 4.16's weights.

    Returns
    -------
    (F, K) array
    """
    from stimulus_engine.characters.blendshape_transfer import align_blendshapes, rbf_warp, warp_deltas

    if transfer not in ("aligned", "rbf"):
        raise ValueError(f"transfer '{transfer}': expected aligned or rbf (deformation transfer needs the actor's "
                         "whole mesh, markers do not give one)")
    names = sorted(rig.blendshapes)
    s = np.stack([rig.blendshapes[n][vertices] for n in names])
    guess = warp_deltas(rbf_warp(rig.vertices[vertices], neutral), rig.vertices[vertices], s)
    frames = np.asarray(positions, np.float64) - np.asarray(neutral, np.float64)[None]
    b = guess if transfer == "rbf" else align_blendshapes(s, frames, guess, neutral).blendshapes
    return retarget_frames(frames, b, bending_prior(rig, names), mu=mu, nu=nu)
