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

__all__ = ["vertex_occlusion"]


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
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(n, t)
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    return np.stack([c * t + s * b, -s * t + c * b, n], axis=1)


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
    import trimesh

    v = np.asarray(vertices, np.float64)
    ov, of = occluders if occluders is not None else (v, np.asarray(faces))
    scene = trimesh.Trimesh(ov, of, process=False)
    try:
        from trimesh.ray.ray_pyembree import RayMeshIntersector
    except ImportError:  # pragma: no cover - embreex is a dependency
        from trimesh.ray.ray_triangle import RayMeshIntersector
    caster = RayMeshIntersector(scene)
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
