"""Hair for bald rigs: the shipped asset, its fit onto a rig, posing, rendering and the grid field."""

from __future__ import annotations

import importlib.util
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh

from stimulus_engine.parts.hair import (
    HAIR_STYLES, MIN_LIFT_IOD, Hair, fit_hair, hair_arrays, hair_asset, hair_from_arrays, head_points, linear_rgb,
)

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def ict(shared_data):
    from stimulus_engine.characters.ict import load_ict_rig

    return load_ict_rig(shared_data / "meshes" / "ict-facekit", "identity000")


def _skin(rig) -> trimesh.Trimesh:
    return trimesh.Trimesh(rig.vertices, rig.faces[rig.face_part == rig.part_names.index("skin")], process=False)


@pytest.mark.parametrize("style", sorted(HAIR_STYLES))
def test_the_shipped_assets_are_consistent(style):
    a = hair_asset(style)
    assert a.anchors.shape == (len(a.uv), 3) and a.lift.shape == (len(a.uv),) and a.head.shape == (7, 3)
    assert a.offset.shape == (len(a.uv), 3)
    np.testing.assert_allclose(np.abs(a.lift), np.minimum(np.linalg.norm(a.offset, axis=1), np.abs(a.lift)))
    assert a.faces.max() == len(a.uv) - 1 and a.texture.shape == (512, 512, 4)
    alpha = a.texture[..., 3]
    assert set(np.unique(alpha)) == {0, 255}  # alpha-tested: hair or nothing
    assert 0.1 < (alpha == 255).mean() < 0.97


def test_an_unknown_style_is_named():
    with pytest.raises(ValueError, match="unknown hair style 'long'.*long01"):
        hair_asset("long")


