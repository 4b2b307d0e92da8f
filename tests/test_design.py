"""Designed stylisation (issue 48): an artist's head (GDQuest's Sophia, real third-party data) brought into
the ICT rig's topology, each person's own cartoon of it, the morphs between, a user's own stylised head, the
grid option and its one-line errors.

The feature measures are the rig landmarks' (as the continuum report's): an eye's area is its corners'
distance times its lid apexes' distance, a share of the face's area (the face sides' distance times the
forehead-to-chin distance); the nose's width is its alae's distance, a share of the face's width.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml

from appeal.errors import AppealInputError
from cli_errors import one_line_error

ROOT = Path(__file__).resolve().parent.parent
LANDMARKS = ROOT / "protocols" / "grids" / "designs" / "sophia_landmarks.yaml"


@functools.lru_cache(maxsize=1)
def _sophia(shared: str):
    from stimulus_engine.characters.design import correspond_design, design_head
    from stimulus_engine.characters.ict import load_ict_rig
    from stimulus_engine.geometry.mesh_io import load_parts

    landmarks = {k: tuple(v) for k, v in yaml.safe_load(LANDMARKS.read_text()).items()}
    parts = load_parts(Path(shared) / "meshes/gdquest-sophia/sophia.glb")
    head = design_head(parts, np.array(list(landmarks.values())))
    mean = load_ict_rig(Path(shared) / "meshes/ict-facekit", "generic_neutral_mesh")
    return mean, head, landmarks, correspond_design(mean, head, landmarks, name="sophia")


@pytest.fixture(scope="module")
def sophia(shared_data):
    return _sophia(str(shared_data))


def _landmark_measures(lm: dict) -> dict[str, float]:
    """:func:`measures` of landmark points already averaged (the grid's ``landmarks.csv``)."""
    d = lambda a, b: float(np.linalg.norm(lm[a] - lm[b]))  # noqa: E731
    face_w, face_l = d("face_left", "face_right"), d("forehead_top", "chin")
    eye_w = (d("eye_right_outer", "eye_right_inner") + d("eye_left_outer", "eye_left_inner")) / 2
    eye_h = (d("eye_right_top", "eye_right_bottom") + d("eye_left_top", "eye_left_bottom")) / 2
    return {"eye_area": eye_w * eye_h / (face_w * face_l), "eye_ratio": eye_h / eye_w,
            "nose": d("nose_left", "nose_right") / face_w, "mouth": d("mouth_left", "mouth_right") / face_w}


def measures(rig, v) -> dict[str, float]:
    return _landmark_measures(rig.landmark_points(v))


def _similar(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether ``b`` is ``a`` moved whole (rotated, scaled uniformly, shifted): an eyeball stays a ball."""
    from stimulus_engine.correspondence import umeyama

    err = np.linalg.norm(umeyama(a, b).apply(a) - b, axis=1).max()
    return bool(err < 1e-3 * np.ptp(b, axis=0).max())


def test_the_design_is_a_cartoon_in_the_rigs_topology(sophia):
    """Sophia in the rig's topology keeps her proportions: eyes 2.5x the area of the mean adult's and round,
    a button nose; the eyeballs stay spheres; the chin and neck stay where the rig has them."""
    mean, _, _, design = sophia
    real, toon = measures(mean, mean.vertices), measures(mean, design.vertices)
    assert toon["eye_area"] >= 2.5 * real["eye_area"], (toon, real)
    assert toon["eye_ratio"] >= 0.5 and real["eye_ratio"] < 0.35
    assert toon["nose"] <= 0.6 * real["nose"] and toon["mouth"] <= 0.6 * real["mouth"]
    assert design.metrics["hausdorff_rel"] < 0.05  # the surface lies on the design's head
    for ball in mean.rigid_sets:
        assert _similar(mean.vertices[np.asarray(ball)], design.vertices[np.asarray(ball)])  # moved whole
    lm0, lm1 = mean.landmark_points(), mean.landmark_points(design.vertices)
    assert np.allclose(lm0["chin"][1] - (lm0["eye_left"][1] + lm0["eye_right"][1]) / 2,
                       lm1["chin"][1] - (lm1["eye_left"][1] + lm1["eye_right"][1]) / 2)
    low = mean.vertices[:, 1] < lm0["chin"][1] - 0.5 * np.linalg.norm(lm0["forehead_top"] - lm0["chin"])
    assert np.allclose(design.vertices[low], mean.vertices[low])  # the neck where the body joins


@pytest.mark.parametrize("identity", ["identity000", "identity001"])
def test_morphs_run_from_the_character_to_its_cartoon(sophia, shared_data, identity):
    from stimulus_engine.characters.ict import load_ict_rig
    from stimulus_engine.stylisation.designed_shape import designed_shape, own_cartoon

    mean, _, _, design = sophia
    ch = load_ict_rig(shared_data / "meshes/ict-facekit", identity, shapes=[])
    cartoon = own_cartoon(ch, mean.vertices, ch.vertices, design.vertices, 1.0)
    assert np.array_equal(designed_shape(ch, ch.vertices, cartoon, 0.0), ch.vertices)  # the realistic level unchanged
    assert np.allclose(designed_shape(ch, ch.vertices, cartoon, 1.0), cartoon)
    areas = [measures(ch, designed_shape(ch, ch.vertices, cartoon, s))["eye_area"] for s in (0, 0.25, 0.5, 0.75, 1.0)]
    assert all(b > a for a, b in zip(areas, areas[1:]))  # the eyes grow at every step
    half = designed_shape(ch, ch.vertices, cartoon, 0.5, eyes_ahead=1.0)
    width = lambda v: np.linalg.norm(np.subtract(*(ch.landmark_points(v)[k] for k in ("eye_left_outer", "eye_left_inner"))))  # noqa: E731
    assert width(half) == pytest.approx(width(cartoon), rel=0.02)  # the eyes lead: full size at half way
    for ball in ch.rigid_sets:
        assert _similar(ch.vertices[np.asarray(ball)], half[np.asarray(ball)])


def test_each_persons_cartoon_differs_as_the_people_do(sophia, shared_data):
    """Two people's cartoons in one design differ the way their faces do: the difference of their landmarks
    (in units of the face width) points the same way, correlation >= 0.5."""
    from stimulus_engine.characters.ict import ict_identity_basis, load_ict_rig
    from stimulus_engine.characters.mesh_character import front_region
    from stimulus_engine.stylisation.designed_shape import model_identity, own_cartoon

    mean, _, _, design = sophia
    basis = ict_identity_basis(shared_data / "meshes/ict-facekit", shared_data / "meshes/ict-facekit-more")
    region = front_region(mean)
    points = {}
    for ident in ("identity001", "identity002"):
        ch = load_ict_rig(shared_data / "meshes/ict-facekit", ident, shapes=[])
        face, w = model_identity(basis, mean.vertices, ch.vertices, region)
        assert 0.5 < np.linalg.norm(w) < 30
        for kind, v in (("real", face), ("toon", own_cartoon(ch, mean.vertices, face, design.vertices, 1.0))):
            lm = ch.landmark_points(v)
            width = np.linalg.norm(lm["face_left"] - lm["face_right"])
            points[ident, kind] = np.stack([lm[k] for k in sorted(lm)]) / width
    real = (points["identity001", "real"] - points["identity002", "real"]).ravel()
    toon = (points["identity001", "toon"] - points["identity002", "toon"]).ravel()
    assert np.corrcoef(real, toon)[0, 1] >= 0.5
    assert np.linalg.norm(toon) > 0.3 * np.linalg.norm(real)  # visibly different people, not the design twice


def _stylised_ict_head(shared_data: Path, out: Path) -> tuple[Path, dict]:
    """A user's own stylised head made from the ICT rig: its skin in the analytic operator's cartoon shape,
    welded into one surface, as an OBJ, with its landmarks."""
    from stimulus_engine.characters.ict import load_ict_rig
    from stimulus_engine.stylisation.shape import StyliseParams, stylise

    rig = load_ict_rig(shared_data / "meshes/ict-facekit", "identity002", shapes=[])
    v = stylise(rig, 1.0, StyliseParams(eye_scale=0.6, nose_scale=-0.5, mouth_scale=-0.4))
    skin = rig.face_part == rig.part_names.index("skin")
    head = trimesh.Trimesh(v, rig.faces[skin], process=False)
    head.remove_unreferenced_vertices()
    path = out / "toon_head.obj"
    head.export(path)
    lm = rig.landmark_points(v)
    names = ["eye_right_outer", "eye_right_inner", "eye_right_top", "eye_right_bottom", "eye_left_outer",
             "eye_left_inner", "eye_left_top", "eye_left_bottom", "nose_tip", "nose_right", "nose_left",
             "subnasale", "nasion", "mouth_right", "mouth_left", "mouth_top", "mouth_bottom", "chin", "face_right",
             "face_left", "forehead_top"]
    return path, {k: tuple(float(x) for x in lm[k]) for k in names}


def test_a_users_own_stylised_head_is_a_design(shared_data, tmp_path):
    """A stylised head in another mesh (one made from the ICT rig counts): corresponded, it keeps its eyes'
    and nose's proportions."""
    from stimulus_engine.characters.design import correspond_design, design_head
    from stimulus_engine.characters.ict import load_ict_rig
    from stimulus_engine.geometry.mesh_io import load_parts

    path, lm = _stylised_ict_head(shared_data, tmp_path)
    mean = load_ict_rig(shared_data / "meshes/ict-facekit", "generic_neutral_mesh")
    head = design_head(load_parts(path), np.array(list(lm.values())))
    design = correspond_design(mean, head, lm, name="toon")
    got, mesh = measures(mean, design.vertices), _mesh_measures(lm)
    assert got["nose"] == pytest.approx(mesh["nose"], rel=0.15) and got["mouth"] == pytest.approx(mesh["mouth"], rel=0.15)
    assert got["eye_area"] > 1.3 * measures(mean, mean.vertices)["eye_area"]


def _mesh_measures(lm: dict) -> dict[str, float]:
    d = lambda a, b: float(np.linalg.norm(np.subtract(lm[a], lm[b])))  # noqa: E731
    w = d("face_left", "face_right")
    return {"nose": d("nose_left", "nose_right") / w, "mouth": d("mouth_left", "mouth_right") / w}


def test_bad_designs_give_one_line_errors(sophia, shared_data):
    from stimulus_engine.characters.design import correspond_design, design_head
    from stimulus_engine.geometry.mesh_io import load_parts

    mean, head, landmarks, _ = sophia
    parts = load_parts(shared_data / "meshes/gdquest-sophia/sophia.glb")
    with pytest.raises(AppealInputError, match="no piece of the mesh lies under every landmark") as e:
        design_head(parts, np.array([*landmarks.values(), (5.0, 5.0, 5.0)]), "g.yaml: design.sophia")
    assert len(e.value.lines) == 1 and e.value.lines[0].startswith("g.yaml: design.sophia: landmarks:")
    partial = {k: v for k, v in landmarks.items() if k != "mouth_left"}
    with pytest.raises(AppealInputError, match="'mouth_left' is needed"):
        correspond_design(mean, head, partial, where="g.yaml: design.sophia")


GRID = """kind: grid
name: designed
characters:
  - {name: a, ict: ICT, identity: identity001, hair: none}
shapes: [0.0, 1.0]
materials: [original]
expressions: [neutral, happiness, surprise]
lighting: [gi_soft]
shading: [pbr]
expression_transfer: aligned
render: {width: 256, height: 192, shadows: false}
design: {name: sophia, file: SOPHIA, landmarks: LANDMARKS, identity: 1.0, identity_model: MORE}
"""


def _grid_text(shared_data: Path, changes: dict[str, str] | None = None) -> str:
    text = GRID
    for old, new in (changes or {}).items():
        text = text.replace(old, new)
    return (text.replace("ICT", str(shared_data / "meshes/ict-facekit"))
            .replace("SOPHIA", str(shared_data / "meshes/gdquest-sophia/sophia.glb"))
            .replace("LANDMARKS", str(LANDMARKS)).replace("MORE", str(shared_data / "meshes/ict-facekit-more")))


def test_a_grid_with_a_design(shared_data, tmp_path, capsys):
    """The design as the shape axis of a grid: the realistic level as without it, the cartoon's eyes 2.5x,
    and happiness and surprise moving the mouth corners and brows at least as far (in face widths) on the
    cartoon as on the realistic level."""
    from appeal_cli import main

    g = tmp_path / "g.yaml"
    g.write_text(_grid_text(shared_data))
    assert main(["stimuli", "grid", str(g), "--out", str(tmp_path / "out")]) == 0, capsys.readouterr().err
    plain = tmp_path / "plain.yaml"
    plain.write_text(_grid_text(shared_data).split("design:")[0].replace("shapes: [0.0, 1.0]", "shapes: [0.0]"))
    assert main(["stimuli", "grid", str(plain), "--out", str(tmp_path / "plain")]) == 0
    from PIL import Image

    name = "a_realistic_original_neutral_gi_soft_pbr.png"
    same = [np.asarray(Image.open(tmp_path / d / "images" / name)) for d in ("out", "plain")]
    assert np.array_equal(*same)
    import pandas as pd

    cont = pd.read_csv(tmp_path / "out" / "continuum.csv")
    assert {"cheek_detail", "eye_area", "eye_roundness", "nose_width", "mouth_width", "forehead_height"} <= set(cont.columns)
    shape = cont[cont["factor"] == "shape"].set_index("position")
    assert shape.loc[1, "eye_area"] >= 2.5 * shape.loc[0, "eye_area"] and shape.loc[1, "eye_roundness"] >= 0.5
    lm = pd.read_csv(tmp_path / "out" / "landmarks.csv")
    pts = {(r.shape, r.expression, r.landmark): np.array([r.x, r.y, r.z]) for r in lm.itertuples()}
    real, toon = (_landmark_measures({k[2]: p for k, p in pts.items() if k[:2] == (s, "neutral")}) for s in (0.0, 1.0))
    assert toon["eye_area"] >= 2.5 * real["eye_area"] and toon["eye_ratio"] >= 0.5 and toon["nose"] <= 0.6 * real["nose"]
    for shape in (0.0, 1.0):
        width = np.linalg.norm(pts[shape, "neutral", "face_left"] - pts[shape, "neutral", "face_right"])
        move = {e: np.mean([np.linalg.norm(pts[shape, e, k] - pts[shape, "neutral", k]) for k in ks]) / width
                for e, ks in (("happiness", ("mouth_left", "mouth_right")), ("surprise", ("brow_left", "brow_right")))}
        if shape == 0.0:
            real = move
        else:
            assert move["happiness"] >= real["happiness"] and move["surprise"] >= real["surprise"], (move, real)


@pytest.mark.parametrize("change,needles", [
    ({"identity_model: MORE": "identity_model: null"}, ("design", "identity_model: the ICT identity components")),
    ({"{name: a, ict: ICT, identity: identity001, hair: none}": "{name: a, procedural: {seed: 1}}"},
     ("design: character 'a' has no ICT rig",)),
    ({"landmarks: LANDMARKS": "landmarks: {nose_tip: [0, 1, 0]}"}, ("expected at least 6 landmarks",)),
])
def test_bad_design_entries_give_one_line_errors(shared_data, tmp_path, capsys, change, needles):
    g = tmp_path / "g.yaml"
    g.write_text(_grid_text(shared_data, change))
    one_line_error(capsys, ["stimuli", "grid", str(g), "--out", str(tmp_path / "out")], *needles)


def test_cheek_detail_tells_a_photograph_from_paint(shared_data):
    """The continuum's skin-detail measure: a London photograph at stimulus size shows what a photograph
    does (0.007-0.012 at 512 px); the same face with its fine detail blurred away, a fraction of it."""
    from PIL import Image
    from scipy.ndimage import gaussian_filter

    from stimulus_engine.morphpca.keypoints import detect_landmarks
    from stimulus_engine.stylisation.image_distance import cheek_detail

    photo = np.asarray(Image.open(shared_data / "faces2d/london-frl/neutral_front/001_03.jpg").convert("RGB")
                       .resize((512, 512)))
    lm = detect_landmarks(photo)
    real = cheek_detail(photo, lm)
    assert 0.006 <= real <= 0.015
    smooth = np.clip(gaussian_filter(photo.astype(float), (3, 3, 0)), 0, 255).astype(np.uint8)
    assert cheek_detail(smooth, lm) <= 0.3 * real
