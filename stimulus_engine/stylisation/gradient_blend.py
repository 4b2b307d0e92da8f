"""Local texture blending in the gradient domain (Pérez, Gangnet & Blake 2003), for part-based
morphs (thesis §3.4: "for local blending, a gradient-based technique should be employed").

Textures of corresponded meshes share one UV layout, so a region taken from another face is a
region of texels. Pasting its colours would leave a seam wherever the two faces' skin tones
differ; instead the blended texture ``f`` keeps the base texture outside the region and, inside,
solves the discrete Poisson equation whose guidance is the weighted mix of the textures'
gradients: for every region texel ``p`` with 4-neighbours ``q``,
``4 f_p − Σ f_q = Σ_q Σ_k w̄_k,pq (T_k(p) − T_k(q))`` (``w̄`` the mean of the two texels'
weights), with ``f_q = T_base(q)`` for neighbours outside the region. The donor's details come
across, its overall colour is taken from the surrounding base skin.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from appeal.errors import AppealInputError

__all__ = ["gradient_blend", "texel_weights"]


def texel_weights(uv: np.ndarray, face_uv: np.ndarray, faces: np.ndarray, vertex_weights: np.ndarray,
                  size: tuple[int, int]) -> np.ndarray:
    """Per-vertex weights (N, K) rasterised into the UV layout: (K, H, W); uncovered texels
    belong to mesh 0."""
    from stimulus_engine.geometry.uv_raster import rasterize_uv

    h, w = size
    vw = np.asarray(vertex_weights, np.float64)
    out = np.zeros((vw.shape[1], h, w))
    out[0] = 1.0
    rows, cols, face, bary = rasterize_uv(np.asarray(uv, np.float64), np.asarray(face_uv, np.int64), w, h)
    vals = np.einsum("pc,pck->pk", bary, vw[np.asarray(faces)[face]])
    out[:, rows, cols] = vals.T
    return out


def gradient_blend(textures: list[np.ndarray], weights: np.ndarray, base: int = 0) -> np.ndarray:
    """Blend same-size textures in the gradient domain (see the module docstring).

    Parameters
    ----------
    textures : list of (H, W, 3) uint8 arrays
    weights : (K, H, W) array
        Per-texel weights, summing to 1 over K.
    base : int
        The texture kept where its weight is 1.

    Returns
    -------
    (H, W, 3) uint8 array
    """
    from stimulus_engine.correspondence.solve import factorize

    t = np.stack([np.asarray(x, np.float64) for x in textures])
    if len({x.shape for x in t}) != 1 or t.ndim != 4:
        raise AppealInputError("morph: textures must have one size to blend")
    k, h, w, _ = t.shape
    wt = np.asarray(weights, np.float64)
    if wt.shape != (k, h, w):
        raise AppealInputError(f"morph: texel weights must have shape {(k, h, w)} (got {wt.shape})")
    region = wt[base] < 1 - 1e-6
    region[[0, -1], :] = False  # the image border stays the base's (Dirichlet everywhere)
    region[:, [0, -1]] = False
    out = t[base].copy()
    if not region.any():
        return np.clip(np.rint(out), 0, 255).astype(np.uint8)
    idx = -np.ones((h, w), np.int64)
    ys, xs = np.nonzero(region)
    idx[ys, xs] = np.arange(len(ys))
    n = len(ys)
    rows, cols, vals = [np.arange(n)], [np.arange(n)], [np.full(n, 4.0)]
    rhs = np.zeros((n, 3))
    for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        qy, qx = ys + dy, xs + dx
        wbar = 0.5 * (wt[:, ys, xs] + wt[:, qy, qx])  # (K, n)
        rhs += np.einsum("kn,knc->nc", wbar, t[:, ys, xs] - t[:, qy, qx])
        inside = idx[qy, qx] >= 0
        rows.append(np.arange(n)[inside])
        cols.append(idx[qy, qx][inside])
        vals.append(-np.ones(int(inside.sum())))
        rhs[~inside] += t[base][qy[~inside], qx[~inside]]
    a = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    out[ys, xs] = factorize(a).solve(rhs)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
