"""The bust under a character's head: the shipped asset, its join to the neck, posing, and the
head-and-shoulders frame with no torn edge."""

from __future__ import annotations

import importlib.util
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from stimulus_engine.parts.body import (
    GARMENT_LIFT_IOD, NECK_CUT_IOD, body_arrays, body_from_arrays, bust_asset, fit_body, neck_cut,
)

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def ict(shared_data):
    from stimulus_engine.characters.ict import load_ict_rig

    return load_ict_rig(shared_data / "meshes" / "ict-facekit", "identity000")


def _dressed(rig):
    """The rig with its neck cut and the bust fitted (as the grid does), the bust, the ring's iod."""
    from stimulus_engine.grid.characters import _hide_faces

    lm = rig.landmark_points()
    skin = rig.face_part == rig.part_names.index("skin")
    rig = _hide_faces(rig, neck_cut(rig.vertices, rig.faces, skin, lm["eye_right"], lm["eye_left"]))
    skin = rig.face_part == rig.part_names.index("skin")
    body = fit_body(rig.vertices, rig.faces[skin], rig.uv, rig.face_uv[skin], lm["eye_right"], lm["eye_left"])
    return replace(rig, body=body), float(np.linalg.norm(lm["eye_left"] - lm["eye_right"]))


def _ring(rig):
    from stimulus_engine.geometry.mesh_ops import boundary_vertex_mask

    skin = rig.faces[rig.face_part == rig.part_names.index("skin")]
    border = np.flatnonzero(boundary_vertex_mask(skin, len(rig.vertices)))
    lm = rig.landmark_points()
    iod = float(np.linalg.norm(lm["eye_left"] - lm["eye_right"]))
    return border[rig.vertices[border, 1] < (lm["eye_left"][1] + lm["eye_right"][1]) / 2 - 1.6 * iod]


