"""Expressions, deformation transfer, stylisation, materials and neoteny on small and real data."""

from __future__ import annotations

import numpy as np
import pytest

from stimulus_engine.characters.expressions import (
    apply_expression,
    deformation_transfer,
    expression_weights,
    resolve_expression,
)
from stimulus_engine.characters.ict import load_ict_rig
from stimulus_engine.stylisation.materials import stylise_albedo
from stimulus_engine.stylisation.neoteny import neoteny_measures
from stimulus_engine.characters.procedural_head import procedural_head
from stimulus_engine.characters.render_parts import rig_render_parts
from stimulus_engine.stylisation.shape import stylise


@pytest.fixture(scope="module")
def ict(shared_data):
    return load_ict_rig(shared_data / "meshes/ict-facekit", "identity000",
                        shapes=["mouthSmile_L", "mouthSmile_R", "cheekSquint_L", "cheekSquint_R", "mouthDimple_L",
                                "mouthDimple_R", "mouthLowerDown_L", "mouthLowerDown_R", "jawOpen"])


def test_recipes_weights_and_aliases():
    w = expression_weights("happy", 0.5)
    assert w == {"cheekSquint_L": 0.4, "cheekSquint_R": 0.4, "mouthSmile_L": 0.5, "mouthSmile_R": 0.5,
                 "mouthDimple_L": 0.1, "mouthDimple_R": 0.1, "mouthLowerDown_L": 0.125, "mouthLowerDown_R": 0.125}
    assert expression_weights("neutral") == {}
    assert resolve_expression("Angry") == "anger"
    with pytest.raises(ValueError, match="unknown expression 'smug'.*happiness"):
        resolve_expression("smug")


def test_deformation_transfer_on_a_tetrahedron_is_exact_for_affine_maps():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1.0]])
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [1, 4, 2], [2, 4, 3], [1, 3, 4]])
    A = np.array([[1.2, 0.1, 0], [0, 0.9, 0.2], [0.1, 0, 1.1]])
    moved = v.copy()
    moved[4] = A @ v[4] - A @ v[1] + v[1]  # only vertex 4 moves, by the affine map about vertex 1
    # the same deformation carried to the same rest shape reproduces it
    out = deformation_transfer(v, moved, v, f)
    assert np.allclose(out, moved, atol=1e-6)
    # on a uniformly scaled target the moved vertex follows the scaled deformation
    out2 = deformation_transfer(v, moved, 2 * v, f)
    assert np.allclose(out2[:4], 2 * v[:4])
    assert np.linalg.norm(out2[4] - 2 * moved[4]) < np.linalg.norm(2 * v[4] - 2 * moved[4])


def test_ict_expression_and_transfer_to_stylised_shape(ict):
    v = apply_expression(ict, "happiness")
    d = np.linalg.norm(v - ict.vertices, axis=1)
    lm = ict.landmarks
    # the smile moves the mouth corners up, the forehead not at all
    corner = lm["mouth_left"][0]
    assert v[corner, 1] - ict.vertices[corner, 1] > 0.3
    assert d[lm["forehead_top"][0]] < 0.1 * d[corner]
    # transfer onto the rig's own neutral is the plain blendshape sum
    same = apply_expression(ict, "happiness", target=ict.vertices.copy())
    assert np.abs(same - v).max() < 1e-6
    # onto a stylised shape: the corners still move up; level 0 stylisation is the identity
    assert np.array_equal(stylise(ict, 0.0), ict.vertices)
    s = stylise(ict, 1.0)
    t = apply_expression(ict, "happiness", target=s)
    assert t[corner, 1] - s[corner, 1] > 0.2
    with pytest.raises(ValueError, match="lacks blendshape"):
        apply_expression(ict, "surprise")


def test_stylisation_is_continuous_and_neotenic(ict):
    m = [neoteny_measures(ict.landmark_points(stylise(ict, lv))) for lv in (0.0, 0.5, 1.0)]
    assert m[0]["eye_width"] < m[1]["eye_width"] < m[2]["eye_width"]
    assert m[0]["nose_width"] > m[2]["nose_width"]
    assert m[0]["mouth_width"] > m[2]["mouth_width"]
    assert m[0]["eye_position"] < m[2]["eye_position"] or m[0]["forehead_height"] < m[2]["forehead_height"]
    a, b = stylise(ict, 0.50), stylise(ict, 0.51)
    assert np.abs(a - b).max() < 0.1  # a small step in level is a small step in shape
    with pytest.raises(ValueError, match="within 0..1"):
        stylise(ict, 1.5)


