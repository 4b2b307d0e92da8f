"""Morphing among corresponded meshes (thesis §3.4).

Meshes that went through :func:`stimulus_engine.correspond` share the source's connectivity and
UV layout, so they blend vertex by vertex and pixel by pixel. Whole-face blends are linear.
Partial (region) blends interpolate per-vertex cotangent Laplacians (differential
coordinates) with per-vertex weights — by spherical linear interpolation of their directions
and linear interpolation of their lengths (Alexa 2003, with the cotangent instead of the
uniform Laplacian, as in the thesis; :func:`slerp_vectors`) — and recover positions with a
Poisson solve; vertices whose weights equal the base mesh's are kept as they are, so the blend
region joins the rest seamlessly. Linear interpolation of the Laplacians shortens those of a
part that turns between the meshes (a shrunken, flattened part); slerp keeps them.
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

__all__ = ["check_weights", "blend_vertices", "blend_images", "blend_meshes", "load_corresponded", "part_morph",
           "partial_blend", "slerp_vectors"]


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


def load_corresponded(paths: Sequence[Path]) -> list:
    """Load meshes that must be in correspondence with the first (same vertex count and faces);
    one-line error naming the first that is not."""
    from stimulus_engine.geometry.mesh_io import load_mesh

    loaded = [load_mesh(p) for p in paths]
    first = loaded[0]
    for p, m in zip(paths[1:], loaded[1:]):
        if m.vertices.shape != first.vertices.shape or m.faces.shape != first.faces.shape or (m.faces != first.faces).any():
            raise AppealInputError(
                f"{p}: not in correspondence with {paths[0]} (expected the same vertex count and faces; "
                f"got {len(m.vertices)} vs {len(first.vertices)} vertices)"
            )
    return loaded


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
    from stimulus_engine.geometry.mesh_io import texture_image

    paths = [Path(p) for p in paths]
    if len(paths) < 2:
        raise AppealInputError(f"MESH...: expected at least two meshes to blend (got {len(paths)})")
    w = check_weights(weights, len(paths), where)
    loaded = load_corresponded(paths)
    first = loaded[0]
    result = deformed_mesh(first, blend_vertices([m.vertices for m in loaded], w))
    images = [texture_image(m) for m in loaded]
    if all(im is not None for im in images) and len({im.size for im in images}) == 1:
        result.visual.material = trimesh.visual.material.SimpleMaterial(image=blend_images(images, w))
    return result


def slerp_vectors(vectors: np.ndarray, weights: np.ndarray, iterations: int = 8) -> np.ndarray:
    """Per-row weighted spherical interpolation of K vectors: length interpolated linearly,
    direction by slerp (K = 2, exact) or its K-vector generalisation, the weighted spherical
    mean (Buss & Fillmore 2001: log map, weighted mean in the tangent plane, exp map, repeated).

    Parameters
    ----------
    vectors : (K, N, 3) array
    weights : (N, K) array
        Rows sum to 1.

    Returns
    -------
    (N, 3) array
    """
    v = np.asarray(vectors, np.float64)
    w = np.asarray(weights, np.float64).T[:, :, None]  # (K, N, 1)
    length = np.linalg.norm(v, axis=2, keepdims=True)
    unit = v / np.maximum(length, 1e-300)
    mean_len = (w * length).sum(axis=0)
    d = (w * unit).sum(axis=0)  # the normalised linear mean starts the iteration
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    for _ in range(iterations):
        cos = np.clip(np.einsum("knd,nd->kn", unit, d), -1.0, 1.0)[:, :, None]
        ang = np.arccos(cos)
        perp = unit - cos * d[None]
        norm = np.linalg.norm(perp, axis=2, keepdims=True)
        log = np.where(norm > 1e-12, perp / np.maximum(norm, 1e-300) * ang, 0.0)  # tangent vectors at d
        step = (w * log).sum(axis=0)
        t = np.linalg.norm(step, axis=1, keepdims=True)
        d = np.where(t > 1e-15, np.cos(t) * d + np.sin(t) * step / np.maximum(t, 1e-300), d)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = mean_len * d
    zero = (length[..., 0] < 1e-300).any(axis=0)  # a zero vector has no direction: blend linearly
    out[zero] = (w * v).sum(axis=0)[zero]
    return out


def partial_blend(vertex_sets, faces: np.ndarray, vertex_weights: np.ndarray, base: int = 0,
                  interpolation: str = "slerp") -> np.ndarray:
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
    interpolation : {"slerp", "linear"}
        How the Laplacians blend: slerp (the thesis, Alexa 2003) or linearly.

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
    if interpolation not in ("slerp", "linear"):
        raise AppealInputError(f"morph: interpolation: expected slerp or linear (got {interpolation!r})")
    # differential coordinates of each mesh with its own cotangent weights, blended per vertex
    deltas = np.stack([cotangent_laplacian(v[j], faces) @ v[j] for j in range(k)])
    delta = slerp_vectors(deltas, w) if interpolation == "slerp" else np.einsum("ik,kij->ij", w, deltas)
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


def part_morph(meshes: Sequence, regions: dict[str, int], ibug: np.ndarray, interpolation: str = "slerp"):
    """A part-based morph of corresponded meshes: named regions (eyes, brows, nose, mouth) from
    other meshes on mesh 0 (thesis §3.4, Fig. 3.1).

    Geometry by :func:`partial_blend` (Laplacian slerp + Poisson solve) with
    :func:`stimulus_engine.stylisation.morph_regions.region_weights`; when every mesh has a texture of one
    size, texture by :func:`stimulus_engine.stylisation.gradient_blend.gradient_blend` (gradient domain).

    Parameters
    ----------
    meshes : sequence of trimesh.Trimesh
        In correspondence (same vertices count and faces; mesh 0 is the base).
    regions : dict of str to int
        Region -> mesh index (:func:`stimulus_engine.stylisation.morph_regions.parse_regions`).
    ibug : (68, 3) array
        iBUG landmarks on mesh 0.
    interpolation : {"slerp", "linear"}

    Returns
    -------
    trimesh.Trimesh
        Mesh 0's connectivity and UV layout, the blended vertices (and texture).
    """
    import trimesh

    from stimulus_engine.correspondence.pipeline import deformed_mesh
    from stimulus_engine.stylisation.gradient_blend import gradient_blend, texel_weights
    from stimulus_engine.geometry.mesh_io import mesh_uv_layout, texture_image
    from stimulus_engine.stylisation.morph_regions import region_weights

    first = meshes[0]
    faces = np.asarray(first.faces)
    w = region_weights(np.asarray(first.vertices), ibug, regions, len(meshes))
    v = partial_blend([np.asarray(m.vertices) for m in meshes], faces, w, base=0, interpolation=interpolation)
    result = deformed_mesh(first, v)
    images = [texture_image(m) for m in meshes]
    layout = mesh_uv_layout(first)
    if layout is not None and all(im is not None for im in images) and len({im.size for im in images}) == 1:
        arrays = [np.asarray(im.convert("RGB")) for im in images]
        tw = texel_weights(layout[0], layout[1], faces, w, arrays[0].shape[:2])
        result.visual.material = trimesh.visual.material.SimpleMaterial(image=Image.fromarray(gradient_blend(arrays, tw)))
    return result
