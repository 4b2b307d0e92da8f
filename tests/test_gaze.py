"""Eyes that look at the camera: lines of sight of every rig kind, aimed eyeballs, and every
shipped grid's characters in every expression and shape looking into the lens."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from appeal.studyfile import load_study_file
from stimulus_engine.characters.gaze import aim_eyes, lines_of_sight, pupil_ring, sight_misses
from stimulus_engine.characters.procedural_head import procedural_head
from stimulus_engine.parts.eyes import eyeball_asset, painted_pupils

ROOT = Path(__file__).resolve().parent.parent
GRIDS = sorted((ROOT / "protocols" / "grids").glob("*.yaml"))


def _sphere(n: int = 2000) -> np.ndarray:
    """Evenly spread unit vectors (a Fibonacci sphere), like a real eyeball's vertices."""
    k = np.arange(n) + 0.5
    z, phi = 1 - 2 * k / n, np.pi * (1 + 5**0.5) * k
    r = np.sqrt(1 - z**2)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def test_aim_turns_only_the_eyeball_rigidly_onto_the_target():
    ball = _sphere() * 1.2 + [3.0, 2.0, 1.0]
    other = np.random.default_rng(1).normal(size=(50, 3))
    v = np.vstack([ball, other])
    idx = np.arange(len(ball))
    lm = {"eye_left": idx, "pupil_left": pupil_ring(v, idx, np.array([3.0, 2.0, 1.0]), np.array([0.3, 0.0, 1.0]))}
    c, a = lines_of_sight(lm, v)["left"]
    assert np.allclose(c, [3, 2, 1], atol=1e-9) and np.degrees(np.arccos(a @ np.array([0.3, 0, 1]) / np.hypot(0.3, 1))) < 3
    target = np.array([-20.0, 35.0, 70.0])
    out = aim_eyes(lm, v, target)
    assert sight_misses(lm, out, target)["left"] < 1e-9
    assert np.array_equal(out[len(ball):], other)  # nothing else moves
    d0 = np.linalg.norm(ball[:, None] - ball[None], axis=-1)
    d1 = np.linalg.norm(out[idx][:, None] - out[idx][None], axis=-1)
    assert np.allclose(d0, d1, atol=1e-9)  # rigid
    assert sight_misses(lm, v, target)["left"] > 10  # before, it looked elsewhere


def test_a_rig_without_eyes_is_left_as_it_is():
    v = _sphere()
    assert np.array_equal(aim_eyes({}, v, np.zeros(3)), v) and lines_of_sight({"eye_right": np.arange(5)}, v) == {}


def test_template_eyeballs_look_through_their_painted_pupils():
    """MakeHuman's eyeballs are turned by the pupil painted in their texture, not by their mesh's
    front cap (15-18 degrees above it: the irises looked down and showed white above them)."""
    balls, texture = eyeball_asset()
    pupils = painted_pupils(texture)
    assert len(pupils) == 2
    for unit, _, uv in balls:
        pupil = min(pupils, key=lambda p: float(np.linalg.norm(uv - p, axis=1).min()))
        near = np.linalg.norm(uv - pupil, axis=1) < 0.03
        d = unit[near].mean(axis=0)
        assert np.degrees(np.arccos(d[2] / np.linalg.norm(d))) < 1.0


@pytest.mark.parametrize("kind", ["procedural", "ict"])
def test_every_rig_kind_marks_its_lines_of_sight(kind, shared_data):
    if kind == "procedural":
        rig = procedural_head(0, texture_size=64, resolution=32)
    else:
        from stimulus_engine.characters.ict import load_ict_rig

        rig = load_ict_rig(shared_data / "meshes" / "ict-facekit", "identity000", shapes=[])
    sight = lines_of_sight(rig.landmarks, rig.vertices)
    assert set(sight) == {"right", "left"}
    for side, (c, a) in sight.items():
        assert np.degrees(np.arccos(a[2])) < 10  # forward, as modelled
        assert np.isin(rig.landmarks[f"pupil_{side}"], rig.landmarks[f"eye_{side}"]).all()
    assert sight["right"][0][0] < sight["left"][0][0]  # the subject's right is -x


