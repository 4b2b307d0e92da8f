"""Soft shadows baked per vertex by ray casting instead of shadow maps (a rig's parts, every shading).

``direct_soft``'s key is an area light, drawn by pyrender as a disc of six spot lights; with a
filtered shadow map each (six passes over the scene and six lookups per pixel on the CPU,
where llvmpipe runs every branch) it took 0.9–1.3 s an image, where the rest of the image
takes 65 ms — and drew six stacked shadow edges. A face under a fixed light is a static scene,
so the rays are cast once instead: per vertex of every part, the fraction of the disc it sees
(:func:`~stimulus_engine.render.occlusion.light_visibility`; :data:`DISC_RAYS` rays over the
angular size the path tracer gives the same light, so both engines draw the same penumbra),
and the shader multiplies the disc's samples by it (:mod:`.light_shadows`). The result is kept
per geometry and lights in this process, so the materials of one shape and lighting bake once.

A vertex-interpolated shadow is only as sharp as the mesh (vertices about 2 mm apart on the
ICT face, 5–6 px of a 1024 × 768 portrait): right for a penumbra this wide, too coarse for a
hard light's edge, which keeps its shadow map (the key light's, :data:`~.light_shadows.SHADOW_KEY`).
"""

from __future__ import annotations

import hashlib
import math
from typing import Any

import numpy as np

__all__ = ["DISC_RAYS", "bake_shadows", "disc_directions"]

#: Rays per vertex spread over a soft (disc) light.
DISC_RAYS = 16

_CACHE: dict[bytes, list[np.ndarray]] = {}


def disc_directions(world: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    """Ray directions towards the shadow-casting disc lights of ``world`` (from
    :func:`~stimulus_engine.render.scene_export.world_lights`) and their weights (intensity)."""
    from stimulus_engine.render.occlusion import cone_directions

    dirs, weights = [], []
    for light in world:
        if light.get("shadow") and light["kind"] == "disc":
            d = cone_directions(-np.asarray(light["direction"], float), math.atan(light["radius"]), DISC_RAYS)
            dirs.append(d)
            weights.append(np.full(len(d), light["intensity"] / len(d)))
    if not dirs:
        return np.zeros((0, 3)), np.zeros(0)
    return np.concatenate(dirs), np.concatenate(weights)


def bake_shadows(meshes: list[Any], opaque: list[bool], world: list[dict]) -> list[np.ndarray]:
    """Per mesh (trimesh, drawn as they are) the visibility of the shadow-casting discs per vertex.

    Parameters
    ----------
    meshes : list of trimesh.Trimesh
        The parts, in world coordinates, with their vertex normals.
    opaque : list of bool
        Which parts cast shadows (not the alpha-blended lash cards: see the shadow-map pass).
    world : list of dict
        The lights in world coordinates (:func:`~stimulus_engine.render.scene_export.world_lights`).
    """
    from stimulus_engine.render.occlusion import light_visibility

    dirs, weights = disc_directions(world)
    if len(dirs) == 0:
        return [np.ones(len(m.vertices), np.float32) for m in meshes]
    key = hashlib.blake2b(np.round(dirs, 6).tobytes() + np.round(weights, 6).tobytes() + bytes(opaque),
                          digest_size=16)
    for m in meshes:
        key.update(np.ascontiguousarray(m.vertices, np.float64).tobytes())
        key.update(np.ascontiguousarray(m.faces, np.int64).tobytes())
    digest = key.digest()
    hit = _CACHE.get(digest)
    if hit is not None:
        return hit
    blockers = [m for m, o in zip(meshes, opaque) if o] or list(meshes)
    offsets = np.cumsum([0] + [len(m.vertices) for m in blockers])
    ov = np.concatenate([np.asarray(m.vertices, np.float64) for m in blockers])
    of = np.concatenate([np.asarray(m.faces) + o for m, o in zip(blockers, offsets)])
    v = np.concatenate([np.asarray(m.vertices, np.float64) for m in meshes])
    n = np.concatenate([np.asarray(m.vertex_normals, np.float64) for m in meshes])
    vis = light_visibility(v, n, (ov, of), dirs, weights)
    out = np.split(vis, np.cumsum([len(m.vertices) for m in meshes])[:-1])
    if len(_CACHE) >= 8:
        _CACHE.clear()
    _CACHE[digest] = out
    return out
