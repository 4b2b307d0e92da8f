"""Expression projection between face models (Nagle et al. §3) and caricature.

``project_expression`` follows steps 1–6: encode ``I_a`` in model A (``R_a = M_a - M_ma``),
move ``R_a`` into B's faceframe (affine on warp and texture), take its loadings in B
(``L_b = P_bᵀ R_a``), rebuild ``R_b = P_b L_b``, add B's mean and render.
``naive_transfer`` is the baseline the paper warns about: A's loadings used as B's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.morphpca.defaults import DEFAULT_TEXTURE_WEIGHT
from stimulus_engine.morphpca.faceframe import align_relative_vector
from stimulus_engine.morphpca.pca import MorphModel
from stimulus_engine.morphpca.reconstruct import render_vectors

__all__ = ["DEFAULT_TEXTURE_WEIGHT", "Projection", "relative_in_target", "target_loadings", "project_relative", "project_expression", "naive_transfer",
           "caricature_vector", "caricature_loadings"]



@dataclass
class Projection:
    """Result of projecting faces into a target model.

    Attributes
    ----------
    images : (n, h, w, 3) float32 — rendered in the target model
    loadings : (n, k_b) — loadings in the target's expression space
    source_loadings : (n, k_a) — the faces' loadings in the source model
    """

    images: np.ndarray
    loadings: np.ndarray
    source_loadings: np.ndarray


def relative_in_target(relative: np.ndarray, source: MorphModel, target: MorphModel, align: bool = True) -> np.ndarray:
    """Source-relative morph vectors ``(n, D_a)`` moved into the target's faceframe ``(n, D_b)``."""
    rel = np.atleast_2d(relative)
    if not align:
        if tuple(source.size) != tuple(target.size):
            raise AppealInputError(f"models: sizes {source.size} and {target.size} differ (expected equal sizes, "
                                   "or faceframes on both models to align them)")
        return rel
    if source.faceframe is None or target.faceframe is None:
        which = "source" if source.faceframe is None else "target"
        raise AppealInputError(f"{which} model: faceframe: missing (expected eye and philtrum keypoints; build the "
                               "model with keypoints, or project with align=False / --no-align)")
    return np.stack([align_relative_vector(r, source.size, source.faceframe, target.size, target.faceframe)
                     for r in rel])


def target_loadings(rel_b: np.ndarray, target: MorphModel, texture_weight: float = DEFAULT_TEXTURE_WEIGHT) -> np.ndarray:
    """Loadings of relative vectors in ``target``: ``L_b = P_bᵀ R`` when ``texture_weight`` = 1 (the paper).

    With ``texture_weight`` w < 1 the loadings are the weighted least-squares fit
    ``argmin_l ‖Ω^½ (P_b l − R)‖²`` where Ω weighs texture entries by w² and warp entries by 1,
    so the (identity-independent) warp decides the expression and the target model supplies
    its own texture for it.
    """
    p = target.components
    if texture_weight == 1.0:
        return rel_b @ p.T
    nt = target.size[0] * target.size[1] * 3
    w2 = float(texture_weight) ** 2
    gram = w2 * (p[:, :nt] @ p[:, :nt].T) + p[:, nt:] @ p[:, nt:].T
    rhs = w2 * (rel_b[:, :nt] @ p[:, :nt].T) + rel_b[:, nt:] @ p[:, nt:].T
    ridge = 1e-6 * np.trace(gram) / len(gram)
    return np.linalg.solve(gram.astype(np.float64) + ridge * np.eye(len(gram)), rhs.T.astype(np.float64)).T.astype(np.float32)


def project_relative(relative: np.ndarray, source: MorphModel, target: MorphModel, align: bool = True,
                     warp_factor: float = 1.0, texture_factor: float = 1.0, texture_weight: float = DEFAULT_TEXTURE_WEIGHT,
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Steps 3–5: ``L_b = P_bᵀ R`` and the absolute target vectors ``M_b = P_b L_b + M_mb``."""
    rel_b = relative_in_target(relative, source, target, align)
    lb = target_loadings(rel_b, target, texture_weight)
    rb = lb @ target.components
    if warp_factor != 1.0 or texture_factor != 1.0:
        rb = caricature_vector(rb, target.size, warp_factor, texture_factor)
    return lb, rb + target.mean


def project_expression(images: np.ndarray, source: MorphModel, target: MorphModel, align: bool = True,
                       warp_factor: float = 1.0, texture_factor: float = 1.0, texture_weight: float = DEFAULT_TEXTURE_WEIGHT,
                       landmarks: np.ndarray | None = None) -> Projection:
    """Render the expressions of ``images`` (faces of the source model's person) on the target.

    Parameters
    ----------
    images : (n, h, w, 3) or (h, w, 3) float32
        Images of the source person, the size of the source model.
    source, target : MorphModel
    align : bool
        Transform warp and texture from the source to the target faceframe first (needs
        faceframes on both models).
    warp_factor, texture_factor : float
        Caricature: scale the projected relative warp / texture (1 = as projected).
    texture_weight : float
        1 = the paper's inner product ``P_bᵀ R``; the default (:data:`DEFAULT_TEXTURE_WEIGHT`) lets the warp decide the
        loadings (see :func:`target_loadings`), which transfers expressions better.
    landmarks : (n, K, 2) array, optional
        The images' keypoints, for a source model built with landmark-guided warps (the
        images are then encoded as its training images were).

    Returns
    -------
    Projection
    """
    m_a = source.encode(images, landmarks)
    la = source.project(m_a)
    lb, m_b = project_relative(source.relative(m_a), source, target, align, warp_factor, texture_factor,
                               texture_weight)
    return Projection(images=render_vectors(m_b, target.size), loadings=lb, source_loadings=la)


def naive_transfer(images: np.ndarray, source: MorphModel, target: MorphModel) -> Projection:
    """Baseline: the faces' loadings in A used directly as loadings in B."""
    la = source.project(source.encode(images))
    k = min(source.n_components, target.n_components)
    lb = np.zeros((la.shape[0], target.n_components), np.float32)
    lb[:, :k] = la[:, :k]
    return Projection(images=render_vectors(target.vectors(lb), target.size), loadings=lb, source_loadings=la)


def caricature_vector(relative: np.ndarray, size: tuple[int, int], warp_factor: float = 1.5,
                      texture_factor: float = 1.0) -> np.ndarray:
    """Scale the warp (and optionally texture) part of mean-relative vectors (Brennan-style caricature)."""
    rel = np.atleast_2d(np.asarray(relative, np.float32))
    n_tex = size[0] * size[1] * 3
    out = rel.copy()
    out[:, :n_tex] *= texture_factor
    out[:, n_tex:] *= warp_factor
    return out


def caricature_loadings(loadings: np.ndarray, factor: float = 1.5) -> np.ndarray:
    """Scale loadings away from (factor > 1) or towards (factor < 1) the mean."""
    return np.asarray(loadings, np.float32) * float(factor)