def test_the_asset_script_rebuilds_the_shipped_files(shared_data, tmp_path):
    from PIL import Image

    spec = importlib.util.spec_from_file_location("make_hair_asset", ROOT / "scripts" / "make_hair_asset.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    mod.main(shared_data / "meshes" / "makehuman-cc0", tmp_path)
    assert set(mod.STYLES) == set(HAIR_STYLES.values())
    for style in mod.STYLES:
        new, old = np.load(tmp_path / f"{style}.npz"), np.load(ROOT / "stimulus_engine" / "data" / "hair" / f"{style}.npz")
        for k in old.files:
            np.testing.assert_allclose(new[k], old[k], atol=1e-6, err_msg=f"{style} {k}")
        assert np.array_equal(np.asarray(Image.open(tmp_path / f"{style}.png").convert("RGBA")), hair_asset(style).texture)


def test_head_points_find_top_back_front_and_sides_of_a_sphere():
    s = trimesh.creation.icosphere(subdivisions=4, radius=10.0)
    eyes = np.array([[-3.0, 0.0, 9.0], [3.0, 0.0, 9.0]])
    p = head_points(s.vertices, *eyes)
    np.testing.assert_allclose(p[:2], eyes)
    assert p[2, 1] == pytest.approx(10.0, abs=0.2)  # top
    assert p[3, 2] < -9 and p[4, 2] > 9  # back, front
    assert p[5, 0] < -9 and p[6, 0] > 9  # right, left sides
    with pytest.raises(ValueError, match="no head surface above the eyes"):
        head_points(s.vertices[s.vertices[:, 1] < 0], *eyes)


def test_hair_sits_on_the_scalp_outside_the_skin(ict):
    hair = fit_hair(ict)
    v = hair.pose(ict.vertices)
    skin = _skin(ict)
    lm = ict.landmark_points()
    iod = float(np.linalg.norm(lm["eye_left"] - lm["eye_right"]))
    # every hair vertex is lifted along the skin's normal by at least the minimum lift
    _, dist, _ = trimesh.proximity.closest_point(skin, v)
    assert dist.min() > 0.5 * MIN_LIFT_IOD * iod and np.median(dist) < 0.5 * iod
    # it covers the crown and the back of the head, not the face
    top = ict.vertices[ict.skin][np.argmax(ict.vertices[ict.skin, 1])]
    assert np.linalg.norm(v - top, axis=1).min() < 0.3 * iod
    front = (v[:, 2] > lm["eye_right"][2] - 0.3 * iod) & (np.abs(v[:, 0]) < 0.75 * iod)  # over the forehead
    assert front.any() and v[front, 1].min() > lm["eye_right"][1] + 0.2 * iod  # the fringe stays above the eyes
    assert v[:, 1].max() > top[1]


def test_hair_follows_the_skin_through_stylisation_and_identities(shared_data, ict):
    from stimulus_engine.characters.ict import load_ict_rig
    from stimulus_engine.stylisation.shape import stylise

    hair = fit_hair(ict)
    cartoon = stylise(ict, 1.0)
    rise = cartoon[ict.skin, 1].max() - ict.vertices[ict.skin, 1].max()
    assert rise > 0.5  # the cranium grows ...
    hv0, hv1 = hair.pose(ict.vertices), hair.pose(cartoon)
    assert hv1[:, 1].max() - hv0[:, 1].max() == pytest.approx(rise, rel=0.25)  # ... and the hair with it
    # posing is exact for the binding: the offset from the bound skin point is kept
    np.testing.assert_allclose(hv1 - np.einsum("mk,mkd->md", hair.bary, cartoon[hair.corners]), hair.offset)
    other = load_ict_rig(shared_data / "meshes" / "ict-facekit", "identity001")
    _, dist, _ = trimesh.proximity.closest_point(_skin(other), hair.pose(other.vertices))
    assert dist.min() > 0  # fitted on one identity, still outside another's skin


@pytest.mark.parametrize("style", ["short01", "short03", "short04", "bob02", "long01", "afro01", "ponytail01"])
def test_every_style_is_worn_on_the_head_and_hangs_as_cut(ict, style):
    """Each style on an ICT head: the hair near the scalp sits outside the skin; the crown is
    covered; long styles hang below the chin and a ponytail behind the head, not stuck to the
    skin they are nearest; the hair grows with a stylised cranium."""
    from stimulus_engine.stylisation.shape import stylise

    hair = fit_hair(ict, style)
    v = hair.pose(ict.vertices)
    lm = ict.landmark_points()
    iod = float(np.linalg.norm(lm["eye_left"] - lm["eye_right"]))
    eye_y = (lm["eye_left"][1] + lm["eye_right"][1]) / 2
    skin = _skin(ict)
    near, dist, tri = trimesh.proximity.closest_point(skin, v)
    above = v[:, 1] > eye_y + 0.5 * iod
    height = np.einsum("nd,nd->n", v - near, skin.face_normals[tri])
    assert (height[above] > 0).all()  # outside the cranium
    top = ict.vertices[ict.skin][np.argmax(ict.vertices[ict.skin, 1])]
    assert np.linalg.norm(v - top, axis=1).min() < 0.4 * iod
    chin = ict.vertices[ict.skin][:, 1][ict.vertices[ict.skin][:, 2] > lm["eye_right"][2] - 0.5 * iod].min()
    if style == "long01":
        assert v[:, 1].min() < chin - 0.5 * iod and dist.max() > 0.5 * iod
    if style == "ponytail01":
        back = ict.vertices[ict.skin, 2].min()
        assert v[:, 2].min() < back - 0.5 * iod
    rise = stylise(ict, 1.0)[ict.skin, 1].max() - ict.vertices[ict.skin, 1].max()
    assert hair.pose(stylise(ict, 1.0))[:, 1].max() - v[:, 1].max() == pytest.approx(rise, rel=0.3)


def test_hair_arrays_round_trip(ict):
    hair = fit_hair(ict, colour=linear_rgb("#6b4a2f"))
    back = hair_from_arrays(hair_arrays(hair))
    assert isinstance(back, Hair) and back.colour == hair.colour
    for k in ("corners", "bary", "offset", "faces", "uv", "texture"):
        np.testing.assert_array_equal(getattr(back, k), getattr(hair, k))
    assert hair_from_arrays({}) is None and hair_arrays(None) == {}


def test_linear_rgb_is_the_srgb_curve():
    assert linear_rgb("#000000") == (0.0, 0.0, 0.0) and linear_rgb("#ffffff") == (1.0, 1.0, 1.0)
    assert linear_rgb("#808080")[0] == pytest.approx(0.21586, abs=1e-5)  # sRGB 128 -> 0.2159 linear


@pytest.mark.render
def test_alpha_tested_texels_are_not_drawn():
    """A quad whose texture is opaque red on the left half and alpha 0 on the right: the right
    half shows the background (pyrender alone would blend it, unsorted)."""
    from stimulus_engine.parts.hair import Hair
    from stimulus_engine.render import CameraSpec, render_mesh
    from stimulus_engine.characters.render_parts import hair_render_part

    tex = np.zeros((64, 64, 4), np.uint8)
    tex[:, :32] = (255, 255, 255, 255)
    tex[:, 32:] = (255, 255, 255, 0)
    v = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    hair = Hair(np.zeros((4, 3), np.int64), np.tile([1.0, 0, 0], (4, 1)), v, np.array([[0, 1, 2], [0, 2, 3]]),
                np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]]), tex, (0.8, 0.1, 0.1))
    part = hair_render_part(hair, np.zeros((1, 3)))
    cam = CameraSpec((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), 40.0, (0.0, 1.0, 0.0))
    img = render_mesh([part], width=200, height=200, camera=cam, lighting="flat", background=(0.0, 0.0, 1.0))
    left, right = img[100, 70].astype(int), img[100, 130].astype(int)
    assert left[0] > 200 and left[0] - left[2] > 100  # the hair colour
    assert tuple(right) == (0, 0, 255)  # the background, untouched


