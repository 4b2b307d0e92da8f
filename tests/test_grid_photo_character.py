"""A character from a photograph in a grid (issue 49): rendered at every level, its photograph
framed alike at the top, the London set's columns in the manifest, one-line errors."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from stimulus_engine.data import DATA_DIR

FACES = DATA_DIR / "faces2d"


def _grid(tmp_path, shared_data) -> object:
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid.schema import GridFile

    sophia = (shared_data / "meshes" / "gdquest-sophia" / "sophia.glb").as_posix()
    landmarks = (DATA_DIR.parent.parent / "protocols" / "grids" / "designs" / "sophia_landmarks.yaml").as_posix()
    text = f"""kind: grid
name: photo_grid
characters:
  - {{name: f002, photo: '{(FACES / "002_03.jpg").as_posix()}'}}
shapes: [0.0, 1.0]
design: {{name: sophia, file: '{sophia}', landmarks: '{landmarks}', identity: 1.0, identity_model: data:ict-facekit-more}}
materials: [original]
expressions: [neutral, happiness]
photographs:
  - character: f002
    files: {{neutral: '{(FACES / "002_03.jpg").as_posix()}', happiness: '{(FACES / "002_08.jpg").as_posix()}'}}
lighting: [gi_soft]
shading: [pbr]
render: {{width: 512, height: 384, shadows: false}}
"""
    path = tmp_path / "grid.yaml"
    path.write_text(text)
    return load_study_file(path, GridFile)


def test_photo_character_grid(tmp_path, shared_data):
    from stimulus_engine.grid import run_grid
    from stimulus_engine.morphpca.keypoints import detect_faceframe
    from stimulus_engine.stylisation.photo_match import render_vs_photo

    grid = _grid(tmp_path, shared_data)
    c = grid.characters[0]
    assert c.ict is not None and c.identity_model is not None and c.hair_style is None and not c.draws_bust
    manifest, _ = run_grid(grid, tmp_path / "out", n_jobs=1)
    assert len(manifest) == 2 * 2 + 2 and (manifest["status"] == "rendered").all()
    assert set(manifest["gender"]) == {"female"} and set(manifest["age"]) == {24.0} and set(manifest["ethnicity"]) == {"white"}
    img = {(r.shape_label, r.expression): np.asarray(Image.open(tmp_path / "out" / r.file).convert("RGB"))
           for r in manifest.itertuples()}
    photo = np.asarray(Image.open(FACES / "002_03.jpg").convert("RGB"))
    m = render_vs_photo(img["realistic", "neutral"], photo)
    assert m.ssim > 0.75 and m.descriptor_distance < 0.4, (m.ssim, m.descriptor_distance)  # benchmarks/photo_characters.py
    # the photograph level: the photograph where the renders put the face (eyes on the render's)
    eyes_render = detect_faceframe(img["realistic", "neutral"])[:2]
    eyes_photo = detect_faceframe(img["photograph", "neutral"])[:2]
    assert np.abs(eyes_render - eyes_photo).max() < 0.02 * 512
    # the cartoon end is a different face (the design's), the happy image a different mouth
    from stimulus_engine.morphpca.keypoints import detect_landmarks
    from stimulus_engine.stylisation.photo_match import face_hull_mask

    points = detect_landmarks(img["realistic", "neutral"])
    face = face_hull_mask((384, 512), points)  # ~15 % of the frame
    assert np.abs(img["cartoon", "neutral"].astype(float) - img["realistic", "neutral"].astype(float))[face].mean() > 20

    mouth = points[48:68]
    (x0, y0), (x1, y1) = mouth.min(axis=0).astype(int) - 8, mouth.max(axis=0).astype(int) + 8
    lo = slice(y0, y1), slice(x0, x1)
    assert np.abs(img["realistic", "happiness"][lo].astype(float) - img["realistic", "neutral"][lo].astype(float)).mean() > 4


def test_photo_eyes_where_the_gaze_is_the_photographs(tmp_path, shared_data):
    from dataclasses import replace

    from stimulus_engine.characters.photo_character import photo_eyed
    from stimulus_engine.grid.characters import load_character
    from stimulus_engine.grid.prepare import photo_eyes

    grid = _grid(tmp_path, shared_data)
    ch = load_character(grid.characters[0], tmp_path / ".cache", "grid.yaml", grid.render)
    assert ch.rig.surround is not None
    assert photo_eyes(ch, 0.0, "neutral") and photo_eyes(ch, 0.0, "happiness")
    assert not photo_eyes(ch, 0.0, "surprise")  # the lids open past the photograph's: the rig's eyeballs
    assert not photo_eyes(ch, 0.5, "neutral")   # the eyes grow: the rig's eyeballs
    assert not photo_eyes(replace(ch, rig=replace(ch.rig, surround=None)), 0.0, "neutral")
    drawn = photo_eyed(ch.rig)
    hidden = drawn.part_names.index("hidden")
    assert (drawn.face_part[ch.rig.face_part == ch.rig.part_names.index("eye")] == hidden).all()
    # the iris of the rig's eyeballs is tinted to the photograph's
    from stimulus_engine.parts.eyes import photographic_eye_texture

    assert np.abs(ch.rig.part_textures["eye"].astype(float) - photographic_eye_texture().astype(float)).max() > 20


def test_photo_character_refuses_mesh_and_template_alone(tmp_path):
    from appeal.errors import StudyFileError
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid.schema import GridFile

    base = "kind: grid\nname: g\nshapes: [0.0]\nmaterials: [original]\nexpressions: [neutral]\nlighting: [gi_soft]\nshading: [pbr]\n"
    photo = (FACES / "002_03.jpg").as_posix()
    for chars, message in [
        (f"  - {{name: a, photo: '{photo}', mesh: {{file: '{photo}'}}}}", "takes no 'mesh'"),
        (f"  - {{name: a, ict: data:ict-facekit, template: '{photo}'}}", "template: only with 'photo'"),
        ("  - {name: a, ict: data:ict-facekit, neutral: identity}", "neutral: only with 'photo'"),
        (f"  - {{name: a, photo: '{photo}', neutral: smiling}}", "neutral"),
    ]:
        path = tmp_path / "g.yaml"
        path.write_text(base + "characters:\n" + chars + "\n")
        with pytest.raises(StudyFileError, match=message):
            load_study_file(path, GridFile)


def test_manifest_columns_only_for_photo_characters():
    from stimulus_engine.grid.prepare import _with_people

    class G:  # the two fields _with_people reads
        characters = [type("C", (), {"name": "x", "photo": None})()]

    m = pd.DataFrame({"character": ["x"]})
    assert list(_with_people(m, G()).columns) == ["character"]


def test_render_vs_photo_refines_the_landmark_alignment_by_a_sub_pixel_shift():
    """A 'render' that is the photograph moved by a fraction of a pixel (and a little darker): the
    landmark alignment leaves it out of register, the intensity refinement finds the shift, and the
    SSIM reaches what the images share; a shift beyond MAX_REFINE_PX is not taken."""
    import cv2

    from stimulus_engine.morphpca.keypoints import detect_landmarks
    from stimulus_engine.stylisation.photo_match import MAX_REFINE_PX, render_vs_photo

    photo = np.asarray(Image.open(FACES / "002_03.jpg").convert("RGB"))
    h, w = photo.shape[:2]
    moved = cv2.warpAffine(photo, np.float32([[1, 0, 0.7], [0, 1, -0.5]]), (w, h), flags=cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_REPLICATE)
    render = np.clip(moved.astype(float) * 0.9, 0, 255).astype(np.uint8)
    points = detect_landmarks(photo)  # the same points on both: the landmark alignment misses the shift
    m = render_vs_photo(render, photo, render_points=points, photo_points=points)
    print(m.ssim, m.ssim_landmarks, m.shift_px)
    assert m.shift_px == pytest.approx(np.hypot(0.7, 0.5), abs=0.1)
    assert m.ssim > m.ssim_landmarks + 0.02 and m.ssim > 0.98
    far = cv2.warpAffine(photo, np.float32([[1, 0, 0.0], [0, 1, 6.0]]), (w, h), borderMode=cv2.BORDER_REPLICATE)
    kept = render_vs_photo(far, photo, render_points=points, photo_points=points)
    assert kept.shift_px == 0.0 and kept.ssim == kept.ssim_landmarks  # beyond MAX_REFINE_PX: left as aligned
    assert MAX_REFINE_PX < 6.0
