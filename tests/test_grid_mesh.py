"""Mesh characters in grids: a real mesh (MediaPipe canonical face, its own UV layout) made a
character by corresponding the procedural head onto it (issue-4 ElastiFace), with expressions
carried over by deformation transfer and its texture re-laid for material swaps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from appeal_cli import main
from appeal.errors import StudyFileError
from appeal.studyfile import load_study_file
from stimulus_engine.grid import run_grid
from stimulus_engine.grid.schema import GridFile

# MediaPipe canonical-face vertex ids of the rig landmarks (face_geometry/data mesh map; the
# model looks along +z with the subject's right at -x, like the rigs)
MP_LANDMARKS = ("{nose_tip: 4, chin: 152, eye_right_outer: 33, eye_right_inner: 133, eye_left_outer: 263, "
                "eye_left_inner: 362, mouth_right: 61, mouth_left: 291, mouth_top: 0, mouth_bottom: 17, "
                "face_right: 234, face_left: 454, nasion: 168, subnasale: 2, nose_right: 98, nose_left: 327}")


# procedural head seed 2: at resolution 32 seed 1 puts both inner eye corners on one nose-ridge
# vertex (and mouth_top/bottom on one lip vertex), so its eye-corner ratios do not measure the
# eyes; mesh_character leaves such pairs out (tests/test_grid_mesh_character.py)
def _text(data: Path, landmarks: str = MP_LANDMARKS, region: str = "front", maps: str = "") -> str:
    mp = data / "meshes" / "mediapipe-canonical"
    return f"""kind: grid
name: meshgrid
characters:
  - name: head
    procedural: {{seed: 2, texture_size: 128, resolution: 32}}
  - name: mp
    procedural: {{seed: 2, texture_size: 128, resolution: 32}}
    mesh:
      file: {mp / 'canonical_face_model.obj'}
      texture: {mp / 'canonical_face_model_uv_visualization.png'}
      region: {region}
      texture_size: 128{maps}
      landmarks: {landmarks}