@pytest.mark.render
def test_a_grid_ict_character_has_hair_by_default(shared_data, tmp_path):
    """Rendered: dark hair above the forehead with the default, skin there with hair: none."""
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile

    ict = shared_data / "meshes" / "ict-facekit"
    p = tmp_path / "hair.yaml"
    p.write_text(f"""kind: grid
name: hair
characters:
  - {{name: with, ict: {ict}}}
  - {{name: without, ict: {ict}, hair: none}}
shapes: [0.0]
materials: [original]
expressions: [neutral]
lighting: [gi_soft]
shading: [pbr]
render: {{width: 256, height: 192}}
""")
    run_grid(load_study_file(p, GridFile), tmp_path, n_jobs=1)
    from PIL import Image

    imgs = {n: np.asarray(Image.open(next((tmp_path / "images").glob(f"{n}_*.png"))), float) for n in ("with", "without")}
    # the top of the head: the column through the face's middle, above the first face pixel rows
    col = imgs["without"][:, 118:138].mean(axis=1)
    head_top = int(np.argmax(np.abs(col - col[0]).sum(axis=1) > 30))
    band = slice(head_top + 3, head_top + 12)
    with_hair, bald = imgs["with"][band, 118:138].mean(), imgs["without"][band, 118:138].mean()
    assert with_hair < 0.6 * bald


def test_the_hair_field_of_a_character():
    from stimulus_engine.grid.schema import CharacterSpec

    ict = {"name": "a", "ict": str(ROOT)}
    assert CharacterSpec.model_validate(ict).hair_style == "short"
    assert CharacterSpec.model_validate({**ict, "hair": "none"}).hair_style is None
    assert CharacterSpec.model_validate({"name": "p", "procedural": {}}).hair_style is None
    assert CharacterSpec.model_validate({"name": "p", "procedural": {}, "hair": "short"}).hair_style == "short"
    mesh = {**ict, "mesh": {"file": str(ROOT / "README.md")}}
    assert CharacterSpec.model_validate(mesh).hair_style is None
    scan = {**mesh, "mesh": {**mesh["mesh"], "topology": "scan"}}
    assert CharacterSpec.model_validate(scan).hair_style is None  # a scan shows its own ...
    assert CharacterSpec.model_validate({**scan, "hair": "short04"}).hair_style == "short04"  # ... or a style over it
    with pytest.raises(ValueError, match="hair_colour"):
        CharacterSpec.model_validate({**ict, "hair_colour": "brown"})
    # the field takes every shipped style, and only those
    import typing

    field = typing.get_args(CharacterSpec.model_fields["hair"].annotation)
    assert set(field) == {"auto", "none", *HAIR_STYLES}
    assert CharacterSpec.model_validate({**ict, "hair": "long01"}).hair_style == "long01"


def test_a_rig_with_hair_survives_the_render_cache(ict, tmp_path):
    from stimulus_engine.grid.cache import load_rig, save_rig

    rig = replace(ict, hair=fit_hair(ict))
    save_rig(tmp_path / "r.npz", rig)
    back = load_rig(str(tmp_path / "r.npz"))
    np.testing.assert_array_equal(back.hair.pose(ict.vertices), rig.hair.pose(ict.vertices))