def _asset_script():
    """``scripts/make_body_asset.py`` as a module."""
    spec = importlib.util.spec_from_file_location("make_body_asset", ROOT / "scripts" / "make_body_asset.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_shipped_asset_is_consistent():
    a = bust_asset()
    assert a.faces.max() == len(a.vertices) - 1 and a.cloth.shape == (len(a.vertices),)
    assert a.cloth_face.shape == (len(a.faces),) and 0.5 < a.cloth_face.mean() < 0.99
    # the neckline runs along edges: a garment face's corners are all garment vertices
    assert a.cloth[a.faces[a.cloth_face]].all()
    assert a.texture.ndim == 2 and 150 < a.texture.mean() < 240


def test_the_asset_script_rebuilds_the_shipped_files(shared_data, tmp_path):
    mod = _asset_script()
    mod.main(shared_data / "meshes" / "makehuman-cc0", tmp_path)
    new, old = np.load(tmp_path / "bust.npz"), np.load(ROOT / "stimulus_engine" / "data" / "body" / "bust.npz")
    for k in old.files:
        np.testing.assert_allclose(new[k], old[k], atol=1e-5, err_msg=k)


def test_split_at_zero_cuts_faces_along_the_line():
    mod = _asset_script()
    v = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    verts, faces, below = mod.split_at_zero(v, np.array([[0, 1, 2]]), v[:, 1] - 1.0)
    assert len(faces) == 3 and below.sum() == 2
    centre_y = verts[faces].mean(axis=1)[:, 1]
    assert ((centre_y < 1.0) == below).all()
    # the cut vertices lie on the line
    assert np.allclose(verts[3:, 1], 1.0)


def test_the_bust_meets_the_neck_without_a_gap(ict):
    """Every vertex of the character's lower border lies on the bust's surface (garment or neck),
    in the rest pose, in an expression and on the most stylised shape."""
    from stimulus_engine.characters.expressions import apply_expression
    from stimulus_engine.geometry.closest import SurfaceIndex
    from stimulus_engine.stylisation.shape import stylise

    rig, iod = _dressed(ict)
    ring = _ring(rig)
    assert len(ring) > 20
    cartoon = stylise(rig, 1.0)
    for v in (rig.vertices, apply_expression(rig, "surprise", 1.0), apply_expression(rig, "anger", 1.0, target=cartoon)):
        gap = SurfaceIndex(rig.body.pose(v), rig.body.faces).distance(np.asarray(v)[ring])
        # the garment stands GARMENT_LIFT_IOD off the skin; nothing further (< 0.6 cm)
        assert gap.max() < GARMENT_LIFT_IOD * iod + 0.05 * iod, gap.max() / iod


def test_the_character_neck_ends_at_the_cut(ict):
    rig, iod = _dressed(ict)
    lm = rig.landmark_points()
    level = (lm["eye_left"][1] + lm["eye_right"][1]) / 2 - NECK_CUT_IOD * iod
    skin = rig.faces[rig.face_part == rig.part_names.index("skin")]
    assert rig.vertices[skin, 1].max(axis=1).min() >= level - 1e-9  # no skin face wholly below it
    assert "hidden" in rig.part_names


def test_the_bust_follows_the_head(ict):
    rig, _ = _dressed(ict)
    shift = np.array([1.0, -2.0, 3.0])
    np.testing.assert_allclose(rig.body.pose(rig.vertices + shift), rig.body.pose(rig.vertices) + shift, atol=1e-4)


def test_body_arrays_round_trip(ict):
    rig, _ = _dressed(ict)
    back = body_from_arrays(body_arrays(rig.body))
    np.testing.assert_array_equal(back.pose(rig.vertices), rig.body.pose(rig.vertices))
    assert back.colour == rig.body.colour and body_from_arrays({}) is None


def test_the_neck_colour_comes_from_the_skin_above_the_ring(ict):
    rig, _ = _dressed(ict)
    albedo = np.zeros((64, 64, 3), np.uint8)
    albedo[...] = (200, 150, 120)
    tex = rig.body.neck_texture(albedo)
    assert tex.shape[0] == 2 and np.abs(tex.astype(int) - (200, 150, 120)).max() <= 1


@pytest.mark.render
def test_head_and_shoulders_have_no_torn_edge_below_the_chin(shared_data, tmp_path):
    """Rendered head-and-shoulders: no background showing through the figure (no background
    region cut off from the frame's border: a gap between neck and garment, a hole, a crack),
    and the figure reaches the frame's bottom; without the bust the cut neck floats over the
    background."""
    from PIL import Image
    from scipy import ndimage

    from appeal.studyfile import load_study_file
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile

    ict = shared_data / "meshes" / "ict-facekit"
    p = tmp_path / "body.yaml"
    p.write_text(f"""kind: grid
name: body
characters:
  - {{name: dressed, ict: {ict}}}
  - {{name: bare, ict: {ict}, body: none}}
shapes: [0.0, 1.0]
materials: [original]
expressions: [neutral]
lighting: [gi_soft]
shading: [pbr]
render: {{width: 256, height: 192, background: [0.0, 0.0, 1.0]}}
""")
    run_grid(load_study_file(p, GridFile), tmp_path, n_jobs=1)
    holes, fg_bottom = {}, {}
    for f in sorted((tmp_path / "images").glob("*.png")):
        img = np.asarray(Image.open(f).convert("RGB"), float)
        fg = np.abs(img - (0, 0, 255)).sum(axis=2) > 40
        fg_bottom[f.name.split("_")[0], f.name.split("_")[1]] = bool(fg[-1].mean() > 0.4)
        labels, n = ndimage.label(~fg)
        border = set(np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])))
        gaps = sum(int((labels == k).sum()) for k in range(1, n + 1) if k not in border)
        holes[f.name.split("_")[0], f.name.split("_")[1]] = gaps
    assert holes[("dressed", "realistic")] == 0 and holes[("dressed", "cartoon")] == 0, holes
    # bare: the neck ends in the picture, the background below it -- no hole in a row, but no figure
    # either: the bust's rows reach the frame's bottom only when dressed
    assert all(fg_bottom[k] for k in fg_bottom if k[0] == "dressed") and not any(fg_bottom[k] for k in fg_bottom if k[0] == "bare")
