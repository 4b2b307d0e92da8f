"""Morphing among corresponded meshes (thesis §3.4).

Meshes that went through :func:`stimulus_engine.correspond` share the source's connectivity and
UV layout, so they blend vertex by vertex and pixel by pixel. Whole-face blends are linear.
Partial (region) blends interpolate per-vertex cotangent Laplacians (differential
coordinates) with per-vertex weights and recover positions with a Poisson solve (Alexa 2003,
with the cotangent instead of the uniform Laplacian, as in the thesis); vertices whose weights
equal the base mesh's are kept as they are, so the blend region joins the rest seamlessly.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from PIL import Image

from appeal.errors import AppealInputError
from stimulus_engine.correspondence.laplacian import cotangent_laplacian
from stimulus_engine.correspondence.solve import factorize

__all__ = ["check_weights", "blend_vertices", "blend_images", "blend_meshes", "partial_blend"]


def check_weights(weights, n: int, where: str = "weights") -> np.ndarray:
    """Weights as floats; one per mesh, finite, summing to 1 (within 1e-6)."""
    w = np.asarray(weights, dtype=np.float64).ravel()
    if len(w) != n:
        raise AppealInputError(f"{where}: expected {n} weights, one per mesh (got {len(w)})")
    if not np.all(np.isfinite(w)):
        raise AppealInputError(f"{where}: weights must be finite numbers")
    if abs(w.sum() - 1.0) > 1e-6:
        raise AppealInputError(f"{where}: weights must sum to 1 (got {w.sum():.6g})")
    return w


def _stack(vertex_sets) -> np.ndarray:
    vs = [np.asarray(v, dtype=np.float64) for v in vertex_sets]
    if len({v.shape for v in vs}) != 1:
        shapes = ", ".join(str(v.shape[0]) for v in vs)
        raise AppealInputError(
            f"morph: meshes must be in correspondence (same vertex count; got {shapes} vertices)"
        )
    return np.stack(vs)


def blend_vertices(vertex_sets, weights) -> np.ndarray:
    """Linear blend ``Σ w_k V_k`` of corresponded vertex arrays (each (N, 3))."""
    v = _stack(vertex_sets)
    w = check_weights(weights, len(v))
    return np.einsum("k,kij->ij", w, v)


def blend_images(images, weights) -> Image.Image:
    """Linear blend of same-size texture images (same UV layout)."""
    arrs = [np.asarray(im.convert("RGB") if isinstance(im, Image.Image) else im, dtype=np.float64) for im in images]
    if len({a.shape for a in arrs}) != 1:
        raise AppealInputError(
            "morph: textures must have the same size (got " + ", ".join(f"{a.shape[1]}x{a.shape[0]}" for a in arrs) + ")"
        )
    w = check_weights(weights, len(arrs))
    out = np.einsum("k,k...->...", w, np.stack(arrs))
    return Image.fromarray(np.clip(np.rint(out), 0, 255).astype(np.uint8))


def blend_meshes(paths: Sequence[str | Path], weights, where: str = "weights"):
    """Load corresponded meshes and blend them: vertices always, textures when all have one of one size.

    ``appeal stimuli morph`` calls this.

    Parameters
    ----------
    paths : sequence of path-like
        At least two meshes in correspondence (same vertex count and faces), typically
        ``deformed.obj`` files of correspondence runs from one source.
    weights : sequence of float
        One per mesh, summing to 1.
    where : str
        The option named in error messages.

    Returns
    -------
    trimesh.Trimesh
        The first mesh's connectivity and UV layout with the blended vertices (and texture).

    Raises
    ------
    AppealInputError
        One line: too few meshes, bad weights, or a mesh not in correspondence with the first.
    """
    import trimesh

    from stimulus_engine.correspondence.pipeline import deformed_mesh
    from stimulus_engine.mesh_io import load_mesh, texture_image

    paths = [Path(p) for p in paths]
    if len(paths) < 2:
        raise AppealInputError(f"MESH...: expected at least two meshes to blend (got {len(paths)})")
    w = check_weights(weights, len(paths), where)
    loaded = [load_mesh(p) for p in paths]
    first = loaded[0]
    for p, m in zip(paths[1:], loaded[1:]):
        if m.vertices.shape != first.vertices.shape or m.faces.shape != first.faces.shape or (m.faces != first.faces).any():
            raise AppealInputError(
                f"{p}: not in correspondence with {paths[0]} (expected the same vertex count and faces; "
                f"got {len(m.vertices)} vs {len(first.vertices)} vertices)"
            )
    result = deformed_mesh(first, blend_vertices([m.vertices for m in loaded], w))
    images = [texture_image(m) for m in loaded]
    if all(im is not None for im in images) and len({im.size for im in images}) == 1:
        result.visual.material = trimesh.visual.material.SimpleMaterial(image=blend_images(images, w))
    return result


def partial_blend(vertex_sets, faces: np.ndarray, vertex_weights: np.ndarray, base: int = 0) -> np.ndarray:
    """Blend regions of corresponded meshes through their Laplacians and a Poisson solve.

    Parameters
    ----------
    vertex_sets : sequence of (N, 3) arrays
        Corresponded meshes (same connectivity ``faces``).
    faces : (F, 3) int array
    vertex_weights : (N, K) array
        Per-vertex blend weights (rows sum to 1); e.g. the nose region of mesh 1 on mesh 0:
        ``w[:, 1] = nose_mask_smoothed``, ``w[:, 0] = 1 - w[:, 1]``.
    base : int
        The mesh that vertices with ``w[:, base] == 1`` keep exactly (the anchors).

    Returns
    -------
    (N, 3) array
    """
    v = _stack(vertex_sets)
    k, n = v.shape[0], v.shape[1]
    w = np.asarray(vertex_weights, dtype=np.float64)
    if w.shape != (n, k):
        raise AppealInputError(f"morph: vertex weights must have shape ({n}, {k}) (got {w.shape})")
    if np.abs(w.sum(axis=1) - 1).max() > 1e-6:
        raise AppealInputError("morph: per-vertex weights must sum to 1 for every vertex")
    # differential coordinates of each mesh with its own cotangent weights, blended per vertex
    delta = sum(w[:, [j]] * (cotangent_laplacian(v[j], faces) @ v[j]) for j in range(k))
    linear = np.einsum("ik,kij->ij", w, v)
    lap = cotangent_laplacian(linear, faces)
    anchors = w[:, base] >= 1 - 1e-9
    if not anchors.any():
        anchors[np.argmax(w[:, base])] = True
    # anchors are fixed exactly (Dirichlet); the rest solve min ||L X - δ||² + ε ||X - linear||²
    free = ~anchors
    out = np.where(anchors[:, None], v[base], linear)
    if not free.any():
        return out
    scale = float(np.median(np.abs(lap.diagonal()))) ** 2 + 1e-300
    h = (lap.T @ lap).tocsr()
    rhs = lap.T @ delta - h[:, anchors] @ out[anchors]
    h_ff = h[free][:, free] + sp.identity(int(free.sum())) * (1e-6 * scale)
    out[free] = factorize(h_ff).solve(rhs[free] + 1e-6 * scale * linear[free])
    return out