@pytest.fixture(scope="module")
def prepared(tmp_path_factory):
    """Every shipped grid prepared (one material each: geometry does not depend on it), one cache."""
    from stimulus_engine.grid.characters import load_character
    from stimulus_engine.grid.prepare import prepare_grid
    from stimulus_engine.grid.schema import GridFile

    out = tmp_path_factory.mktemp("gaze")
    done = []
    for path in GRIDS:
        grid = load_study_file(path, GridFile)
        grid = grid.model_copy(update={"materials": grid.material_specs()[:1], "lighting": grid.lighting[:1],
                                       "shading": grid.shading[:1], "photographs": [], "pair_materials_with_shapes": False,
                                       "animation": None})  # an animated grid's cells as stills (a pool's rest face)
        manifest, items, _ = prepare_grid(grid, out, source=path.name)
        chars = {c.name: load_character(c, out / ".cache", path.name) for c in grid.characters}
        done.append((path.name, grid, manifest, items, chars))
    return done


@pytest.mark.slow
def test_every_shipped_character_looks_into_the_lens(prepared):
    """Each line of sight passes within 1 cm of the camera: every shipped grid, character, shape
    and expression (the drawn eyeballs of scans, the rig's own elsewhere)."""
    seen = set()
    for name, grid, manifest, items, chars in prepared:
        assert grid.render.gaze == "camera"
        for item, row in zip(items, manifest.itertuples()):
            ch = chars[row.character]
            drawn = ch.rig if ch.scan is None else ch.scan.topology
            v = np.load(item.geometry_npy).astype(np.float64)
            misses = sight_misses(drawn.landmarks, v, np.asarray(item.camera[0]))
            assert set(misses) == {"right", "left"}, (name, row.character)
            assert max(misses.values()) < 1.0, (name, row.file, misses)
            seen.add((row.character, row.expression))
    assert {e for _, e in seen} >= {"neutral", "anger", "happiness", "sadness", "surprise"}
    assert {c for c, _ in seen} >= {"james", "lps"}


@pytest.mark.slow
def test_gaze_model_leaves_the_eyes_as_posed(prepared, tmp_path):
    """With ``gaze: model`` nothing is aimed: the rig's eyes diverge and miss the camera by centimetres."""
    from stimulus_engine.grid.prepare import prepare_grid

    name, grid, *_ = prepared[0]
    grid = grid.model_copy(update={"render": grid.render.model_copy(update={"gaze": "model"}),
                                   "expressions": grid.expressions[:1]})
    manifest, items, _ = prepare_grid(grid, tmp_path)
    from stimulus_engine.grid.characters import load_character

    ch = load_character(grid.characters[0], tmp_path / ".cache", name)
    drawn = ch.rig if ch.scan is None else ch.scan.topology
    misses = sight_misses(drawn.landmarks, np.load(items[0].geometry_npy).astype(np.float64), np.asarray(items[0].camera[0]))
    assert max(misses.values()) > 1.0


def test_grid_files_say_where_the_eyes_look(tmp_path):
    from appeal.errors import AppealInputError
    from stimulus_engine.grid.schema import GridFile

    text = (ROOT / "protocols" / "grids" / "exp1c_texture.yaml").read_text()
    for gaze, ok in (("camera", True), ("model", True), ("[0, 10, 80]", True), ("the_moon", False), ("[1, 2]", False)):
        f = tmp_path / "g.yaml"
        f.write_text(text + f"\nrender: {{gaze: {gaze}}}\n" if "render:" not in text else text)
        if ok:
            assert load_study_file(f, GridFile).render.gaze is not None
        else:
            with pytest.raises(AppealInputError, match=r"render\.gaze"):
                load_study_file(f, GridFile)


@pytest.mark.slow
def test_aimed_eyeballs_stay_behind_the_lids(prepared):
    """No drawn eyeball of a scan lies in front of its lids' skin (james's left one came through
    his thin lower lid by up to 0.6 mm, a grey patch of sclera on the lid)."""
    from stimulus_engine.characters.skin_clearance import behind_skin

    checked = 0
    for _, _, manifest, items, chars in prepared:
        for item, row in zip(items, manifest.itertuples()):
            ch = chars[row.character]
            if ch.scan is None:
                continue
            topo = ch.scan.topology
            v = np.load(item.geometry_npy).astype(np.float64)
            for side in ("right", "left"):
                ball = topo.landmarks[f"eye_{side}"]
                moved = behind_skin(v, topo.faces, topo.face_part, topo.part_names, ball, gap=0.0)
                assert np.abs(moved[ball] - v[ball]).max() < 1e-3, (row.file, side)  # float32 storage
                checked += 1
    assert checked > 0


