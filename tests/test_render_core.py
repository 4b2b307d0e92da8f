"""The renderer core: determinism, background, framing, lighting presets, contact sheets."""

from __future__ import annotations

import hashlib
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from stimulus_engine.render import (
    LIGHTING_PRESETS,
    RenderPart,
    contact_sheet,
    face_camera,
    fit_camera,
    lighting_preset,
    render_mesh,
    save_png,
)


def _sphere(centre=(0.0, 0.0, 0.0), radius=1.0, color=(200, 150, 120, 255)) -> trimesh.Trimesh:
    m = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    m.apply_translation(centre)
    m.visual.vertex_colors = np.tile(np.array(color, np.uint8), (len(m.vertices), 1))
    return m


def test_same_inputs_give_identical_pixels_and_lighting_matters():
    m = [_sphere(), _sphere((1.2, 0.5, 0.4), 0.5)]
    a = render_mesh(m, width=160, height=120, lighting="direct_hard")
    b = render_mesh(m, width=160, height=120, lighting="direct_hard")
    assert a.shape == (120, 160, 3) and a.dtype == np.uint8
    assert a.tobytes() == b.tobytes()
    c = render_mesh(m, width=160, height=120, lighting="gi_soft")
    assert np.abs(a.astype(int) - c.astype(int)).max() > 20


_CHILD = """
import hashlib, numpy as np, trimesh
from stimulus_engine.render import render_mesh
m = trimesh.creation.icosphere(subdivisions=3)
m.visual.vertex_colors = np.tile(np.array([200, 150, 120, 255], np.uint8), (len(m.vertices), 1))
print(hashlib.sha256(render_mesh(m, width=96, height=72, lighting='direct_soft').tobytes()).hexdigest())
"""