@pytest.mark.render
def test_a_see_through_blended_card_casts_no_shadow():
    """Lashes are blended cards; pyrender's shadow-map pass ignores alpha, so a card shadowed its
    whole rectangle. A nearly empty blended card in front of a lit plane leaves the plane as it was."""
    from stimulus_engine.render import CameraSpec, RenderPart, render_mesh
    from stimulus_engine.render._pyrender import _see_through
    from stimulus_engine.characters.render_parts import _new_material

    tex = np.zeros((32, 32, 4), np.uint8)
    tex[15:17, 15:17] = (20, 20, 20, 255)  # one small dark dot, the rest see-through
    card_mat = _new_material("pbr", (0.05, 0.04, 0.04, 1.0), tex, 0.6)
    assert _see_through(card_mat) and not _see_through(_new_material("pbr", (0.8, 0.6, 0.5, 1.0), None, 0.6))
    plane = trimesh.Trimesh([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], [[0, 1, 2], [0, 2, 3]], process=False)
    card = trimesh.Trimesh([[-3, -3, 1.5], [3, -3, 1.5], [3, 3, 1.5], [-3, 3, 1.5]], [[0, 1, 2], [0, 2, 3]], process=False)
    card.visual = trimesh.visual.TextureVisuals(uv=np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]]))
    cam = CameraSpec((0.0, 0.0, 12.0), (0.0, 0.0, 0.0), 50.0, (0.0, 1.0, 0.0))
    kw = dict(width=160, height=160, camera=cam, lighting="direct_hard", shadows=True)
    alone = render_mesh([RenderPart(plane, name="plane")], **kw).astype(float)
    both = render_mesh([RenderPart(plane, name="plane"), RenderPart(card, material=card_mat, name="card")], **kw).astype(float)
    away = np.ones((160, 160), bool)
    away[70:90, 70:90] = False  # around the dot itself
    assert np.abs(both - alone)[away].mean() < 1.0


def test_the_strands_edges_are_soft_and_their_cores_opaque():
    """The binary strand alpha is softened when drawn: a one-texel strand keeps an opaque core,
    its neighbours are half covered (the edge fades over a texel instead of stepping), and three
    texels away nothing is drawn."""
    from stimulus_engine.characters.render_parts import _soft_alpha

    tex = np.zeros((32, 32, 4), np.uint8)
    tex[:, 16] = 255
    a = _soft_alpha(tex)[..., 3].astype(int)
    assert (a[:, 16] >= 230).all() and (60 < a[:, 15]).all() and (a[:, 17] < 200).all()
    assert (a[:, 13] < 10).all() and (a[:, 19] < 10).all()
    assert np.array_equal(_soft_alpha(tex)[..., :3], tex[..., :3])


@pytest.mark.render
def test_blended_cards_are_drawn_back_to_front():
    """Two cards of one blended part, the front one (half transparent red) first in the mesh:
    drawn in that order it would hide the card behind (depth written, the blue card rejected,
    the green background through the red); sorted farthest first, the blue card shows through
    the red one and no background does."""
    import pyrender

    from stimulus_engine.render import CameraSpec, render_mesh
    from stimulus_engine.render.renderer import RenderPart

    tex = np.zeros((8, 16, 4), np.uint8)
    tex[:, :8] = (255, 0, 0, 128)  # left half of the texture: the front card
    tex[:, 8:] = (0, 0, 255, 255)  # right half: the back card
    quad = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    v = np.vstack([quad + [0, 0, 0.5], quad])
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    uv = np.array([[0.1, 0.1], [0.4, 0.1], [0.4, 0.9], [0.1, 0.9], [0.6, 0.1], [0.9, 0.1], [0.9, 0.9], [0.6, 0.9]])
    mesh = trimesh.Trimesh(v, f, process=False)
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv)
    mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=(1.0, 1.0, 1.0, 1.0), metallicFactor=0.0,
                                             baseColorTexture=pyrender.Texture(source=tex, source_channels="RGBA"),
                                             alphaMode="BLEND", doubleSided=True)
    cam = CameraSpec((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), 40.0, (0.0, 1.0, 0.0))
    img = render_mesh([RenderPart(mesh, material=mat, name="cards")], width=100, height=100, camera=cam,
                      lighting="flat", background=(0.0, 1.0, 0.0), shadows=False)
    r, g, b = img[50, 50].astype(int)
    assert g < 60 and r > 60 and b > 60, (r, g, b)