def test_albedo_stylisations():
    rng = np.random.default_rng(0)
    img = (rng.random((64, 64, 3)) * 255).astype(np.uint8)
    lips = np.zeros((64, 64), np.float32)
    lips[20:30, 20:40] = 1
    img[20:30, 20:40] = (200, 40, 40)
    flat = stylise_albedo(img, "flat", {"lips": lips})
    assert (flat[25, 30] == (200, 40, 40)).all()
    assert len(np.unique(flat[lips == 0].reshape(-1, 3), axis=0)) == 1
    blur = stylise_albedo(img, "blur50", {"lips": lips})
    assert blur[lips == 0].std() < img[lips == 0].std()
    assert (blur[25, 30] == (200, 40, 40)).all()  # lips blurred on their own: no skin bleeds in
    assert stylise_albedo(img, "bilateral").std() < img.std()
    assert np.array_equal(stylise_albedo(img, "original"), img)
    with pytest.raises(ValueError, match="unknown material style 'gold'"):
        stylise_albedo(img, "gold")


def test_procedural_head_is_deterministic_and_textured():
    a = procedural_head(4, texture_size=64, resolution=24)
    b = procedural_head.__wrapped__(4, texture_size=64, resolution=24) if hasattr(procedural_head, "__wrapped__") \
        else procedural_head(4, texture_size=64, resolution=24)
    assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.texture, b.texture)
    c = procedural_head(5, texture_size=64, resolution=24)
    assert not np.array_equal(a.texture, c.texture)
    assert a.texture_masks["lips"].max() == 1.0
    parts = rig_render_parts(a, a.vertices, a.texture)
    assert {p.name for p in parts} == {"skin", "eye"}  # eyes: one textured part (sclera, iris, pupil)
    no_uv = a.with_vertices(a.vertices)
    no_uv.uv = None
    with pytest.raises(ValueError, match="no UVs but a texture was asked for"):
        rig_render_parts(no_uv, a.vertices, a.texture)


def test_eye_texture_and_eyeball_uv():
    from stimulus_engine.parts.eyes import eye_texture, eyeball_uv, fit_sphere

    tex = eye_texture(128)
    assert tex[64, 64].max() < 20  # pupil at the centre
    iris = tex[64, 64 + int(64 * np.sin(np.radians(16) / 2))]  # 16° from the axis: iris (brown)
    assert iris[0] > iris[2] and 40 < iris.mean() < 160
    sclera = tex[64, 64 + int(64 * np.sin(np.radians(60) / 2))]
    assert sclera.min() > 200
    assert tex[64, 2].max() < 20  # the back of the ball is dark (seen through a pupil hole)
    # a unit sphere: the gaze point maps to the UV centre, the side to radius 0.5·sin(45°)
    d = np.array([[0, 0, 1.0], [1, 0, 0], [0, 1, 0], [0, 0, -1.0]])
    uv = eyeball_uv(np.array([2.0, 0, 0]) + d, np.array([2.0, 0, 0]), np.array([0, 0, 1.0]))
    assert np.allclose(uv[0], [0.5, 0.5])
    assert np.allclose(uv[1], [0.5 + 0.5 * np.sin(np.pi / 4), 0.5])
    assert np.allclose(uv[2], [0.5, 0.5 + 0.5 * np.sin(np.pi / 4)])
    assert np.isclose(np.linalg.norm(uv[3] - 0.5), 0.5)
    c, r = fit_sphere(np.array([1.0, -1, 0.5]) + 3 * d)
    assert np.allclose(c, [1, -1, 0.5]) and np.isclose(r, 3)
    with pytest.raises(ValueError, match="pupil_angle < iris_angle"):
        eye_texture(64, iris_angle=5.0, pupil_angle=8.0)


def test_ict_eyes_render_open_with_iris_and_sclera(ict):
    """The corneal caps and lower lash cards are hidden; an eye close-up shows sclera, iris, pupil."""
    from stimulus_engine.render import face_camera, render_mesh

    names = ict.part_names
    cap = ((ict.faces >= 21451) & (ict.faces <= 22220)).any(axis=1)
    assert (ict.face_part[cap] == names.index("hidden")).all()
    ball = ((ict.faces >= 22221) & (ict.faces <= 23020)).all(axis=1)
    assert (ict.face_part[ball] == names.index("eye")).all() and "eye" in ict.part_textures
    lash = ict.face_part == names.index("lashes")
    assert 0 < lash.sum() < 2160 / 2  # upper lashes only
    lm = ict.landmark_points()
    cam = face_camera(lm["eye_left"], 4.0, eye_row=0.5, face_fraction=1.0)
    img = render_mesh(rig_render_parts(ict, ict.vertices, None), width=96, height=72, camera=cam,
                      lighting="flat").astype(int)
    centre = img[30:42, 42:54]
    assert centre.max(axis=2).min() < 45  # the pupil is dark
    row = img[36, 10:86]
    assert (row.min(axis=1) > 150).sum() >= 6  # white sclera on either side of the iris