def test_renders_are_identical_across_processes():
    m = _sphere()
    here = hashlib.sha256(render_mesh(m, width=96, height=72, lighting="direct_soft").tobytes()).hexdigest()
    out = subprocess.run([sys.executable, "-c", _CHILD], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == here


def test_background_is_fifty_percent_grey():
    img = render_mesh(_sphere(), width=64, height=48)
    assert tuple(img[0, 0]) == (128, 128, 128)
    assert tuple(img[-1, -1]) == (128, 128, 128)


def test_face_camera_puts_the_eye_point_at_the_requested_row_and_size():
    # a small sphere at the "eye midpoint": it must appear centred at (W/2, eye_row * H)
    eye = np.array([3.0, 5.0, -2.0])
    W, H = 200, 150
    cam = face_camera(eye, face_length=10.0, eye_row=0.3, face_fraction=0.5)
    img = render_mesh(_sphere(eye, 0.4, (255, 255, 255, 255)), width=W, height=H, camera=cam, lighting="flat")
    ys, xs = np.nonzero(np.abs(img.astype(int) - 128).sum(axis=2) > 30)
    assert abs(xs.mean() - (W - 1) / 2) < 1.0
    assert abs(ys.mean() - 0.3 * (H - 1)) < 1.0
    # a sphere of diameter 10 * 0.5 / 5 = 1/5 of face length would cover 0.5/10*0.8 of H ...
    # simpler: a sphere of radius 0.4 spans 2*0.4/10*0.5*H pixels vertically (same depth as the eyes)
    assert abs((ys.max() - ys.min() + 1) - 0.8 / 10 * 0.5 * H) <= 2


def test_fit_camera_sees_the_whole_mesh():
    m = _sphere((10, -4, 3), 2.0)
    cam = fit_camera(m.vertices, 4 / 3)
    img = render_mesh(m, width=80, height=60, camera=cam)
    fg = np.abs(img.astype(int) - 128).sum(axis=2) > 10
    assert fg.any() and not fg[0].any() and not fg[-1].any() and not fg[:, 0].any() and not fg[:, -1].any()


def test_all_presets_render_and_unknown_preset_is_rejected():
    m = RenderPart(_sphere(), smooth=False)
    for name in LIGHTING_PRESETS:
        img = render_mesh(m, width=48, height=36, lighting=name)
        assert img.std() > 1
    with pytest.raises(ValueError, match="unknown lighting preset 'sunny'.*direct_hard"):
        lighting_preset("sunny")
    with pytest.raises(ValueError, match="empty"):
        render_mesh([])


def test_shadows_darken_the_occluded_side():
    # a sphere above a floor; the key light comes from upper left so its shadow lies lower right
    floor = trimesh.creation.box(extents=(8, 0.2, 8))
    floor.apply_translation((0, -1.3, 0))
    floor.visual.vertex_colors = np.tile(np.array([220, 220, 220, 255], np.uint8), (len(floor.vertices), 1))
    scene = [_sphere(), floor]
    cam = fit_camera(np.vstack([floor.vertices, _sphere().vertices]), 4 / 3, view_dir=(0, 0.6, 1))
    with_s = render_mesh(scene, width=160, height=120, camera=cam, lighting="direct_hard")
    without = render_mesh(scene, width=160, height=120, camera=cam, lighting="direct_hard", shadows=False)
    darker = (without.astype(int) - with_s.astype(int)).sum(axis=2)
    assert (darker > 30).sum() > 50


def _darker_with_shadows(parts, light, camera=None):
    """Per pixel, how much darker (mean over RGB) the image gets when shadow maps are on; and depth."""
    a, depth = render_mesh(parts, width=320, height=240, lighting=light, camera=camera, return_depth=True)
    b = render_mesh(parts, width=320, height=240, lighting=light, camera=camera, shadows=False)
    return (b.astype(int) - a.astype(int)).mean(axis=2), depth


@pytest.mark.render
@pytest.mark.parametrize("light", ["direct_hard", "direct_soft"])
def test_a_convex_object_does_not_shadow_itself(light):
    # nothing can cast a shadow on a lone sphere: pyrender's shadow lookup darkened blocks of its
    # lit side (shadow acne following the triangles; 306 pixels with direct_hard)
    m = trimesh.creation.uv_sphere(radius=1.0, count=[24, 24])
    m.visual.vertex_colors = np.tile(np.array([200, 170, 150, 255], np.uint8), (len(m.vertices), 1))
    darker, depth = _darker_with_shadows(m, light)
    assert (darker[depth > 0] > 8).sum() == 0


@pytest.fixture(scope="module")
def plain_head():
    """A procedural head without texture (smooth shading: any abrupt step on its skin is an
    artefact) and its framing."""
    from stimulus_engine.characters.render_parts import rig_render_parts
    from stimulus_engine.characters.procedural_head import procedural_head

    rig = procedural_head(0, texture_size=64, resolution=48)
    lm = rig.landmark_points(rig.vertices)
    cam = face_camera((lm["eye_left"] + lm["eye_right"]) / 2, float(np.linalg.norm(lm["forehead_top"] - lm["chin"])))
    return rig_render_parts(rig, rig.vertices, None), cam


@pytest.mark.render
@pytest.mark.parametrize("light", ["direct_hard", "direct_soft", "gi_soft"])
def test_the_lit_cheek_of_a_face_has_no_shadow_staircase(plain_head, light):
    """The key light comes from the viewer's left, so nothing casts a shadow on the left cheek
    (left third of the face, below the eyes, 3 px inside the outline). Untextured skin there
    shades smoothly: no two neighbouring pixels may differ by more than 6 grey levels. Before
    the shadow fix, shadow-map blocks made 130 (direct_hard) and 249 (direct_soft) such steps,
    up to 44 levels high."""
    from scipy import ndimage

    parts, cam = plain_head
    img, depth = render_mesh(parts, width=320, height=240, lighting=light, camera=cam, return_depth=True)
    grey = img.astype(float).mean(axis=2)
    cheek = ndimage.binary_erosion(depth > 0, iterations=3)
    cols = np.nonzero(cheek.any(axis=0))[0]
    cheek[:, cols[0] + (cols[-1] - cols[0]) // 3:] = False
    cheek[: depth.shape[0] // 2] = False  # the eyes (row 0.42) shadow their sockets' rims
    assert cheek.sum() > 1000
    step = np.maximum(np.abs(np.diff(grey, axis=1))[:-1, :], np.abs(np.diff(grey, axis=0))[:, :-1])
    assert (step[cheek[:-1, :-1]] > 6).sum() == 0


@pytest.mark.render
def test_the_nose_still_casts_its_shadow(plain_head):
    parts, cam = plain_head
    darker, depth = _darker_with_shadows(parts, "direct_hard", cam)
    right = depth > 0
    cols = np.nonzero(right.any(axis=0))[0]
    right[:, : (cols[0] + cols[-1]) // 2] = False
    assert (darker[right] > 20).sum() > 200


def test_shadow_shader_patch_needs_the_pyrender_it_was_written_for():
    from pathlib import Path

    from stimulus_engine.render._pyrender import pyrender, shadow_fragment_shader

    original = (Path(pyrender.__file__).parent / "shaders" / "mesh.frag").read_text()
    patched = shadow_fragment_shader(original)
    assert "POISSON_DISK[16]" in patched and "float PCF(" not in patched
    assert patched.count("float shadow_calc(") == 1
    with pytest.raises(RuntimeError, match="pyrender's mesh.frag changed"):
        shadow_fragment_shader(original.replace("float PCF(", "float pcf("))


def test_every_light_of_a_preset_is_drawn():
    """gi_soft has 14 lights; pyrender drew at most 4 per type without shadow maps. Eight lights
    from eight directions: leaving out any one of them must change the picture."""
    from stimulus_engine.render import LightSpec

    m = _sphere()
    dirs = [(np.cos(a) * 0.8, np.sin(a) * 0.8, -0.6) for a in np.linspace(0, 2 * np.pi, 8, endpoint=False)]
    lights = [LightSpec("directional", tuple(map(float, d)), 0.8) for d in dirs]
    every = render_mesh(m, width=64, height=48, lighting=(lights, 0.05)).astype(int)
    for k in range(len(lights)):
        less = render_mesh(m, width=64, height=48, lighting=(lights[:k] + lights[k + 1:], 0.05)).astype(int)
        assert (every - less).sum(axis=2).max() > 30, k
    assert len(lighting_preset("gi_soft")[0]) > 4


def test_contact_sheet_layout_and_png(tmp_path):
    ims = [np.full((30, 40, 3), v, np.uint8) for v in (0, 80, 160, 240, 255)]
    sheet = contact_sheet(ims + [None], ncols=3, thumb_width=40, row_labels=["a", "b"],
                          col_labels=["x", "y", "z"], labels=list("123456"), title="t")
    assert sheet.ndim == 3 and sheet.shape[1] > 3 * 40 and sheet.shape[0] > 2 * 30
    p = save_png(sheet, tmp_path / "s.png")
    q = save_png(sheet, tmp_path / "t.png")
    assert p.read_bytes() == q.read_bytes()
    with pytest.raises(ValueError, match="no images"):
        contact_sheet([None], ncols=1)


def test_contact_sheet_title_is_not_cut_off():
    title = "a long heading: shape (rows) x lighting/shading (columns), original, neutral"
    sheet = contact_sheet([np.full((30, 40, 3), 128, np.uint8)] * 2, ncols=2, thumb_width=40, title=title)
    ink = np.nonzero((sheet[:12] < 100).all(axis=2).any(axis=0))[0]  # dark text pixels of the heading row
    assert ink.max() < sheet.shape[1] - 2
    wide = contact_sheet([np.full((30, 40, 3), 128, np.uint8)] * 2, ncols=2, thumb_width=40, title="t")
    assert sheet.shape[1] > wide.shape[1] + 100


def test_textured_parts_render_at_two_sizes_in_one_process():
    """Materials (and their textures) are shared between images; switching image size must not
    try to load a texture into a second OpenGL context (pyrender refuses that)."""
    from stimulus_engine.characters.render_parts import rig_render_parts
    from stimulus_engine.characters.procedural_head import procedural_head

    r = procedural_head(0, texture_size=64, resolution=24)
    a = render_mesh(rig_render_parts(r, r.vertices, r.texture), width=64, height=48, lighting="flat")
    b = render_mesh(rig_render_parts(r, r.vertices, r.texture), width=96, height=72, lighting="flat")
    c = render_mesh(rig_render_parts(r, r.vertices, r.texture), width=64, height=48, lighting="flat")
    assert b.shape == (72, 96, 3) and np.array_equal(a, c)


@pytest.mark.render
def test_textured_scan_has_no_dark_band_along_its_uv_seam(shared_data):
    """james's texture is two photographs; vertices on the seam between them carry two UVs. Drawn
    with one UV per vertex, the seam triangles sampled the dark background between the photos:
    a black band down the face (2.1 % of the central face box darker than 15/255; now 0.05 %)."""
    from stimulus_engine.geometry.mesh_io import load_mesh
    from stimulus_engine.render import CameraSpec
    from stimulus_engine.render.renderer import split_uv_seams

    mesh = load_mesh(shared_data / "meshes" / "menpo3d-james" / "james.obj")
    drawn = split_uv_seams(mesh)
    assert len(drawn.vertices) > len(mesh.vertices) and len(drawn.faces) == len(mesh.faces)
    np.testing.assert_allclose(drawn.vertex_normals, np.asarray(mesh.vertex_normals)[
        np.unique(np.c_[mesh.faces.ravel(), mesh.metadata["face_uv"].ravel()], axis=0)[:, 0]])
    v = np.asarray(mesh.vertices)
    c = (v.max(0) + v.min(0)) / 2
    cam = CameraSpec(tuple(c + [0.0, 0.0, 700.0]), tuple(c), 30.0, (0.0, 1.0, 0.0))
    img, depth = render_mesh(mesh, width=256, height=256, camera=cam, lighting="flat", shadows=False, return_depth=True)
    ys, xs = np.nonzero(depth > 0)
    h, w = ys.max() - ys.min(), xs.max() - xs.min()
    box = img[ys.min() + h * 30 // 100: ys.min() + h * 75 // 100, xs.min() + w * 35 // 100: xs.min() + w * 65 // 100]
    assert (box.max(axis=2) < 15).mean() < 0.005
    flat = trimesh.creation.icosphere()
    assert split_uv_seams(flat) is flat  # nothing to split


def test_downsample_averages_light_not_srgb_values():
    """Half of each output pixel's area lit (255) and half dark (0): the camera's sum of light is
    half the white's, sRGB 188, not the 128 an average of sRGB values gives."""
    from stimulus_engine.render.renderer import downsample

    img = np.zeros((4, 4, 3), np.uint8)
    img[:, ::2] = 255
    out = downsample(img, 2, 2)
    assert out.shape == (2, 2, 3) and np.all(np.abs(out.astype(int) - 188) <= 1)
    assert downsample(img, 4, 4) is img


def test_supersampling_smooths_a_silhouette():
    """A white sphere on black: drawn with one sample a pixel its outline is a staircase of
    pixels either lit or background; supersampled, the outline's pixels take the covered share
    of the light in between, and the image keeps the size asked for."""
    import trimesh

    from stimulus_engine.render import CameraSpec, render_mesh

    sphere = trimesh.creation.icosphere(subdivisions=4)
    cam = CameraSpec((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), 40.0, (0.0, 1.0, 0.0))
    kw = dict(width=96, height=96, camera=cam, lighting="flat", background=(0.0, 0.0, 0.0), shadows=False)
    hard, soft = render_mesh(sphere, **kw), render_mesh(sphere, supersample=2.0, **kw)
    assert soft.shape == hard.shape == (96, 96, 3)
    lum = [im.astype(float).mean(axis=2) for im in (hard, soft)]
    inner = [(lu > 0) & (lu < 0.5 * lu.max()) for lu in lum]  # pixels part lit, part background
    assert inner[1].sum() > 3 * max(inner[0].sum(), 1)
    with pytest.raises(ValueError, match="supersample"):
        render_mesh(sphere, supersample=0.5, **kw)