shapes: [0.0]
materials: [original, {{name: mp_skin, style: original, from_character: mp}}]
expressions: [neutral, surprise]
lighting: [flat]
render: {{width: 96, height: 72}}
"""


@pytest.fixture(scope="module")
def mesh_grid(tmp_path_factory, shared_data):
    """The MediaPipe pair rendered once: (grid file, grid, out folder, manifest)."""
    tmp_path = tmp_path_factory.mktemp("meshgrid")
    # normal and specular maps in the MediaPipe UV layout (a tilt towards +u; a mid-grey map
    # whose left half of the layout is white): re-laid like the texture, worn by both heads
    from PIL import Image

    nm, sm = tmp_path / "mp_normal.png", tmp_path / "mp_spec.png"
    Image.fromarray(np.tile(np.array([190, 128, 230], np.uint8), (256, 256, 1))).save(nm)
    spec = np.full((256, 256), 128, np.uint8)
    spec[:, :128] = 255
    Image.fromarray(spec).save(sm)
    p = tmp_path / "g.yaml"
    p.write_text(_text(shared_data, maps=f"\n      normal_map: {nm}\n      specular_map: {sm}"))
    grid = load_study_file(p, GridFile)
    out = tmp_path / "o"
    manifest, _ = run_grid(grid, out, n_jobs=1, source=str(p))
    return p, grid, out, manifest


def test_mesh_character_expressions_maps_and_material_swap(mesh_grid):
    p, grid, out, manifest = mesh_grid
    assert (manifest["status"] == "rendered").all() and len(manifest) == 8
    h = manifest.set_index(["character", "material"])["albedo_hash"].groupby(level=[0, 1]).first()
    # the MediaPipe texture, re-laid into the rig's layout, is worn by the other head as well
    assert h[("head", "mp_skin")] == h[("mp", "original")] != h[("head", "original")]
    mh = manifest.set_index(["character", "material"])["maps_hash"].groupby(level=[0, 1]).first()
    assert mh[("head", "mp_skin")] == mh[("mp", "original")] != "none" and mh[("head", "original")] == "none"
    d = np.load(next((out / ".cache" / "mesh").glob("*.npz")))
    normal, specular = d["map_normal"], d["map_specular"]
    assert normal.shape == (128, 128, 3) and specular.shape == (128, 128)
    moved = (normal == (190, 128, 230)).all(axis=-1)
    assert moved.mean() > 0.05 and (normal == (128, 128, 255)).all(axis=-1).mean() > 0.3  # flat elsewhere
    assert {255, 128} <= set(np.unique(specular[moved]).tolist())
    lm = pd.read_csv(out / "landmarks.csv").set_index(["character", "expression", "landmark"])[["x", "y", "z"]]
    # the surprise (jaw drop, brows up) is carried onto the corresponded shape
    move = lambda n: lm.loc[("mp", "surprise", n), "y"] - lm.loc[("mp", "neutral", n), "y"]  # noqa: E731
    assert move("chin") < -0.5 and move("brow_left") > 0.2 and move("brow_right") > 0.2
    # the correspondence is cached: a re-run has everything up to date
    again, _ = run_grid(grid, out, n_jobs=1, source=str(p))
    assert (again["status"] == "up to date").all()
    assert len(list((out / ".cache" / "mesh").glob("*.npz"))) == 1


def test_mesh_character_takes_the_mesh_proportions(mesh_grid):
    _, _, out, _ = mesh_grid
    lm = pd.read_csv(out / "landmarks.csv").set_index(["character", "expression", "landmark"])[["x", "y", "z"]]

    def ratios(ch: str) -> tuple[float, float]:
        g = lambda n: lm.loc[(ch, "neutral", n)].to_numpy()  # noqa: E731
        eyes = np.linalg.norm(g("eye_left_outer") - g("eye_right_outer"))
        corners_z = np.mean([g(n)[2] for n in ("eye_left_outer", "eye_right_outer", "eye_left_inner",
                                                "eye_right_inner")])
        return np.linalg.norm(g("mouth_left") - g("mouth_right")) / eyes, (g("nose_tip")[2] - corners_z) / eyes

    # MediaPipe's own ratios from its vertices 61/291, 33/263, 133/362, 4: mouth 0.5525, nose 0.4635
    (mouth_mp, nose_mp), (mouth_head, nose_head) = ratios("mp"), ratios("head")
    assert abs(mouth_mp - 0.5525) < 0.01 and abs(mouth_head - 0.5525) > 0.05
    assert abs(nose_mp - 0.4635) < abs(nose_head - 0.4635) - 0.05  # the nose moves towards MediaPipe's
    assert abs(nose_mp - 0.4635) < 0.03  # and nearly reaches it (0.4431; the head's own is 0.5466)


def test_mesh_character_errors_are_one_line_and_early(tmp_path, shared_data, capsys):
    p = tmp_path / "g.yaml"
    p.write_text(_text(shared_data, landmarks=MP_LANDMARKS.replace("nose_tip: 4", "nose: 4")))
    code = main(["stimuli", "grid", str(p), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2
    assert "characters.mp.mesh: landmarks: unknown or unusable rig landmark 'nose'" in err and "nose_tip" in err
    assert not (tmp_path / "o" / "images").exists()
    p.write_text(_text(shared_data, region="narrow_face"))
    with pytest.raises(StudyFileError) as exc:
        load_study_file(p, GridFile)
    assert any("only the region 'front'" in line for line in exc.value.lines)
    p.write_text(_text(shared_data, landmarks="{nose_tip: 4, chin: 152}"))
    with pytest.raises(StudyFileError) as exc:
        load_study_file(p, GridFile)
    assert any("landmarks" in line and "at least 6" in line for line in exc.value.lines), exc.value.lines
