"""Identity-blended avatars (Nagle et al. §4, steps 1–9).

Given k identity models (steps 1–4: each built from its own images, with a faceframe on its
mean image), every training face of every identity is projected into all k identities
(step 5, with the faceframe affine transform), sharpened by unsharp masking (step 6),
aligned onto a reference faceframe (step 7) and morph-averaged per expression (step 8: the
projection onto the reference identity is the reference image of the average; identity
weights other than equal move the blend towards or away from identities). The blended
frames are then modelled by PCA (step 9) into one avatar model whose identity is a blend.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from appeal.errors import AppealInputError
from appeal.progress import progress
from stimulus_engine.morphpca.defaults import DEFAULT_TEXTURE_WEIGHT
from stimulus_engine.morphpca.faceframe import align_image, faceframe_affine, transform_points
from stimulus_engine.morphpca.flow import sample_field
from stimulus_engine.morphpca.morphvec import decompose, deserialise
from stimulus_engine.morphpca.pca import MorphModel, build_model
from stimulus_engine.morphpca.project import project_relative
from stimulus_engine.morphpca.reconstruct import render_vectors

__all__ = ["Avatar", "unsharp_mask", "morph_average", "build_avatar"]


@dataclass
class Avatar:
    """An identity-blended model and the frames it was built from.

    Attributes
    ----------
    model : MorphModel
        The avatar's PCA model (faceframe = the reference faceframe).
    frames : (m, h, w, 3) float32
        The blended frames (one per source expression).
    projections : (m, k, h, w, 3) float32
        For each source expression, its aligned projections into the k identities.
    sources : list of (int, int)
        (identity, image) of each source expression.
    weights : (k,) identity weights used for blending
    """

    model: MorphModel
    frames: np.ndarray
    projections: np.ndarray
    sources: list[tuple[int, int]]
    weights: np.ndarray


def unsharp_mask(image: np.ndarray, sigma: float = 1.0, amount: float = 0.6) -> np.ndarray:
    """``image + amount · (image − blur(image))``, clipped to [0, 1] (step 6)."""
    blur = cv2.GaussianBlur(np.ascontiguousarray(image, np.float32), (0, 0), sigma)
    return np.clip(image + amount * (image - blur), 0.0, 1.0)


def morph_average(images: np.ndarray, reference_index: int = 0, weights: Sequence[float] | None = None,
                  backend: str = "dis", landmarks: np.ndarray | None = None) -> np.ndarray:
    """Morph average of aligned faces: the (weighted) mean texture shown on the mean shape.

    Because the mean of the absolute warps is the identity on the mean shape, the mean
    morph image is the mean texture itself. ``landmarks`` ``(n, K, 2)``: the faces' keypoints,
    for landmark-guided warps between them (no doubled features where flow between different
    people fails).
    """
    ms = decompose(np.asarray(images, np.float32), reference_index, backend, weights=weights, desc="morph average",
                   landmarks=landmarks)
    wts = np.full(len(images), 1.0 / len(images)) if weights is None else np.asarray(weights, float)
    return np.clip(np.tensordot(wts, ms.textures, axes=1), 0.0, 1.0).astype(np.float32)


def _check_weights(weights, k: int) -> np.ndarray:
    if weights is None:
        return np.full(k, 1.0 / k)
    w = np.asarray(weights, float)
    if w.shape != (k,) or not np.all(np.isfinite(w)):
        raise AppealInputError(f"weights: expected {k} identity weights, one per model (got {list(np.ravel(w))})")
    if abs(w.sum() - 1.0) > 1e-6:
        raise AppealInputError(f"weights: expected identity weights summing to 1 (got sum {w.sum():.4g}); "
                               "weights outside [0, 1] move beyond an identity")
    return w


def build_avatar(models: Sequence[MorphModel], *, reference_model: int = 0, weights: Sequence[float] | None = None,
                 n_components: int | None = None, sharpen: float = 0.6, texture_weight: float = DEFAULT_TEXTURE_WEIGHT,
                 backend: str = "dis") -> Avatar:
    """Blend k identity models into one avatar model (steps 5–9).

    Parameters
    ----------
    models : sequence of MorphModel
        At least 2 identity models, each with a faceframe and its training loadings.
    reference_model : int
        Whose faceframe (and size) the avatar uses (step 7a).
    weights : sequence of float, optional
        Identity weights of the morph average (default equal; they must sum to 1).
    n_components : int, optional
        Components of the avatar model (default all).
    sharpen : float
        Unsharp-mask amount of step 6 (0 disables).
    texture_weight : float
        See :func:`stimulus_engine.morphpca.project.target_loadings`.

    Returns
    -------
    Avatar
    """
    k = len(models)
    if k < 2:
        raise AppealInputError(f"models: an avatar needs at least 2 identity models (got {k})")
    for i, m in enumerate(models):
        if m.faceframe is None:
            raise AppealInputError(f"models[{i}]: faceframe: missing (build identity models with keypoints)")
        if len(m.loadings) == 0:
            raise AppealInputError(f"models[{i}]: loadings: the model holds no training faces to project")
    if not 0 <= reference_model < k:
        raise AppealInputError(f"reference: expected a model index 0..{k - 1} (got {reference_model})")
    w = _check_weights(weights, k)
    ref = models[reference_model]
    sources = [(s, i) for s, m in enumerate(models) for i in range(len(m.loadings))]
    projections = np.empty((len(sources), k) + tuple(ref.size) + (3,), np.float32)
    # with the same landmarks on every identity's mean, the averages are landmark-guided
    counts = {None if m.landmarks is None else len(m.landmarks) for m in models}
    guided = None not in counts and len(counts) == 1
    points = np.empty((len(sources), k, len(ref.landmarks), 2)) if guided else None
    for j, (s, i) in enumerate(progress(sources, total=len(sources), desc="projecting expressions")):
        src = models[s]
        rel = src.loadings[i : i + 1] @ src.components  # R = P l (the training face, relative)
        for t, tgt in enumerate(models):
            _, m_b = project_relative(rel, src, tgt, align=True, texture_weight=texture_weight)
            img = render_vectors(m_b, tgt.size)[0]
            if sharpen > 0:
                img = unsharp_mask(img, amount=sharpen)
            projections[j, t] = align_image(img, tgt.faceframe, ref.faceframe, ref.size)
            if guided:
                # the mean's landmarks go where the rendered warp takes them, then through the alignment
                warp = deserialise(m_b[0], tgt.size)[1]
                moved = sample_field(np.ascontiguousarray(warp), tgt.landmarks.astype(np.float32)[None])[0]
                points[j, t] = transform_points(faceframe_affine(tgt.faceframe, ref.faceframe), moved)
    frames = np.stack([morph_average(projections[j], reference_model, w, backend,
                                     landmarks=None if points is None else points[j])
                       for j in progress(range(len(sources)), total=len(sources), desc="blending identities")])
    ref_index = next(j for j, (s, _) in enumerate(sources) if s == reference_model)
    frame_points = np.repeat(np.asarray(ref.faceframe, float)[None], len(frames), axis=0)
    model = build_model(frames, n_components=n_components, reference_index=ref_index, backend=backend,
                        faceframes=frame_points, names=[f"id{s}_img{i}" for s, i in sources])
    model.faceframe = np.asarray(ref.faceframe, float)
    model.meta.update(avatar_identities=k, avatar_weights=[float(v) for v in w], reference_model=reference_model)
    return Avatar(model=model, frames=frames, projections=projections, sources=sources, weights=w)
