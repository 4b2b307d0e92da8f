"""The ``skin`` shading of the fast tier: scattering-softened skin, wet eyes, a filmic tone curve."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from stimulus_engine.render import LightSpec, RenderPart, render_mesh
from stimulus_engine.characters.render_parts import _new_material
from stimulus_engine.render.skin_shader import SCATTER_WRAP, skin_fragment_shader

SKIN = (0.85, 0.62, 0.52, 1.0)


def _sphere(shading: str, scatter: bool, intensity: float = 3.0, lighting=None) -> np.ndarray:
    """A skin-coloured sphere lit from the side (terminator through the middle of the image)."""
    s = trimesh.creation.icosphere(subdivisions=4)
    mat = _new_material(shading, SKIN, None, 0.62, scatter=scatter)
    lights = lighting or ([LightSpec("directional", (-1.0, 0.0, -0.15), intensity)], 0.0)
    return render_mesh([RenderPart(s, material=mat)], width=160, height=120, lighting=lights, shadows=False)


def test_without_its_switches_the_patched_shader_draws_what_pbr_drew():
    a = _sphere("pbr", scatter=True)  # pbr materials carry no switches: scatter is ignored
    b = _sphere("pbr", scatter=False)
    assert np.array_equal(a, b)


def test_scattering_reddens_and_softens_the_terminator():
    pbr = _sphere("pbr", False).astype(float)
    skin = _sphere("skin", True).astype(float)
    # a band just past the terminator (the light comes from the image's right): dark under pbr,
    # lit by scattered, reddish light under skin
    row = slice(50, 70)
    centre = 80
    band = (slice(None), slice(centre - 22, centre - 8))
    p, s = pbr[row][band], skin[row][band]
    assert s[..., 0].mean() > p[..., 0].mean() + 10
    assert (s[..., 0] - s[..., 1]).mean() > (p[..., 0] - p[..., 1]).mean() + 5
    # lit side: similar brightness (the wrap leaves fully lit skin alone; the tone curve moves it a little)
    lit = (row, slice(centre + 25, centre + 40))
    assert abs(skin[lit].mean() - pbr[lit].mean()) < 40


def test_filmic_curve_rolls_highlights_off_instead_of_clipping():
    pbr = _sphere("pbr", False, intensity=12.0)
    skin = _sphere("skin", True, intensity=12.0)
    assert (pbr == 255).all(axis=-1).sum() > 200  # pyrender's pow(1/2.2) clips an over-lit sphere
    assert (skin == 255).all(axis=-1).sum() < (pbr == 255).all(axis=-1).sum() / 4


def test_background_stays_50_percent_grey_and_skin_renders_are_deterministic():
    a, b = _sphere("skin", True), _sphere("skin", True)
    assert np.array_equal(a, b)
    assert (a[0, 0] == 128).all() and (a[-1, -1] == 128).all()


def test_skin_shading_in_a_grid(tmp_path):
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile

    p = tmp_path / "g.yaml"
    p.write_text("""kind: grid
name: skin
characters:
  - name: a
    procedural: {seed: 4, texture_size: 128, resolution: 32}
