"""Morph vectors (Nagle et al. §2): texture on the mean shape + absolute warp, serialised.

A set of images of one face is compared with a reference image by optical flow. The mean
flow defines the *mean shape*; every image ``I_i`` is then split into

* ``T_i`` — its texture, ``I_i`` resampled onto the mean shape (``T_i(q) = I_i(W_i(q))``), and
* ``W_i`` — its warp in absolute coding: for each mean-shape pixel ``q`` the position in
  ``I_i`` that pixel moves to.

Serialisation is column-wise over the R, G, B texture matrices and then the x and y warp
matrices, giving vectors of length ``h * w * 5``. Texture values are stored on the 0–255 scale
(:data:`TEXTURE_SCALE`) and warps in pixels, so both parts carry comparable variance.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from appeal.progress import progress
from stimulus_engine.morphpca.flow import (
    compute_flow,
    fix_foldovers,
    grey_u8,
    grid,
    invert_displacement,
    sample_field,
    warp_image,
)
from stimulus_engine.morphpca.landmark_warp import reference_flow

__all__ = ["TEXTURE_SCALE", "MorphSet", "serialise", "deserialise", "decompose", "encode_with_reference"]

#: Texture values are multiplied by this in morph vectors (images are [0, 1] floats).
TEXTURE_SCALE = 255.0


def serialise(textures: np.ndarray, warps: np.ndarray) -> np.ndarray:
    """Morph vector(s) from texture(s) ``(…, h, w, 3)`` and absolute warp(s) ``(…, h, w, 2)``.

    The order is column-wise (Fortran order) over R, G, B, then x, y.
    """
    t = np.asarray(textures, np.float32)
    wp = np.asarray(warps, np.float32)
    lead, (h, w) = t.shape[:-3], t.shape[-3:-1]
    out = np.empty((*lead, 5, w, h), np.float32)
    # (..., h, w, c) -> (..., c, w, h): channel-major, then column-major within a channel; one
    # strided copy per part into the preallocated result (no concatenated temporary)
    np.multiply(np.moveaxis(t, (-1, -2, -3), (-3, -2, -1)), np.float32(TEXTURE_SCALE), out=out[..., :3, :, :])
    out[..., 3:, :, :] = np.moveaxis(wp, (-1, -2, -3), (-3, -2, -1))
    return out.reshape(*lead, -1)


def deserialise(vectors: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`serialise`: ``(textures (…, h, w, 3) in [0, 1], warps (…, h, w, 2))``."""
    h, w = size
    v = np.asarray(vectors, np.float32)
    arr = v.reshape(*v.shape[:-1], 5, w, h)
    hw5 = np.moveaxis(arr, (-3, -2, -1), (-1, -2, -3))  # (..., h, w, 5)
    return hw5[..., :3] / TEXTURE_SCALE, hw5[..., 3:]


@dataclass
class MorphSet:
    """Images decomposed into morph pairs relative to a reference.

    Attributes
    ----------
    textures : (n, h, w, 3) float32
    warps : (n, h, w, 2) float32, absolute positions in each image
    ref_positions : (h, w, 2) float32
        For every mean-shape pixel, its position in the reference image (the inverse mean warp).
    reference_index : int
    """

    textures: np.ndarray
    warps: np.ndarray
    ref_positions: np.ndarray
    reference_index: int

    def vectors(self) -> np.ndarray:
        """The absolute morph vectors, ``(n, h*w*5)``."""
        return serialise(self.textures, self.warps)


def encode_with_reference(image: np.ndarray, reference: np.ndarray, ref_positions: np.ndarray,
                          backend: str = "dis", levels: int = 1, flow: np.ndarray | None = None,
                          ) -> tuple[np.ndarray, np.ndarray]:
    """Texture and absolute warp of ``image`` on the mean shape defined by ``ref_positions``."""
    f = compute_flow(reference, image, backend, levels) if flow is None else flow
    warp = ref_positions + sample_field(f, ref_positions)
    return warp_image(image, warp), warp


def decompose(images: np.ndarray, reference_index: int = 0, backend: str = "dis", levels: int = 1,
              weights: Sequence[float] | None = None, desc: str = "warp fields", landmarks: np.ndarray | None = None,
              refine: bool = True) -> MorphSet:
    """Split images into textures and warps on their (weighted) mean shape.

    Parameters
    ----------
    images : (n, h, w, 3) float32 in [0, 1]
    reference_index : int
        The reference image (neutral face, eyes open, ideally teeth slightly visible).
    backend, levels
        See :func:`stimulus_engine.morphpca.flow.compute_flow`.
    weights : sequence of float, optional
        Weights of the mean shape (default equal; they must sum to 1). Other weights move the
        mean towards or beyond some images (used for identity weights of avatars).
    landmarks : (n, K, 2) array, optional
        The same K keypoints in every image: warps start from them and the flow refines
        (:func:`~.landmark_warp.guided_flow`); without, plain optical flow from the reference.
    refine : bool
        With landmarks: False keeps the landmark spline alone (Psychomorph-style).

    Returns
    -------
    MorphSet
    """
    n, h, w = images.shape[:3]
    ref = images[reference_index]
    ref_grey = grey_u8(ref)  # converted once for all n flows
    flows = np.empty((n, h, w, 2), np.float32)
    flows[reference_index] = 0.0
    for i in progress(range(n), total=n, desc=desc):
        if i != reference_index:
            flows[i] = reference_flow(ref_grey, images[i], None if landmarks is None else landmarks[reference_index],
                                      None if landmarks is None else landmarks[i], backend=backend, levels=levels,
                                      refine=refine)
    wts = np.full(n, 1.0 / n, np.float32) if weights is None else np.asarray(weights, np.float32)
    mean_d = fix_foldovers((wts @ flows.reshape(n, -1)).reshape(h, w, 2))
    ref_positions = grid(h, w) + invert_displacement(mean_d)
    textures = np.empty((n, h, w, 3), np.float32)
    warps = np.empty((n, h, w, 2), np.float32)
    for i in range(n):
        textures[i], warps[i] = encode_with_reference(images[i], ref, ref_positions, flow=flows[i])
    return MorphSet(textures=textures, warps=warps, ref_positions=ref_positions, reference_index=reference_index)
