"""Which lights cast shadows and how: the key light's own map, baked soft shadows of the skin shading."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from stimulus_engine.render import LightSpec, RenderPart, face_camera, fit_camera, lighting_preset, render_mesh
from stimulus_engine.render.light_shadows import (
    SHADOW_BAKED,
    SHADOW_KEY,
    SHADOW_MAP,
    SHADOW_NONE,
    light_shadow_fragment_shader,
)
from stimulus_engine.render.occlusion import cone_directions, light_visibility
from stimulus_engine.characters.render_parts import _new_material

SKIN = (0.85, 0.62, 0.52, 1.0)


def _floor(n: int = 61, size: float = 6.0) -> trimesh.Trimesh:
    """A finely triangulated floor (y = -1.3) facing up: the baked shadows live on its vertices."""
    g = np.linspace(-size / 2, size / 2, n)
    x, z = np.meshgrid(g, g)
    v = np.stack([x.ravel(), np.full(x.size, -1.3), z.ravel()], axis=1)
    i = np.arange(n * n).reshape(n, n)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel()
    return trimesh.Trimesh(v, np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)]), process=False)


def _modes(lighting: str, *, shadows: bool = True, baked: bool = False) -> tuple[list[float], int]:
    from stimulus_engine.render._pyrender import pyrender
    from stimulus_engine.render.renderer import _add_lights, _discs_as_suns

    lights, _ = lighting_preset(lighting)
    lights, baked = _discs_as_suns(lights) if baked else (lights, frozenset())
    scene = pyrender.Scene()
    cam = face_camera(np.zeros(3), 20.0)
    flags = _add_lights(scene, lights, cam, [0], np.array([[-1.0, -1, -1], [1, 1, 1]]), shadows=shadows, baked=baked)
    order = sorted(scene.light_nodes, key=hash)
    return [n.light.appeal_shadow for n in order], flags


def test_only_the_lights_a_preset_names_cast_shadows():
    from stimulus_engine.render._pyrender import pyrender

    # direct_hard: the key alone, through its own map (no pyrender shadow flags: rims and fill
    # used to render and filter maps of their own)
    modes, flags = _modes("direct_hard")
    assert modes.count(SHADOW_KEY) == 1 and set(modes) == {SHADOW_KEY, SHADOW_NONE} and flags == 0
    # direct_soft: its six spot samples; pyrender's spot maps, or baked where the materials read it
    modes, flags = _modes("direct_soft")  # on meshes without baked visibility
    assert modes.count(SHADOW_MAP) == 6 and flags == pyrender.RenderFlags.SHADOWS_SPOT
    # baked: the six samples shade as one light at the disc's centre (one highlight, not six)
    modes, flags = _modes("direct_soft", baked=True)
    assert modes.count(SHADOW_BAKED) == 1 and SHADOW_MAP not in modes and SHADOW_KEY not in modes and flags == 0
    from stimulus_engine.render.renderer import _discs_as_suns

    suns, which = _discs_as_suns(lighting_preset("direct_soft")[0])
    (k,) = which
    assert suns[k].kind == "directional" and suns[k].intensity == pytest.approx(3.2) and len(suns) == 4
    assert set(_modes("direct_hard", shadows=False)[0]) == {SHADOW_NONE}
    assert set(_modes("gi_soft")[0]) == {SHADOW_NONE}


def test_cone_directions_fill_the_disc_of_the_light():
    axis = np.array([0.3, 0.9, 0.1])
    d = cone_directions(axis, np.radians(10), 16)
    assert d.shape == (16, 3) and np.allclose(np.linalg.norm(d, axis=1), 1)
    angles = np.degrees(np.arccos(d @ (axis / np.linalg.norm(axis))))
    assert angles.max() <= 10.0 + 1e-6 and angles.min() < 3.0
    assert np.allclose(cone_directions(axis, np.radians(10), 1)[0], axis / np.linalg.norm(axis))


def test_light_visibility_of_a_floor_under_a_box():
    floor = _floor()
    box = trimesh.creation.box(extents=(1.0, 0.4, 1.0))
    box.apply_translation((0, -0.8, 0))  # 0.3 above the floor
    occ = (np.vstack([floor.vertices, box.vertices]), np.vstack([floor.faces, box.faces + len(floor.vertices)]))
    up = np.array([[0.0, 1.0, 0.0]])
    vis = light_visibility(floor.vertices, floor.vertex_normals, occ, up)
    x, z = floor.vertices[:, 0], floor.vertices[:, 2]
    under = (np.abs(x) < 0.45) & (np.abs(z) < 0.45)
    outside = (np.abs(x) > 0.55) | (np.abs(z) > 0.55)
    assert (vis[under] == 0).all() and (vis[outside] == 1).all()
    # a wide light: an umbra under the middle, a penumbra around the box, darker towards it
    soft = light_visibility(floor.vertices, floor.vertex_normals, occ, cone_directions(up[0], np.radians(25), 32))
    row = (np.abs(z) < 0.05) & (x > 0) & (x < 1.6)
    ordered = soft[row][np.argsort(x[row])]
    assert ordered[0] == 0 and ordered[-1] == 1 and ((ordered > 0.05) & (ordered < 0.95)).sum() >= 3
    assert (np.diff(ordered) >= -1e-6).all()
    # light from below the floor: the floor's own surface is in the way, as a shadow map has it
    assert (light_visibility(floor.vertices, floor.vertex_normals, occ, -up) == 0).all()


def _sphere_over_floor(shading: str) -> tuple[list, object]:
    sphere = trimesh.creation.icosphere(subdivisions=4)
    mat = _new_material(shading, SKIN, None, 0.62, scatter=shading == "skin")
    parts = [RenderPart(sphere, material=mat), RenderPart(_floor(), material=mat)]
    cam = fit_camera(np.vstack([p.mesh.vertices for p in parts]), 4 / 3, view_dir=(0, 0.6, 1))
    return parts, cam


def _darker(parts, cam, lighting: str) -> np.ndarray:
    a = render_mesh(parts, width=200, height=150, lighting=lighting, camera=cam).astype(int)
    b = render_mesh(parts, width=200, height=150, lighting=lighting, camera=cam, shadows=False).astype(int)
    return (b - a).mean(axis=2)


def test_baked_soft_shadow_lies_where_the_shadow_maps_put_it(monkeypatch):
    parts, cam = _sphere_over_floor("skin")
    baked = _darker(parts, cam, "direct_soft")
    # the same scene through pyrender's six spot shadow maps
    monkeypatch.setattr("stimulus_engine.render.renderer._wants_baked_shadows", lambda items: False)
    mapped = _darker(parts, cam, "direct_soft")
    a, b = baked > 8, mapped > 8
    assert a.sum() > 300 and b.sum() > 300
    assert (a & b).sum() / (a | b).sum() > 0.6  # the same shadow (vertex-interpolated vs per pixel)
    assert abs(baked[a & b].mean() - mapped[a & b].mean()) < 0.35 * mapped[a & b].mean()
    # a penumbra: a band of partial darkening between the umbra and the lit floor
    assert ((baked > 3) & (baked < 0.5 * baked.max())).sum() > 100


def test_the_soft_light_is_baked_under_every_shading():
    # the thesis's pbr/phong contrast gets the same smooth penumbra as skin (not six stacked edges)
    for shading in ("pbr", "phong"):
        parts, cam = _sphere_over_floor(shading)
        darker = _darker(parts, cam, "direct_soft")
        assert (darker > 8).sum() > 300, shading
        assert ((darker > 3) & (darker < 0.5 * darker.max())).sum() > 100, shading


def test_the_key_lights_map_casts_the_hard_shadow_under_every_shading():
    for shading in ("pbr", "skin", "phong"):
        parts, cam = _sphere_over_floor(shading)
        darker = _darker(parts, cam, "direct_hard")
        assert (darker > 20).sum() > 300, shading


def test_shader_patch_switches_every_light_loop():
    from stimulus_engine.render._pyrender import _mesh_shader_path

    for glossy in (False, True):  # the Phong branch repeats the light loops
        text = open(_mesh_shader_path(__import__("pyrender").__path__[0] + "/shaders", glossy)).read()
        assert text.count("float appeal_shadow;") == 2
        assert text.count("if (shadow_kind == 3.0)") == text.count("float key_lit =") == (2 if glossy else 1)
        assert "uniform sampler2D appeal_key_map;" in text
    with pytest.raises(RuntimeError, match="shadow lookup"):
        light_shadow_fragment_shader("void main() {}")


def test_a_user_light_without_our_switch_keeps_pyrenders_shadows():
    from stimulus_engine.render.light_shadows import casts_shadow_map

    class Plain:
        pass

    assert casts_shadow_map(Plain())
    # a list of LightSpecs given directly (not a preset name) goes the same way as a preset
    lights = ([LightSpec("directional", (0.55, -0.45, -0.7), 3.0, shadow=True)], 0.1)
    parts, cam = _sphere_over_floor("pbr")
    assert (_darker(parts, cam, lights) > 20).sum() > 300
