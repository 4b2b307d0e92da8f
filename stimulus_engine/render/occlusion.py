"""Ambient occlusion baked per vertex by ray casting (Embree through trimesh).

How much of the sky each vertex sees: ``rays`` cosine-weighted directions over the hemisphere
around its normal (one fixed low-discrepancy pattern, turned by a per-vertex angle, so a bake
is deterministic), traced against the whole head (skin, eyes, teeth, mouth, hair); a hit at
distance ``d`` occludes by ``1 − d / reach`` (near geometry — the eye socket, the inside of the
mouth, under the nose — more than far). The ``skin`` shading multiplies its ambient light by it
(:mod:`.skin_shader`). A bake depends only on the geometry, so a grid bakes each (character,
shape, expression) once and every lighting, shading and material of it reuses the result.
"""

from __future__ import annotations

import numpy as np

__all__ = ["light_visibility", "vertex_occlusion"]


def _hemisphere(rays: int) -> np.ndarray:
    """``rays`` cosine-weighted unit directions around +z (a Fibonacci spiral on the disc, lifted)."""
    k = np.arange(rays) + 0.5
    r = np.sqrt(k / rays)
    phi = k * np.pi * (3.0 - np.sqrt(5.0))
    x, y = r * np.cos(phi), r * np.sin(phi)
    return np.stack([x, y, np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))], axis=1)


def _frames(normals: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Per vertex an orthonormal frame (t, b, n) as rows, turned about n by ``angle``."""
    n = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(helper, n)
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
    b = np.cross(n, t)
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    return np.stack([c * t + s * b, -s * t + c * b, n], axis=1)


def _caster(ov: np.ndarray, of: np.ndarray):
    """An Embree ray caster on the occluders (trimesh's pure-Python one if Embree is missing)."""
    import trimesh

    scene = trimesh.Trimesh(ov, of, process=False)
    try:
        from trimesh.ray.ray_pyembree import RayMeshIntersector
    except ImportError:  # pragma: no cover - embreex is a dependency
        from trimesh.ray.ray_triangle import RayMeshIntersector
    return RayMeshIntersector(scene)


def vertex_occlusion(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray, *, rays: int = 32,
                     reach: float = 0.15, occluders: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Visibility ``(N,)`` float32 in [0, 1] of each vertex (1 = sees the whole hemisphere).

    Parameters
    ----------
    vertices, faces : arrays
        The surface whose vertices are baked (also an occluder).
    normals : (N, 3) array
        Outward vertex normals.
    rays : int
        Directions per vertex.
    reach : float
        Occlusion distance as a fraction of the occluders' bounding-box diagonal.
    occluders : (V, F), optional
        All geometry that can block (default: the surface itself).
    """
    v = np.asarray(vertices, np.float64)
    ov, of = occluders if occluders is not None else (v, np.asarray(faces))
    caster = _caster(ov, of)
    diag = float(np.linalg.norm(np.ptp(ov, axis=0)))
    dist_max = reach * diag
    golden = np.pi * (3.0 - np.sqrt(5.0))
    frames = _frames(np.asarray(normals, np.float64), np.arange(len(v)) * golden)
    dirs = np.einsum("rk,nkj->nrj", _hemisphere(rays), frames).reshape(-1, 3)
    origins = np.repeat(v + frames[:, 2] * (1e-4 * diag), rays, axis=0)
    occl = np.zeros(len(origins))
    loc, ray_idx, _ = caster.intersects_location(origins, dirs, multiple_hits=False)
    if len(ray_idx):
        d = np.linalg.norm(loc - origins[ray_idx], axis=1)
        occl[ray_idx] = np.clip(1.0 - d / dist_max, 0.0, 1.0)
    return (1.0 - occl.reshape(len(v), rays).mean(axis=1)).astype(np.float32)


def cone_directions(direction: np.ndarray, half_angle: float, rays: int) -> np.ndarray:
    """``rays`` unit directions evenly over a cone of ``half_angle`` radians around ``direction``
    (a sunflower pattern on the disc the cone cuts at unit distance; one ray: the axis)."""
    d = np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    if rays <= 1 or half_angle <= 0:
        return d[None]
    frame = _frames(d[None], np.zeros(1))[0]
    k = np.arange(rays) + 0.5
    r = np.tan(half_angle) * np.sqrt(k / rays)
    phi = k * np.pi * (3.0 - np.sqrt(5.0))
    out = d + (r * np.cos(phi))[:, None] * frame[0] + (r * np.sin(phi))[:, None] * frame[1]
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def light_visibility(vertices: np.ndarray, normals: np.ndarray, occluders: tuple[np.ndarray, np.ndarray],
                     directions: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """How much of a light each vertex sees, ``(N,)`` float32 in [0, 1] (1 = unshadowed).

    A ray per direction (towards the light: the samples of a sun or an area light, see
    :func:`cone_directions`) from each vertex, started a hair off the surface; a ray that hits
    an occluder counts as shadowed. Rays leaving *behind* a vertex's own surface (``n·l ≤ 0``)
    are not cast and count as shadowed, as a shadow map has it (the surface itself is in the
    way): where a cast shadow meets the side turned away from the light, both are dark alike.

    Parameters
    ----------
    vertices, normals : (N, 3) arrays
    occluders : (V, F)
        Everything that can cast a shadow (the opaque parts of the head).
    directions : (L, 3) array
        Unit directions from the surface towards the light.
    weights : (L,) array, optional
        Share of the light per direction (default equal).
    """
    v = np.asarray(vertices, np.float64)
    n = np.asarray(normals, np.float64)
    dirs = np.asarray(directions, np.float64).reshape(-1, 3)
    w = np.full(len(dirs), 1.0 / len(dirs)) if weights is None else np.asarray(weights, float) / np.sum(weights)
    ov, of = occluders
    diag = float(np.linalg.norm(np.ptp(ov, axis=0)))
    facing = (n @ dirs.T) > 0.0  # (N, L)
    vi, li = np.nonzero(facing)
    origins = v[vi] + n[vi] * (2e-4 * diag) + dirs[li] * (2e-4 * diag)
    blocked = np.zeros(len(vi), bool)
    if len(vi):
        blocked = _caster(np.asarray(ov, np.float64), np.asarray(of)).intersects_any(origins, dirs[li])
    shadow = np.ones(facing.shape)
    shadow[vi, li] = blocked
    return (1.0 - shadow @ w).astype(np.float32)