shapes: [0.0]
materials: [original]
expressions: [neutral]
lighting: [direct_soft]
shading: [pbr, skin, phong, toon]
render: {width: 96, height: 72}
""")
    manifest, _ = run_grid(load_study_file(p, GridFile), tmp_path / "out", n_jobs=1)
    assert (manifest["status"] == "rendered").all() and set(manifest["shading"]) == {"pbr", "skin", "phong", "toon"}
    assert len(set(manifest["input_hash"])) == 4


def test_patch_refuses_another_pyrender_shader():
    with pytest.raises(RuntimeError, match="pyrender's mesh.frag changed"):
        skin_fragment_shader("void main() {}")
    assert all(0 < w < 1 for w in SCATTER_WRAP) and SCATTER_WRAP[0] > SCATTER_WRAP[1] > SCATTER_WRAP[2]


def test_baked_occlusion_darkens_concavities_only():
    from stimulus_engine.render.occlusion import vertex_occlusion

    sphere = trimesh.creation.icosphere(subdivisions=3)
    vis = vertex_occlusion(sphere.vertices, sphere.faces, sphere.vertex_normals)
    assert vis.min() > 0.99  # a convex surface sees its whole hemisphere
    # the inside of a bowl (a sphere's lower half seen from inside) is occluded, most at the bottom
    bowl = sphere.vertices[:, 2] < 0.2
    keep = bowl[sphere.faces].all(axis=1)
    cup = trimesh.Trimesh(sphere.vertices, sphere.faces[keep][:, ::-1], process=False)  # normals inwards
    used = np.unique(cup.faces)
    vis_cup = vertex_occlusion(cup.vertices, cup.faces, cup.vertex_normals, reach=1.0)[used]
    z = cup.vertices[used][:, 2]
    bottom, rim = z < -0.9, z > 0.0  # the rim sees out of the bowl's opening
    assert vis_cup[bottom].mean() < 0.8 and vis_cup[bottom].mean() < vis_cup[rim].mean() - 0.05
    again = vertex_occlusion(cup.vertices, cup.faces, cup.vertex_normals, reach=1.0)[used]
    assert np.array_equal(vis_cup, again)  # a fixed ray pattern: the bake is deterministic


def test_occlusion_dims_only_the_ambient_light_of_skin_shading():
    s = trimesh.creation.icosphere(subdivisions=3)
    half = np.full(len(s.vertices), 0.5, np.float32)

    def render(shading: str, occlusion, ambient: float, light: float) -> float:
        mat = _new_material(shading, SKIN, None, 0.62, scatter=False)
        lights = ([LightSpec("directional", (0.0, 0.0, -1.0), light)] if light else [], ambient)
        img = render_mesh([RenderPart(s, material=mat, occlusion=occlusion)], width=64, height=48,
                          lighting=lights, shadows=False)
        return float(img[20:28, 28:36].mean())

    # ambient only: half the visibility, darker; direct only: the occlusion changes nothing
    assert render("skin", half, 0.6, 0.0) < render("skin", None, 0.6, 0.0) - 10
    assert abs(render("skin", half, 0.0, 2.0) - render("skin", None, 0.0, 2.0)) < 1
    # pbr and phong materials ignore it (pyrender would otherwise multiply the whole colour by it)
    assert abs(render("pbr", half, 0.6, 2.0) - render("pbr", None, 0.6, 2.0)) < 1
    assert abs(render("phong", half, 0.6, 2.0) - render("phong", None, 0.6, 2.0)) < 1


@pytest.mark.parametrize("shading", ["pbr", "skin"])
def test_an_eye_reflects_a_dome_of_lights_as_one_glint(shading):
    """Under gi_soft (a dozen lights around the camera) a glossy ball shows a ring of sharp dots;
    the eye's EYE_GLINT switch gives one glint, centred where the lights' mean direction
    reflects, and keeps the ball's diffuse shading."""
    from scipy import ndimage

    from stimulus_engine.characters.render_parts import _material

    ball = trimesh.creation.icosphere(subdivisions=5)
    grey = (0.6, 0.6, 0.6, 1.0)
    imgs, body = {}, None
    for glint in (False, True):
        mat = _material(shading, grey, None, 0.05, glint=glint)
        img, depth = render_mesh([RenderPart(ball, material=mat)], width=200, height=200, lighting="gi_soft",
                                 shadows=False, return_depth=True)
        imgs[glint], body = img.astype(float).mean(axis=2), depth > 0
    spots = {glint: ndimage.label(img > np.percentile(img[body], 99.0) * 0.98)[1] for glint, img in imgs.items()}
    assert spots[False] >= 4 and spots[True] == 1, spots
    # the ball's diffuse shading is the same away from the glints: the switch only gathers them
    calm = body & (imgs[False] < np.percentile(imgs[False][body], 80)) & (imgs[True] < np.percentile(imgs[True][body], 80))
    assert calm.sum() > 1000 and np.abs(imgs[False][calm] - imgs[True][calm]).mean() < 6


@pytest.mark.parametrize("lighting", ["gi_soft", "direct_soft"])
def test_the_catch_light_is_a_small_window(lighting):
    """The eye's catch-light is a window, wider than tall and a small share of the iris, not a
    round spot a third of it wide: on a ball 200 px across its core is at most 16 px wide, 1.2-1.8
    times wider than tall, and fills its box as a rectangle does (an ellipse fills pi/4 of it)."""
    from scipy import ndimage

    from stimulus_engine.characters.render_parts import _material

    ball = trimesh.creation.icosphere(subdivisions=6)
    dark = (0.2, 0.2, 0.2, 1.0)  # a dark iris: only the catch-light is bright
    img, depth = render_mesh([RenderPart(ball, material=_material("pbr", dark, None, 0.05, glint=True))], width=400,
                             height=400, lighting=lighting, shadows=False, return_depth=True)
    lum = img.astype(float).mean(axis=2)
    core = (lum > 0.5 * (lum.max() + np.median(lum[depth > 0]))) & (depth > 0)
    labels, n = ndimage.label(core)
    assert n == 1
    rows, cols = np.nonzero(core)
    w, h = np.ptp(cols) + 1, np.ptp(rows) + 1
    assert w <= 16 and 1.2 <= w / h <= 1.8, (w, h)
    assert core.sum() / (w * h) > 0.8


