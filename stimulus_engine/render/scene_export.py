"""One scene description for both engines: render parts, lights and camera written to a folder.

:func:`export_scene` turns what :func:`~stimulus_engine.render.renderer.render_mesh` draws (the
render parts with their pyrender materials, a lighting preset, a :class:`CameraSpec`) into files
any renderer can read without this package: ``scene.json`` (camera, lights in world
coordinates, background, per part its material values and file names) beside ``parts.npz``
(per part vertices, triangles, normals and UVs) and the part textures as PNG. The path tracer
(:mod:`.cycles`) renders from it in a separate Python (Blender's ``bpy`` needs numpy < 2).

The hair part also gets strands (:func:`stimulus_engine.render.hair_strands.grow_strands`, grown
over the posed hair mesh where its texture has hair): ``parts.npz`` holds their points, points
per strand and radii, which Cycles renders as curves with its hair BSDF over the hair mesh.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from stimulus_engine.render.hair_strands import grow_strands
from stimulus_engine.render.camera import CameraSpec
from stimulus_engine.render.lighting import Disc, LightSpec, group_discs

__all__ = ["SCENE_FORMAT", "export_scene", "world_lights"]

SCENE_FORMAT = "appeal-scene/1"


def world_lights(lights: list[LightSpec], camera: CameraSpec) -> list[dict]:
    """Camera-relative :class:`LightSpec` s as world-space dictionaries (direction the light travels).

    A preset's spot lights sampling one disc (``direct_soft``: same direction, different
    offsets) become one disc light: its direction, the summed intensity, and the disc's angular
    radius (the largest offset, as a fraction of the distance).
    """
    rot = camera.rotation()
    out: list[dict] = []
    for light in group_discs(lights):
        d = rot @ np.asarray(light.direction, float)
        rec = {"direction": (d / np.linalg.norm(d)).tolist(), "intensity": light.intensity, "color": list(light.color),
               "shadow": light.shadow}
        if isinstance(light, Disc):
            out.append({"kind": "disc", **rec, "radius": light.radius})
        elif light.kind == "directional":
            out.append({"kind": "directional", **rec})
        else:
            raise ValueError(f"unknown light kind '{light.kind}' (expected directional or spot)")
    return out


def _texture_array(tex: Any) -> np.ndarray | None:
    return None if tex is None else np.asarray(tex.source)


def _material_record(name: str, mat: Any, folder: Path, index: int) -> dict:
    """The values of a pyrender material (metallic-roughness or specular-glossiness) and its texture files."""
    # pyrender culls the back faces of single-sided materials (ICT's lash shells, the inside of
    # the mouth): the path tracer must hide them too
    rec: dict[str, Any] = {"name": name, "roughness": 0.6, "alpha_blend": False,
                           "double_sided": bool(getattr(mat, "doubleSided", False)),
                           "toon": "TOON_CEL" in getattr(mat, "appeal_defines", {})}  # the toon shading
    if mat is None:
        rec["base_color"] = [0.7, 0.7, 0.7, 1.0]
        return rec
    emissive = _texture_array(getattr(mat, "emissiveTexture", None))
    if emissive is not None:  # an unlit image (a photograph's surround): its own colour, whatever the light
        rec["emission"] = f"part{index}_emission.png"
        Image.fromarray(np.ascontiguousarray(emissive[..., :3])).save(folder / rec["emission"])
    if hasattr(mat, "baseColorFactor"):  # metallic-roughness
        rec["base_color"] = [float(v) for v in mat.baseColorFactor]
        rec["roughness"] = float(mat.roughnessFactor if mat.roughnessFactor is not None else 1.0)
        tex = _texture_array(mat.baseColorTexture)
        mr = _texture_array(getattr(mat, "metallicRoughnessTexture", None))
        if mr is not None:  # pyrender reads roughness from R (× the factor)
            rec["roughness"] = float(np.mean(mr[..., 0]) / 255.0 * rec["roughness"])
    else:  # specular-glossiness (the thesis's Phong shading)
        rec["base_color"] = [float(v) for v in mat.diffuseFactor]
        rec["roughness"] = float(1.0 - (mat.glossinessFactor if mat.glossinessFactor is not None else 0.5))
        rec["phong"] = True
        tex = _texture_array(mat.diffuseTexture)
    # the texture's alpha cuts the surface out: blended cards (lashes, hair: as an opaque card the
    # hair rendered as a solid dark cap) and alpha-tested ones
    rec["alpha_blend"] = getattr(mat, "alphaMode", "OPAQUE") in ("BLEND", "MASK")
    if tex is not None:
        rec["texture"] = f"part{index}_albedo.png"
        Image.fromarray(np.ascontiguousarray(tex)).save(folder / rec["texture"])
    normal = _texture_array(getattr(mat, "normalTexture", None))
    if normal is not None:
        rec["normal_map"] = f"part{index}_normal.png"
        Image.fromarray(np.ascontiguousarray(normal[..., :3])).save(folder / rec["normal_map"])
    return rec


def export_scene(parts: list, lights: list[LightSpec], ambient: float, camera: CameraSpec, folder: str | Path, *,
                 width: int, height: int, background: tuple[float, float, float]) -> Path:
    """Write the scene into ``folder`` (created) and return the path of its ``scene.json``.

    Parameters
    ----------
    parts : list of RenderPart
        As for :func:`~stimulus_engine.render.renderer.render_mesh` (trimesh meshes with vertex
        normals and, when textured, UVs; pyrender materials).
    lights, ambient
        A lighting preset (:func:`~stimulus_engine.render.lighting.lighting_preset`).
    camera : CameraSpec
    width, height : int
    background : RGB in 0..1
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, np.ndarray] = {}
    records = []
    skin_extent = None
    for k, p in enumerate(parts):
        mesh = p.mesh
        arrays[f"v{k}"] = np.asarray(mesh.vertices, np.float32)
        arrays[f"f{k}"] = np.asarray(mesh.faces, np.int32)
        arrays[f"n{k}"] = np.asarray(mesh.vertex_normals, np.float32)
        uv = getattr(mesh.visual, "uv", None)
        if uv is not None:
            arrays[f"uv{k}"] = np.asarray(uv, np.float32)
        records.append(_material_record(p.name, p.material, folder, k))
        if p.name == "skin":
            skin_extent = float(np.ptp(mesh.vertices[:, 0]))
    # the face's scale in millimetres (a head is about 150 mm wide): subsurface scattering
    # distances and hair strands are physical lengths
    mm_per_unit = 150.0 / skin_extent if skin_extent else 150.0 / max(float(np.linalg.norm(camera.target)), 1.0)
    for k, (p, rec) in enumerate(zip(parts, records)):
        # the texture the record saved: metallic-roughness or specular-glossiness (phong)
        tex = _texture_array(getattr(p.material, "baseColorTexture", None) or getattr(p.material, "diffuseTexture", None))
        massed = "HAIR_MASS" in getattr(p.material, "appeal_defines", {})  # painted masses: the cards themselves
        if (p.name == "hair" and not massed and f"uv{k}" in arrays and rec.get("alpha_blend") and tex is not None
                and tex.shape[-1] == 4):
            alpha = tex[..., 3] > 127
            arrays[f"sp{k}"], arrays[f"ss{k}"], arrays[f"sr{k}"] = grow_strands(
                arrays[f"v{k}"], arrays[f"f{k}"], arrays[f"uv{k}"], alpha, mm_per_unit)
            rec["strands"] = True
    np.savez(folder / "parts.npz", **arrays)
    scene = {
        "format": SCENE_FORMAT,
        "width": int(width), "height": int(height), "background": [float(b) for b in background],
        "camera": {"position": list(map(float, camera.position)), "target": list(map(float, camera.target)),
                   "up": list(map(float, camera.up)), "yfov_deg": float(camera.yfov_deg)},
        "lights": world_lights(lights, camera), "ambient": float(ambient),
        "mm_per_unit": mm_per_unit, "parts": records,
    }
    path = folder / "scene.json"
    path.write_text(json.dumps(scene, indent=1))
    return path