@pytest.mark.slow
def test_lashes_stay_rooted_on_the_lids(prepared):
    """Rig characters (ICT rig on a mesh: Lee Perry-Smith) keep every lash root within 0.5 mm of
    the lid skin in every shape and expression (carried along with the smooth displacement, the
    upper lashes floated a few millimetres above the lid)."""
    from scipy.spatial import cKDTree

    from stimulus_engine.geometry.closest import SurfaceIndex

    checked = 0
    for _, _, manifest, items, chars in prepared:
        for item, row in zip(items, manifest.itertuples()):
            rig = chars[row.character].rig
            if chars[row.character].scan is not None or "lashes" not in rig.part_names:
                continue
            skin = rig.faces[rig.face_part == rig.part_names.index("skin")]
            lash = np.unique(rig.faces[rig.face_part == rig.part_names.index("lashes")])
            index = SurfaceIndex(rig.vertices, skin)
            roots = lash[index.query(rig.vertices[lash]).distance < 0.01]  # on the lid in the neutral
            assert len(roots) > 20
            v = np.load(item.geometry_npy).astype(np.float64)
            gap = SurfaceIndex(v, skin).query(v[roots]).distance
            assert gap.max() < 0.05, (row.file, float(gap.max()))
            # each card keeps its shape, grown with its eye: bound vertex by vertex, the cartoon
            # level's lash tips came apart into dark shards over the eye (stretch up to 2.2x)
            # each card's root as seat_lashes takes it (the lash vertices nearest the lid, its closest tenth)
            d0 = index.query(rig.vertices[lash]).distance
            seated = lash[d0 <= max(float(np.percentile(d0, 10)), 1e-9)]
            own = seated[cKDTree(rig.vertices[seated]).query(rig.vertices[lash])[1]]
            lm0, lm1 = rig.landmark_points(), rig.landmark_points(v)
            grow = max(np.linalg.norm(lm1[f"eye_{s}_outer"] - lm1[f"eye_{s}_inner"])
                       / np.linalg.norm(lm0[f"eye_{s}_outer"] - lm0[f"eye_{s}_inner"]) for s in ("right", "left"))
            before = np.linalg.norm(rig.vertices[lash] - rig.vertices[own], axis=1)
            after = np.linalg.norm(v[lash] - v[own], axis=1)
            long = before > 0.05
            assert (after[long] / before[long]).max() < 1.05 * grow, (row.file, float((after[long] / before[long]).max()))
            checked += 1
    assert checked > 0


def test_template_sclera_is_lit_like_a_photographed_one():
    """The eyeball texture's sclera sits at SCLERA_LEVEL (MakeHuman's photograph had it at 120-130:
    as dark as the skin around a rendered eye); the iris and pupil keep their colours."""
    from stimulus_engine.geometry.uv_raster import rasterize_uv
    from stimulus_engine.parts.eyes import SCLERA_LEVEL

    from PIL import Image

    from stimulus_engine.data import DATA_DIR

    balls, texture = eyeball_asset()
    raw = np.asarray(Image.open(DATA_DIR / "eyes" / "brown_eye.jpg").convert("RGB"))
    h, w = texture.shape[:2]
    for unit, faces, uv in balls:
        angle = np.degrees(np.arccos(np.clip(unit[:, 2], -1, 1)))
        rows, cols, fid, bary = rasterize_uv(uv, faces, w, h)
        a = np.einsum("nk,nk->n", bary, angle[faces[fid]])
        grey = texture[rows, cols].astype(float).mean(axis=1)
        assert abs(np.median(grey[(a > 26) & (a < 90)]) - SCLERA_LEVEL) < 3
        iris = a < 18
        assert np.array_equal(texture[rows[iris], cols[iris]], raw[rows[iris], cols[iris]])  # iris and pupil as photographed
        assert np.median(raw[rows, cols][(a > 26) & (a < 90)].mean(axis=1)) < 140  # it was dim