def test_thesis_expressions_are_clearly_different_from_neutral(shared_data):
    """At intensity 1 each expression moves its key features by millimetres, not fractions of one."""
    rig = load_ict_rig(shared_data / "meshes/ict-facekit", "identity000")
    v0 = rig.vertices
    lm = rig.landmarks

    def moved(expr: str, name: str) -> np.ndarray:
        v = apply_expression(rig, expr)
        return (v[lm[name]] - v0[lm[name]]).mean(axis=0)

    brow = lambda e: (moved(e, "brow_left") + moved(e, "brow_right"))[1] / 2  # noqa: E731
    gap = lambda e: (apply_expression(rig, e)[lm["mouth_top"][0], 1]  # noqa: E731
                     - apply_expression(rig, e)[lm["mouth_bottom"][0], 1])
    assert brow("anger") < -0.5 and brow("surprise") > 0.5  # cm: brows lowered / raised
    assert gap("anger") > gap("neutral") + 0.3 and gap("surprise") > gap("neutral") + 1.0  # mouth opens
    corner = lambda e: (moved(e, "mouth_left") + moved(e, "mouth_right"))[1] / 2  # noqa: E731
    assert corner("happiness") > 0.5 and corner("sadness") < -0.3
    inner_brow = moved("sadness", "brow_left")[1] - (apply_expression(rig, "sadness") - v0)[lm["brow_left"][-1], 1]
    assert inner_brow > 0.1  # sad brows are oblique: the inner end rises more than the outer


def test_deformation_transfer_reuses_its_factorisation_bit_identically():
    from stimulus_engine.characters import expressions as ex
    from stimulus_engine.characters.procedural_head import procedural_head
    from stimulus_engine.stylisation.shape import stylise

    rig = procedural_head(seed=4, texture_size=64, resolution=32)
    targets = [stylise(rig, s) for s in (0.25, 0.5, 1.0)]
    ex._DT_SYSTEMS.clear()
    cached = [ex.apply_expression(rig, "surprise", target=t) for t in targets]
    assert len(ex._DT_SYSTEMS) == 1  # one factorisation for all three levels
    fresh = []
    for t in targets:
        ex._DT_SYSTEMS.clear()
        fresh.append(ex.apply_expression(rig, "surprise", target=t))
    assert all(np.array_equal(a, b) for a, b in zip(cached, fresh))
    assert not np.allclose(cached[0], cached[2])


@pytest.mark.parametrize("roll_deg", [0.0, 4.0, -9.0])
def test_framing_levels_the_eyes_of_a_tilted_head(roll_deg):
    """A scan sits as scanned, often rolled: the grid's camera turns with it so both eye centres
    project to one image row, at the eye row asked for."""
    from stimulus_engine.grid.prepare import level_up
    from stimulus_engine.render import face_camera

    a = np.radians(roll_deg)
    rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    right, left = rot @ [-3.1, 2.0, 9.0], rot @ [3.1, 2.0, 9.0]
    cam = face_camera((right + left) / 2, 20.0, eye_row=0.4, face_fraction=0.7, up=level_up(right, left))
    world_to_cam = np.linalg.inv(cam.pose())
    rows = []
    for p in (right, left):
        x, y, z = (world_to_cam @ np.append(p, 1.0))[:3]
        rows.append(y / -z)
    assert rows[0] == pytest.approx(rows[1], abs=1e-12)
    tan_half = np.tan(np.radians(cam.yfov_deg) / 2)
    assert 0.5 - rows[0] / (2 * tan_half) == pytest.approx(0.4)