@pytest.mark.parametrize("shading", ["pbr", "skin"])
def test_hair_highlights_run_across_the_strands(shading):
    """Kajiya-Kay hair (HAIR_KAJIYA): a ball combed around its vertical axis, lit from the camera,
    shows its sheen as a vertical band across the horizontal strands, where an isotropic lobe
    shows a round spot."""
    from stimulus_engine.characters.render_parts import _hair_material, _material

    ball = trimesh.creation.icosphere(subdivisions=5)
    ball.visual = trimesh.visual.TextureVisuals(uv=0.5 + 0.5 * ball.vertices[:, :2])
    strands = np.cross([0.0, 1.0, 0.0], ball.vertices)  # around the vertical axis
    strands[np.linalg.norm(strands, axis=1) < 1e-9] = [1.0, 0.0, 0.0]
    strands /= np.linalg.norm(strands, axis=1, keepdims=True)
    texture = np.full((8, 8, 4), 200, np.uint8)
    texture[..., 3] = 255
    mat = _hair_material(shading, (0.5, 0.45, 0.4), texture)
    assert mat.appeal_defines.get("HAIR_KAJIYA") == 1
    light = ([LightSpec("directional", (0.0, 0.0, -1.0), 3.0)], 0.0)
    shapes = {}
    plain = _material(shading, (0.5, 0.45, 0.4, 1.0), None, 0.3)
    for name, part in (("strands", RenderPart(ball, material=mat, tangents=strands)), ("isotropic", RenderPart(ball, material=plain))):
        img, depth = render_mesh([part], width=200, height=200,
                                 lighting=light, shadows=False, return_depth=True)
        lum = img.astype(float).mean(axis=2)
        bright = (lum > np.percentile(lum[depth > 0], 95)) & (depth > 0)
        rows, cols = np.nonzero(bright)
        shapes[name] = np.ptp(rows) / max(np.ptp(cols), 1)
    assert shapes["strands"] > 3 and shapes["isotropic"] < 2, shapes


def _tones(image: np.ndarray, keep: np.ndarray, k: int = 3, width: int = 6) -> float:
    """The share of the ``keep`` pixels whose luma falls in the ``k`` fullest bins ``width`` wide."""
    luma = image[..., :3].astype(float) @ np.array([0.299, 0.587, 0.114])
    counts = np.bincount((luma[keep] // width).astype(int))
    return float(np.sort(counts)[-k:].sum() / keep.sum())


def test_toon_shading_paints_the_light_in_a_few_flat_bands():
    """A sphere lit from the side (a key light and ambient light): ``skin`` shades it in a smooth
    ramp, ``toon`` in a few flat tones with narrow edges (a lit side, a shadow side), as bright,
    with the scattering's warmth and the tone curve kept; under a dome of a dozen lights
    (``gi_soft``) as bright and warm as ``skin`` too."""
    from stimulus_engine.render import lighting_preset

    def flat_share(image: np.ndarray, sphere: np.ndarray) -> float:
        inside = sphere[:, 1:-1] & sphere[:, 2:] & sphere[:, :-2]
        return float((np.diff(image[..., 1].astype(int), axis=1)[:, :-1][inside] == 0).mean())

    side = ([LightSpec("directional", (-1.0, 0.0, -0.6), 2.0)], 0.3)
    for lights in (side, lighting_preset("gi_soft")):
        skin, toon = _sphere("skin", True, lighting=lights), _sphere("toon", True, lighting=lights)
        sphere = np.abs(skin.astype(int) - 128).sum(axis=-1) > 0
        assert abs(toon[sphere].mean() - skin[sphere].mean()) < 20
        assert (toon[sphere][:, 0] > toon[sphere][:, 2] + 10).all()  # skin-warm, not grey
    sphere = np.abs(_sphere("skin", True, lighting=side).astype(int) - 128).sum(axis=-1) > 0
    skin, toon = _sphere("skin", True, lighting=side), _sphere("toon", True, lighting=side)
    assert _tones(toon, sphere) > 0.7 and _tones(skin, sphere) < 0.5, (_tones(toon, sphere), _tones(skin, sphere))
    assert flat_share(toon, sphere) > 2 * flat_share(skin, sphere)  # flat inside the bands
    assert np.array_equal(toon, _sphere("toon", True, lighting=side))  # deterministic
