"""Render an exported scene (:mod:`stimulus_engine.render.scene_export`) with Blender's Cycles.

Run as a script by the Python that has Blender's ``bpy`` wheel (it pins numpy < 2, so it lives in
its own environment, ``.venv-cycles``)::

    .venv-cycles/bin/python stimulus_engine/render/cycles_worker.py SCENE.json OUT.png \
        --samples 16 --seed 0 --threads 2

OUT.png is RGBA (straight alpha, the face on a transparent film); the caller composites it onto
the background.

It imports nothing from this package. Skin is Blender's Principled BSDF with random-walk
subsurface scattering driven by the albedo (radius red > green > blue, as in skin, in
millimetres converted to scene units), eyes and teeth wet and glossy, lashes and hair cut out by
their texture's alpha; the hair's strands (when the scene has them) as curves with the Principled
Hair BSDF (Chiang's model; coloured by the hair colour) over the cut-out hair mesh. Lights: directional → sun (0.5° across: hard shadows), a disc of spot
samples → a sun as wide as the disc seen from the face (an area light at infinity: soft
shadows), the ambient level → a uniform world, which with 4 diffuse bounces is the global
illumination of ``gi_soft``. Film: AgX view transform (Blender's filmic tone curve),
transparent; OpenImageDenoise; fixed seed, so a re-render gives the same pixels.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np


def _look_at(position, target, up) -> np.ndarray:
    z = np.asarray(position, float) - np.asarray(target, float)
    z /= np.linalg.norm(z)
    x = np.cross(np.asarray(up, float), z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, z, position
    return m


def _light_matrix(direction) -> np.ndarray:
    """A rotation whose -z axis points along ``direction`` (Blender lights shine along local -z)."""
    return _look_at(np.zeros(3), np.asarray(direction, float), [0.0, 1.0, 0.0] if abs(direction[1]) < 0.9 else [1.0, 0.0, 0.0])


def _image(bpy, folder: Path, name: str, colour: bool):
    img = bpy.data.images.load(str(folder / name))
    img.colorspace_settings.name = "sRGB" if colour else "Non-Color"
    return img


#: Part names drawn as a wet eye (a clear coat over a glossy surface; never toon-shaded).
EYE_PARTS = ("eyes", "eye", "sclera", "iris", "cornea")


def _emission(bpy, rec: dict, folder: Path):
    """An unlit image (a photograph's surround): emission of its texture, seen by the camera only."""
    mat = bpy.data.materials.new(rec["name"] or "part")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = _image(bpy, folder, rec["emission"], True)
    em = nodes.new("ShaderNodeEmission")
    links.new(tex.outputs["Color"], em.inputs["Color"])
    links.new(em.outputs["Emission"], nodes["Material Output"].inputs["Surface"])
    return mat


def _material(bpy, rec: dict, folder: Path, mm_per_unit: float):
    if "emission" in rec:
        return _emission(bpy, rec, folder)
    mat = bpy.data.materials.new(rec["name"] or "part")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    base = rec["base_color"]
    bsdf.inputs["Base Color"].default_value = (*base[:3], 1.0)
    bsdf.inputs["Roughness"].default_value = float(np.clip(rec.get("roughness", 0.6), 0.02, 1.0))
    if rec.get("alpha_blend") and "texture" not in rec:  # a clear film (the lids' wet line)
        bsdf.inputs["Alpha"].default_value = float(base[3]) if len(base) > 3 else 1.0
    name = rec["name"]
    if "texture" in rec:
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = _image(bpy, folder, rec["texture"], True)
        if any(b != 1.0 for b in base[:3]):
            mix = nodes.new("ShaderNodeMix")
            mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
            mix.inputs["Factor"].default_value = 1.0
            links.new(tex.outputs["Color"], mix.inputs["A"])
            mix.inputs["B"].default_value = (*base[:3], 1.0)
            links.new(mix.outputs["Result"], bsdf.inputs["Base Color"])
        else:
            links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
        if rec.get("alpha_blend"):
            links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    if "normal_map" in rec:
        nt = nodes.new("ShaderNodeTexImage")
        nt.image = _image(bpy, folder, rec["normal_map"], False)
        nm = nodes.new("ShaderNodeNormalMap")
        links.new(nt.outputs["Color"], nm.inputs["Color"])
        links.new(nm.outputs["Normal"], bsdf.inputs["Normal"])
    if not rec.get("double_sided", True):
        # single-sided, as pyrender draws it: back faces let the rays through
        out = nodes["Material Output"]
        geo, clear, mix = nodes.new("ShaderNodeNewGeometry"), nodes.new("ShaderNodeBsdfTransparent"), nodes.new("ShaderNodeMixShader")
        links.new(geo.outputs["Backfacing"], mix.inputs["Fac"])
        links.new(bsdf.outputs["BSDF"], mix.inputs[1])
        links.new(clear.outputs["BSDF"], mix.inputs[2])
        links.new(mix.outputs["Shader"], out.inputs["Surface"])
    mm = 1.0 / mm_per_unit  # scene units per millimetre
    if name in ("skin", "neck") and not rec.get("phong"):
        # random-walk SSS driven by the albedo; skin's mean free paths ~ 1.0 / 0.4 / 0.2 mm (R, G, B)
        bsdf.subsurface_method = "RANDOM_WALK"
        bsdf.inputs["Subsurface Weight"].default_value = 1.0
        bsdf.inputs["Subsurface Radius"].default_value = (1.0, 0.4, 0.2)
        bsdf.inputs["Subsurface Scale"].default_value = 1.5 * mm
        bsdf.inputs["Specular IOR Level"].default_value = 0.45
        bsdf.inputs["IOR"].default_value = 1.4
    elif name in ("skin", "neck"):  # the thesis's Phong contrast: no scattering, a plain specular lobe
        bsdf.inputs["Specular IOR Level"].default_value = 0.5
    elif name in EYE_PARTS:
        bsdf.inputs["Roughness"].default_value = 0.05
        bsdf.inputs["Coat Weight"].default_value = 1.0
        bsdf.inputs["Coat Roughness"].default_value = 0.02
    elif name == "teeth":  # enamel: glossy, no scattering (a thin shell glowed orange with it)
        bsdf.inputs["Roughness"].default_value = 0.25
    if rec.get("toon") and name not in EYE_PARTS and not rec.get("alpha_blend"):
        _toon(nodes, links, bsdf)
    return mat


#: The ``toon`` shading's Toon BSDFs (Cycles' cel shading, per light): the lit area's angular
#: size and its edge's softness, and the share of a glossy toon highlight.
TOON_SIZE, TOON_SMOOTH, TOON_GLOSS = 0.7, 0.08, 0.03


def _toon(nodes, links, bsdf) -> None:
    """Put a cel-shaded surface in place of ``bsdf``: a diffuse Toon BSDF fed what fed its base
    colour and normal, with a little glossy Toon BSDF for a hard-edged highlight."""
    diffuse, gloss, mix = nodes.new("ShaderNodeBsdfToon"), nodes.new("ShaderNodeBsdfToon"), nodes.new("ShaderNodeMixShader")
    diffuse.component, gloss.component = "DIFFUSE", "GLOSSY"
    diffuse.inputs["Size"].default_value, diffuse.inputs["Smooth"].default_value = TOON_SIZE, TOON_SMOOTH
    gloss.inputs["Size"].default_value, gloss.inputs["Smooth"].default_value = 0.15, TOON_SMOOTH
    diffuse.inputs["Color"].default_value = bsdf.inputs["Base Color"].default_value
    for link in list(bsdf.inputs["Base Color"].links):
        links.new(link.from_socket, diffuse.inputs["Color"])
    for link in list(bsdf.inputs["Normal"].links):
        links.new(link.from_socket, diffuse.inputs["Normal"])
        links.new(link.from_socket, gloss.inputs["Normal"])
    mix.inputs["Fac"].default_value = TOON_GLOSS
    links.new(diffuse.outputs["BSDF"], mix.inputs[1])
    links.new(gloss.outputs["BSDF"], mix.inputs[2])
    for link in list(bsdf.outputs["BSDF"].links):
        links.new(mix.outputs["Shader"], link.to_socket)


#: Principled Hair BSDF settings: longitudinal and azimuthal roughness, and the share of the
#: hair colour the strands take (the grey strand texture averages about 0.7 of it).
HAIR_ROUGHNESS, HAIR_RADIAL_ROUGHNESS, HAIR_TEXTURE_MEAN = 0.3, 0.3, 0.7
#: Darkest colour a strand absorbs down to (its absorption coefficient is -ln of the colour).
HAIR_MIN_COLOUR = 1e-3


def _hair_material(bpy, rec: dict):
    mat = bpy.data.materials.new("strands")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.remove(nodes["Principled BSDF"])
    hair = nodes.new("ShaderNodeBsdfHairPrincipled")
    # absorption from the colour: one pass through a fibre keeps the colour's share of the light
    # (Blender's "direct colouring" maps a colour to a hair volume's multiple scattering instead,
    # under which dark brown strands lit from behind by the presets' rim lights glowed white)
    hair.parametrization = "ABSORPTION"
    colour = np.maximum(HAIR_TEXTURE_MEAN * np.asarray(rec["base_color"][:3], float), HAIR_MIN_COLOUR)
    hair.inputs["Absorption Coefficient"].default_value = tuple(-np.log(colour))
    hair.inputs["Roughness"].default_value = HAIR_ROUGHNESS
    hair.inputs["Radial Roughness"].default_value = HAIR_RADIAL_ROUGHNESS
    links.new(hair.outputs["BSDF"], nodes["Material Output"].inputs["Surface"])
    return mat


def _strands(bpy, name: str, points: np.ndarray, sizes: np.ndarray, radius: np.ndarray):
    curves = bpy.data.hair_curves.new(name)
    curves.add_curves([int(n) for n in sizes])
    curves.position_data.foreach_set("vector", points.astype(np.float32).ravel())
    attr = curves.attributes.get("radius") or curves.attributes.new("radius", "FLOAT", "POINT")
    attr.data.foreach_set("value", radius.astype(np.float32))
    return curves


def _mesh(bpy, name: str, v: np.ndarray, f: np.ndarray, n: np.ndarray, uv: np.ndarray | None):
    me = bpy.data.meshes.new(name or "part")
    me.vertices.add(len(v))
    me.vertices.foreach_set("co", v.astype(np.float32).ravel())
    me.loops.add(f.size)
    me.loops.foreach_set("vertex_index", f.astype(np.int32).ravel())
    me.polygons.add(len(f))
    me.polygons.foreach_set("loop_start", np.arange(0, f.size, 3, dtype=np.int32))
    me.polygons.foreach_set("loop_total", np.full(len(f), 3, np.int32))
    me.polygons.foreach_set("use_smooth", np.ones(len(f), bool))
    if uv is not None:
        layer = me.uv_layers.new(name="UVMap")
        layer.data.foreach_set("uv", uv[f.ravel()].astype(np.float32).ravel())
    me.update(calc_edges=True)
    me.validate(clean_customdata=False)
    me.normals_split_custom_set_from_vertices([tuple(x) for x in n.astype(float)])
    return me


def build_scene(bpy, scene_path: Path, samples: int, seed: int, threads: int):
    spec = json.loads(scene_path.read_text())
    folder = scene_path.parent
    bpy.ops.wm.read_factory_settings(use_empty=True)
    import addon_utils

    addon_utils.enable("cycles", default_set=True)  # an empty factory scene starts without it
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = samples
    sc.cycles.seed = seed
    sc.cycles.use_animated_seed = False
    sc.cycles.use_adaptive_sampling = False  # the same work for every image: reproducible and comparable
    sc.cycles.use_denoising = True
    sc.cycles.denoiser = "OPENIMAGEDENOISE"
    sc.cycles.max_bounces, sc.cycles.diffuse_bounces, sc.cycles.glossy_bounces = 8, 4, 4
    sc.cycles.transparent_max_bounces = 16
    sc.render.threads_mode = "FIXED"
    sc.render.threads = max(1, threads)
    sc.render.resolution_x, sc.render.resolution_y = spec["width"], spec["height"]
    sc.render.resolution_percentage = 100
    sc.render.film_transparent = True
    sc.render.image_settings.file_format = "PNG"
    sc.render.image_settings.color_mode = "RGBA"
    sc.view_settings.view_transform = "AgX"
    sc.view_settings.look = "None"
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bg.inputs["Strength"].default_value = float(spec["ambient"])
    sc.world = world
    parts = np.load(folder / "parts.npz")
    for k, rec in enumerate(spec["parts"]):
        uv = parts[f"uv{k}"] if f"uv{k}" in parts.files else None
        me = _mesh(bpy, rec["name"], parts[f"v{k}"], parts[f"f{k}"], parts[f"n{k}"], uv)
        me.materials.append(_material(bpy, rec, folder, spec["mm_per_unit"]))
        ob = bpy.data.objects.new(rec["name"] or f"part{k}", me)
        if "emission" in rec:  # a photograph behind the head: seen, not lighting the face nor shadowed
            ob.visible_diffuse = ob.visible_glossy = ob.visible_transmission = ob.visible_shadow = False
        sc.collection.objects.link(ob)
        if rec.get("strands"):
            curves = _strands(bpy, "strands", parts[f"sp{k}"], parts[f"ss{k}"], parts[f"sr{k}"])
            curves.materials.append(_hair_material(bpy, rec))
            sc.collection.objects.link(bpy.data.objects.new("strands", curves))
    for i, light in enumerate(spec["lights"]):
        data = bpy.data.lights.new(f"light{i}", "SUN")
        data.energy = float(light["intensity"])
        data.color = light["color"]
        # a disc of spot samples at ``radius`` × distance: as wide as seen from the face
        data.angle = 2 * math.atan(light["radius"]) if light["kind"] == "disc" else math.radians(0.5)
        data.use_shadow = bool(light["shadow"])
        ob = bpy.data.objects.new(f"light{i}", data)
        ob.matrix_world = _matrix(_light_matrix(light["direction"]))
        sc.collection.objects.link(ob)
    cam = spec["camera"]
    cd = bpy.data.cameras.new("camera")
    cd.sensor_fit = "VERTICAL"
    cd.angle_y = math.radians(cam["yfov_deg"])
    dist = float(np.linalg.norm(np.subtract(cam["position"], cam["target"])))
    cd.clip_start, cd.clip_end = max(dist * 0.05, 1e-4), dist * 20
    co = bpy.data.objects.new("camera", cd)
    co.matrix_world = _matrix(_look_at(cam["position"], cam["target"], cam["up"]))
    sc.collection.objects.link(co)
    sc.camera = co
    return spec


def _matrix(m: np.ndarray):
    from mathutils import Matrix

    return Matrix([list(map(float, row)) for row in m])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Render an appeal-lab scene with Cycles.")
    ap.add_argument("scene", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=0)
    a = ap.parse_args(argv)
    import os

    # run as a script, this file's folder leads sys.path, and its sibling cycles.py would shadow
    # Blender's own "cycles" add-on
    here = Path(__file__).resolve().parent
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != here]
    import bpy

    build_scene(bpy, a.scene, a.samples, a.seed, a.threads or os.cpu_count() or 1)
    bpy.context.scene.render.filepath = str(a.out)
    bpy.ops.render.render(write_still=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