def test_the_lids_wet_line_is_a_clear_glossy_film(ict, tmp_path):
    """The ICT rig's lacrimal fluid is drawn as the lids' wet line: a thin strip along each eye
    (between the corners, at the lid margins), alpha-blended and glossy in pyrender, and cut
    out by its own alpha in the path tracer's export."""
    from stimulus_engine.render.scene_export import _material_record

    tear = ict.faces[ict.face_part == ict.part_names.index("tear")]
    assert len(tear) == 2 * 2 * 163  # both sides' lacrimal fluid (ICT's table: 163 quads each)
    lm = ict.landmark_points()
    iod = float(np.linalg.norm(lm["eye_left"] - lm["eye_right"]))
    centres = ict.vertices[tear].mean(axis=1)
    near_eye = np.minimum(*(np.linalg.norm(centres - ict.vertices[ict.landmarks[f"eye_{s}"]].mean(axis=0), axis=1)
                            for s in ("left", "right")))
    assert near_eye.max() < 0.5 * iod  # on the eyes, nowhere else
    parts = {p.name: p for p in rig_render_parts(ict, ict.vertices, None)}
    mat = parts["tear"].material
    assert mat.alphaMode == "BLEND" and mat.baseColorFactor[3] < 0.5 and mat.roughnessFactor < 0.1
    rec = _material_record("tear", mat, tmp_path, 0)
    assert rec["alpha_blend"] and rec["base_color"][3] < 0.5 and "texture" not in rec


def test_the_eye_shadow_texture_darkens_the_lid_margins_and_paints_the_caruncle():
    from stimulus_engine.parts.eyes import EYE_SHADOW_UPPER, eye_shadow_texture

    t = eye_shadow_texture(128).astype(float)
    a = t[..., 3] / 255

    def at(u: float, v: float) -> np.ndarray:  # UV (0, 0) bottom-left: outer corner, lower lid
        return t[int((1 - v) * 127), int(u * 127)]

    assert at(0.5, 0.55)[3] < 5  # the middle of the eye: clear
    assert at(0.5, 0.98)[3] / 255 > 0.9 * EYE_SHADOW_UPPER  # under the upper lid: the darkest band
    assert at(0.5, 0.02)[3] < at(0.5, 0.98)[3]  # the lower lid's shadow is lighter
    assert a[:, :8].mean() > 0.3  # the outer corner
    car = at(0.97, 0.5)
    assert car[3] > 180 and car[0] - car[1] > 50 and car[0] > 150  # the caruncle: opaque pink
    assert (t[..., :3].mean(axis=2)[a > 0.3] < 120).mean() > 0.6  # the shadow itself is dark


def test_the_eye_shadow_lies_on_the_eyeballs_and_darkens_only_the_eye(ict):
    """The ICT rig's eye-occlusion shells are drawn as the eye's shadow: alpha-blended on their
    texture, laid just outside each eyeball's sphere (so only the lids' opening shows them), in
    every pose; the render differs from one without them only where the eye shows."""
    from stimulus_engine.characters.render_parts import EYE_SHADOW_LIFT, _eyeballs
    from stimulus_engine.render import render_mesh
    from stimulus_engine.render.camera import face_camera

    smile = apply_expression(ict, "happiness")
    for v in (ict.vertices, smile):
        parts = {p.name: p for p in rig_render_parts(ict, v, None)}
        shadow = parts["eye_shadow"]
        assert shadow.material.alphaMode == "BLEND" and shadow.material.baseColorTexture is not None
        centres, radii = _eyeballs(ict, v)
        d = np.linalg.norm(shadow.mesh.vertices[:, None] - centres[None], axis=2).min(axis=1)
        assert np.allclose(d, radii.mean() * (1 + EYE_SHADOW_LIFT), rtol=0.02)
    parts = rig_render_parts(ict, ict.vertices, None)
    lm = ict.landmark_points()
    iod = float(np.linalg.norm(lm["eye_left"] - lm["eye_right"]))
    cam = face_camera((lm["eye_left"] + lm["eye_right"]) / 2, iod, eye_row=0.5)  # the eyes fill the frame
    kw = dict(width=320, height=240, lighting="gi_soft", return_depth=True, camera=cam)
    with_shadow, d_with = render_mesh(parts, **kw)
    without, d_without = render_mesh([p for p in parts if p.name != "eye_shadow"], **kw)
    changed = np.abs(with_shadow.astype(int) - without.astype(int)).max(axis=2) > 2
    front = d_with < d_without - 1e-4 * d_without.max()  # the shadow is the nearest surface there
    eye = render_mesh([p for p in parts if p.name == "eye"], **kw)[1] > 0
    assert changed.sum() > 20 and front.sum() > 20
    assert (changed & ~eye).sum() <= 0.02 * changed.sum()  # nothing on the lids or the skin
