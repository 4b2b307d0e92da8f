"""Reconstruction: loadings → morph vector → image (Nagle et al. §2, steps 1–3).

The texture is displaced by the warp field with *backward* mapping: the warp (mean shape →
image) is inverted by fixed-point iteration and the texture is sampled at the inverse
positions, so every output pixel gets a value (no holes). Before inversion, regions where the
warp would fold over (Jacobian determinant ≤ 0, e.g. after strong caricaturing or extreme
loadings) are smoothed until the warp is one-to-one (no fold-over artefacts).
"""

from __future__ import annotations

import cv2
import numpy as np

from stimulus_engine.morphpca.flow import fix_foldovers, grid, invert_displacement, warp_image
from stimulus_engine.morphpca.morphvec import deserialise

__all__ = ["render_morph", "render_vectors", "Reconstructor", "reconstruct_image"]


def render_morph(texture: np.ndarray, warp: np.ndarray, *, fix: bool = True, iterations: int = 6,
                 base: np.ndarray | None = None) -> np.ndarray:
    """Image from a texture on the mean shape and its absolute warp field.

    Parameters
    ----------
    texture : (h, w, 3) float32 in [0, 1]
    warp : (h, w, 2) float32
        Absolute positions in the output image of every mean-shape pixel.
    fix : bool
        Repair fold-overs first (see :func:`stimulus_engine.morphpca.flow.fix_foldovers`).
    iterations : int
        Fixed-point iterations of the warp inversion.

    Returns
    -------
    (h, w, 3) float32 in [0, 1]
    """
    g = grid(*warp.shape[:2]) if base is None else base
    d = warp - g
    if fix:
        d = fix_foldovers(d)
    e = invert_displacement(d, iterations, base=g)
    return np.clip(warp_image(texture, g + e, cv2.INTER_LINEAR), 0.0, 1.0)


def render_vectors(vectors: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Images ``(n, h, w, 3)`` from absolute morph vectors ``(n, D)``."""
    textures, warps = deserialise(np.atleast_2d(vectors), size)
    g = grid(*size)
    return np.stack([render_morph(t, w, base=g) for t, w in zip(textures, warps)])


class Reconstructor:
    """Fast repeated reconstruction from one model: the function a trial loop calls.

    Holds the model's component matrix as float32 ``(k, D)`` and the pixel grid, so a call does
    one small matrix product, the fold-over check, the warp inversion and one remap. Calling
    with a batch of loadings ``(n, k)`` reads the matrix once for the whole batch.

    Examples
    --------
    >>> rec = Reconstructor(model)                      # doctest: +SKIP
    >>> frame = rec(np.zeros(model.n_components))       # the mean face, uint8 RGB
    """

    def __init__(self, model, *, as_uint8: bool = True):
        self.size = model.size
        self.components = np.ascontiguousarray(model.components, np.float32)
        self.mean = np.ascontiguousarray(model.mean, np.float32)
        self.k = self.components.shape[0]
        self.grid = grid(*self.size)
        self.as_uint8 = as_uint8

    def vectors(self, loadings: np.ndarray) -> np.ndarray:
        """Absolute morph vectors for ``loadings`` (``(k,)`` or ``(n, k)``; fewer columns = zeros)."""
        lo = np.atleast_2d(np.asarray(loadings, np.float32))
        if lo.shape[1] > self.k:
            raise ValueError(f"loadings: expected at most {self.k} values per face (got {lo.shape[1]})")
        return lo @ self.components[: lo.shape[1]] + self.mean

    def __call__(self, loadings: np.ndarray) -> np.ndarray:
        single = np.asarray(loadings).ndim == 1
        textures, warps = deserialise(self.vectors(loadings), self.size)
        out = np.stack([render_morph(t, w, base=self.grid) for t, w in zip(textures, warps)])
        if self.as_uint8:
            out = (out * 255.0 + 0.5).astype(np.uint8)
        return out[0] if single else out


def reconstruct_image(model, loadings: np.ndarray) -> np.ndarray:
    """One image ``(h, w, 3)`` float32 in [0, 1] from ``loadings`` of ``model``.

    For many calls (inside a trial loop) keep a :class:`Reconstructor` instead.
    """
    return Reconstructor(model, as_uint8=False)(np.asarray(loadings, np.float32).ravel())
