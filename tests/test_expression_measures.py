"""How far each expression moves the face per shape level (stimulus_engine.grid.expression_measures):
exact measures and agreement on synthetic faces with known moves, invariance to a level's pose and
size, bad input, and the files a grid run writes."""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from appeal.errors import AppealInputError
from stimulus_engine.characters.rig import LANDMARK_NAMES
from stimulus_engine.grid.expression_measures import (
    MEASURES,
    expression_measures,
    expression_spread,
    level_agreement,
    write_expression_measures,
)

#: A frontal face in (across, up, depth), forehead_top -> chin 20 long; the eyes' centres level.
FACE: dict[str, tuple[float, float, float]] = {
    "eye_right": (-3, 2, -1), "eye_left": (3, 2, -1),
    "eye_right_outer": (-4.5, 2, 0), "eye_right_inner": (-1.5, 2, 0), "eye_right_top": (-3, 2.6, 0.2),
    "eye_right_bottom": (-3, 1.5, 0.2), "eye_left_outer": (4.5, 2, 0), "eye_left_inner": (1.5, 2, 0),
    "eye_left_top": (3, 2.6, 0.2), "eye_left_bottom": (3, 1.5, 0.2),
    "nasion": (0, 2.5, 0.5), "subnasale": (0, -3, 1.5), "nose_tip": (0, -1.5, 3), "nose_right": (-1.2, -2.8, 1),
    "nose_left": (1.2, -2.8, 1), "mouth_right": (-2.2, -5.5, 0.8), "mouth_left": (2.2, -5.5, 0.8),
    "mouth_top": (0, -5, 1.2), "mouth_bottom": (0, -6, 1.1), "chin": (0, -10, 0), "face_right": (-7, 0, -3),
    "face_left": (7, 0, -3), "forehead_top": (0, 10, 0), "brow_right": (-3, 4, 0.6), "brow_left": (3, 4, 0.6),
    "pupil_right": (-3, 2, 0.3), "pupil_left": (3, 2, 0.3),
}
LENGTH = 20.0
#: Moves (across, up, depth) in face lengths: the jaw drops, the mouth widens and its corners
#: rise, the brows rise, the left eye opens; the nose tip pushes forward (only ``total`` sees it).
SURPRISE = {"mouth_bottom": (0, -0.1, 0), "mouth_left": (0.02, 0.03, 0), "mouth_right": (-0.02, 0.03, 0),
            "brow_left": (0, 0.04, 0), "brow_right": (0, 0.04, 0), "eye_left_top": (0, 0.01, 0),
            "eye_left_bottom": (0, -0.01, 0), "nose_tip": (0, 0, 0.05)}
#: Its measures, by the module's formulas.
SURPRISE_MEASURES = {"mouth_opening": 0.1, "mouth_width": 0.04, "mouth_corner_raise": 0.03, "brow_raise": 0.04,
                     "eye_opening": 0.01,
                     "total": np.sqrt(sum(np.sum(np.square(d)) for d in SURPRISE.values()) / (len(FACE) - 4))}


def _geometry(character: str, shape: float, expression: str, moves: dict, scale: float = 1.0) -> list[dict]:
    """Landmark rows of FACE (``scale`` times as large) with ``moves`` in face lengths."""
    rows = []
    for name, p in FACE.items():
        xyz = scale * (np.asarray(p, float) + LENGTH * np.asarray(moves.get(name, (0, 0, 0)), float))
        rows.append({"character": character, "shape": shape, "stylisation": int(shape == 0.0), "expression": expression,
                     "landmark": name, "x": xyz[0], "y": xyz[1], "z": xyz[2]})
    return rows


def _scaled(moves: dict, k: float) -> dict:
    return {n: tuple(k * np.asarray(d)) for n, d in moves.items()}


def _grid_landmarks() -> pd.DataFrame:
    """Character a: realistic (shape 0) surprise as SURPRISE; cartoon (shape 1, a face 0.8 as large)
    with half of every move; happiness only raising the mouth corners, by the same amount at both."""
    smile = {"mouth_left": (0, 0.02, 0), "mouth_right": (0, 0.02, 0)}
    rows = []
    for shape, scale, k in ((0.0, 1.0, 1.0), (1.0, 0.8, 0.5)):
        rows += _geometry("a", shape, "neutral", {}, scale)
        rows += _geometry("a", shape, "surprise", _scaled(SURPRISE, k), scale)
        rows += _geometry("a", shape, "happiness", smile, scale)
    return pd.DataFrame(rows)


def _value(table: pd.DataFrame, **where: object) -> float:
    sel = np.logical_and.reduce([table[k] == v for k, v in where.items()])
    assert sel.sum() == 1, where
    return float(table.loc[sel, "value"].iloc[0])


def test_synthetic_face_has_the_land_marks_of_a_rig():
    assert set(FACE) == set(LANDMARK_NAMES)


def test_measures_are_the_known_moves_in_face_lengths():
    t = expression_measures(_grid_landmarks())
    assert list(t.columns) == ["character", "shape", "stylisation", "expression", "measure", "value"]
    assert len(t) == 1 * 2 * 2 * len(MEASURES)  # neutral left out
    assert list(dict.fromkeys(t["expression"])) == ["surprise", "happiness"]
    for m, v in SURPRISE_MEASURES.items():
        assert _value(t, shape=0.0, expression="surprise", measure=m) == pytest.approx(v, abs=1e-12), m
        assert _value(t, shape=1.0, expression="surprise", measure=m) == pytest.approx(v / 2, abs=1e-12), m
    smile = t[t["expression"] == "happiness"].set_index(["shape", "measure"])["value"]
    assert smile[(0.0, "mouth_corner_raise")] == pytest.approx(0.02, abs=1e-12)
    assert smile[(1.0, "mouth_corner_raise")] == pytest.approx(0.02, abs=1e-12)
    for m in ("mouth_opening", "mouth_width", "brow_raise", "eye_opening"):
        assert smile[(0.0, m)] == pytest.approx(0.0, abs=1e-12)


def test_depth_moves_count_only_in_total_and_a_moved_head_does_not_count():
    push = {"mouth_bottom": (0, 0, 0.1), "brow_left": (0, 0, 0.1)}  # towards the camera: no screen move
    shift = {n: (0.1, -0.2, 0.3) for n in FACE}                       # the whole head, eyes included
    t = expression_measures(pd.DataFrame(_geometry("a", 0.0, "neutral", {}) + _geometry("a", 0.0, "push", push)
                                         + _geometry("a", 0.0, "shift", shift)))
    v = t.set_index(["expression", "measure"])["value"]
    for m in MEASURES[:-1]:
        assert v[("push", m)] == pytest.approx(0.0, abs=1e-12), m
        assert v[("shift", m)] == pytest.approx(0.0, abs=1e-12), m
    assert v[("push", "total")] == pytest.approx(np.sqrt(2 * 0.01 / 23), abs=1e-12)
    assert v[("shift", "total")] == pytest.approx(0.0, abs=1e-12)


def _rigid(rows: pd.DataFrame, seed: int) -> pd.DataFrame:
    """``rows`` rotated, uniformly scaled and translated (one transform for all of them)."""
    rng = np.random.default_rng(seed)
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    rot = q * np.sign(np.diag(r))
    rot[:, 0] *= np.sign(np.linalg.det(rot))  # a rotation, not a reflection
    xyz = rows[["x", "y", "z"]].to_numpy() @ rot.T * 3.7 + rng.normal(size=3) * 50
    return rows.assign(x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_measures_do_not_depend_on_a_levels_pose_or_size(seed):
    lm = _grid_landmarks()
    cartoon = lm["shape"] == 1.0
    moved = pd.concat([lm[~cartoon], _rigid(lm[cartoon], seed)], ignore_index=True)
    a, b = expression_measures(lm), expression_measures(moved)
    assert (a.drop(columns="value") == b.drop(columns="value")).all().all()
    np.testing.assert_allclose(b["value"], a["value"], atol=1e-12)
    # rotating only the expression (not its neutral) is a move: the measures see it
    turned = pd.concat([lm[lm["expression"] == "neutral"], _rigid(lm[lm["expression"] != "neutral"], seed)])
    assert not np.allclose(expression_measures(turned)["value"], a["value"], atol=1e-3)


def test_agreement_is_exact_and_judges_only_what_the_realistic_level_moves():
    ag = level_agreement(expression_measures(_grid_landmarks())).set_index(["expression", "measure"])
    surprise = ag.loc["surprise"]
    assert (surprise["levels"] == 2).all()
    for m, v in SURPRISE_MEASURES.items():
        assert surprise.loc[m, "realistic"] == pytest.approx(v, abs=1e-12)
        assert surprise.loc[m, "ratio"] == pytest.approx(2.0, rel=1e-9)
        assert surprise.loc[m, "largest_relative_difference"] == pytest.approx(0.5, rel=1e-9)
        assert surprise.loc[m, "at_shape"] == 1.0
        assert surprise.loc[m, "share"] == pytest.approx(v / 0.1, rel=1e-9)  # mouth opening is the largest
    # a quarter of the largest (0.1) at least: total (0.028) is, eye opening (0.01) is not
    assert surprise["judged"].to_dict() == {"mouth_opening": True, "mouth_width": True, "mouth_corner_raise": True,
                                            "brow_raise": True, "eye_opening": False, "total": True}
    smile = ag.loc["happiness"]
    assert smile.loc["mouth_corner_raise", "largest_relative_difference"] == pytest.approx(0.0, abs=1e-9)
    assert smile.loc["mouth_corner_raise", "judged"]
    # a feature the realistic level does not move: no ratio or relative difference to speak of
    assert np.isnan(smile.loc["brow_raise", "largest_relative_difference"])
    assert not smile.loc["brow_raise", "judged"]
    spread = expression_spread(ag.reset_index()).set_index("expression")
    assert spread.loc["surprise", "largest_relative_difference"] == pytest.approx(0.5, rel=1e-9)
    assert spread.loc["surprise", "judged"] == 5
    assert spread.loc["happiness", "measure"] == "mouth_corner_raise"


def test_agreement_of_a_sign_that_flips_and_of_a_level_that_does_not_move():
    t = pd.DataFrame({"character": "a", "expression": "x", "measure": "brow_raise", "shape": [0.0, 0.25, 0.5, 1.0],
                      "value": [0.04, -0.03, 0.0, 0.02]})
    row = level_agreement(t).iloc[0]
    assert row["ratio"] == np.inf  # shape 0.5 does not move the brows
    assert row["largest_relative_difference"] == pytest.approx(1.75)  # the flip at 0.25: |-0.03 - 0.04| / 0.04
    assert row["at_shape"] == 0.25 and row["smallest"] == -0.03 and row["largest"] == 0.04
    assert row["judged"]


def test_up_is_perpendicular_to_the_eye_line_when_the_face_is_not():
    """A face whose chin sits off the line through the eye centres' midpoint (a scan's head turned a
    little, james's is): up is still perpendicular to the eye line, the length forehead -> chin."""
    sheared = {**FACE, "forehead_top": (-1, 10, 0), "chin": (1, -10, 0)}
    length = np.hypot(2, 20)

    def rows(expression: str, moves: dict) -> list[dict]:  # moves in scene units
        return [{"character": "a", "shape": 0.0, "stylisation": 0, "expression": expression, "landmark": k,
                 "x": p[0] + moves.get(k, (0, 0))[0], "y": p[1] + moves.get(k, (0, 0))[1], "z": p[2]}
                for k, p in sheared.items()]

    along = {"mouth_left": (0.5, 0), "mouth_right": (0.5, 0), "brow_left": (-0.3, 0)}  # along the eye line only
    lift = {"mouth_left": (0, 0.4), "mouth_right": (0, 0.4)}
    t = expression_measures(pd.DataFrame(rows("neutral", {}) + rows("along", along) + rows("lift", lift)))
    v = t.set_index(["expression", "measure"])["value"]
    assert v[("along", "mouth_corner_raise")] == pytest.approx(0.0, abs=1e-12)
    assert v[("along", "brow_raise")] == pytest.approx(0.0, abs=1e-12)
    assert v[("lift", "mouth_corner_raise")] == pytest.approx(0.4 / length, abs=1e-12)


def test_levels_are_ordered_by_shape_not_by_table_order():
    lm = _grid_landmarks()
    backwards = pd.concat([lm[lm["shape"] == 1.0], lm[lm["shape"] == 0.0]], ignore_index=True)
    ag = level_agreement(expression_measures(backwards)).set_index(["expression", "measure"])
    assert ag.loc[("surprise", "mouth_opening"), "realistic"] == pytest.approx(0.1)


@pytest.mark.parametrize("change, message", [
    (lambda d: d.drop(columns="z"), "lacks column(s) z"),
    (lambda d: d[d["landmark"] != "mouth_top"], "lacks landmark(s) mouth_top"),
    (lambda d: d[~((d["expression"] == "neutral") & (d["shape"] == 1.0))], "no neutral geometry"),
    (lambda d: pd.concat([d, d.iloc[:1]]), "twice"),
    (lambda d: d.assign(x=d["x"].where(d["landmark"] != "chin")), "empty coordinates"),
    (lambda d: d.assign(y=0.0, x=0.0, z=0.0), "degenerate neutral face"),
    (lambda d: d[~((d["expression"] == "surprise") & (d["landmark"] == "nasion"))], "other landmarks"),
])
def test_bad_landmark_tables_are_one_line_input_errors(change, message):
    with pytest.raises(AppealInputError, match=message.replace("(", r"\(").replace(")", r"\)")) as err:
        expression_measures(change(_grid_landmarks()))
    assert "\n" not in str(err.value)


def test_nothing_to_compare_writes_nothing(tmp_path):
    from stimulus_engine.grid.schema import GridFile

    grid = GridFile(kind="grid", name="g", characters=[{"name": "a", "procedural": {}}], shapes=[0.0, 1.0],
                    materials=["original"], expressions=["neutral"])
    lm = _grid_landmarks()
    assert write_expression_measures(tmp_path, lm[lm["expression"] == "neutral"], grid) == []
    assert write_expression_measures(tmp_path, lm[lm["shape"] == 0.0], grid) == []
    assert write_expression_measures(tmp_path, lm[lm["expression"] != "neutral"], grid) == []
    assert not list(tmp_path.iterdir())


GRID = """kind: grid
name: tiny_expr
characters:
  - name: a
    procedural: {seed: 1, texture_size: 128, resolution: 32}
shapes: [0.0, 1.0]
materials: [original]
expressions: [neutral, surprise, happy]
lighting: [flat]
shading: [pbr]
render: {width: 64, height: 48}
"""


def test_run_grid_writes_the_measures_the_agreement_and_the_figure(tmp_path, caplog):
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile

    p = tmp_path / "g.yaml"
    p.write_text(GRID)
    grid = load_study_file(p, GridFile)
    out = tmp_path / "out"
    with caplog.at_level(logging.INFO, logger="stimulus_engine.grid.expression_measures"):
        _, sheets = run_grid(grid, out, n_jobs=1)
    assert sheets[-1] == out / "expression_measures.png"
    with Image.open(sheets[-1]) as im:
        assert im.size[0] > 400 and im.size[1] > 200
    table = pd.read_csv(out / "expression_measures.csv")
    assert len(table) == 1 * 2 * 2 * len(MEASURES)
    assert set(table["expression"]) == {"surprise", "happiness"}
    # the same numbers as measured from the landmarks the run wrote
    again = expression_measures(pd.read_csv(out / "landmarks.csv"))
    np.testing.assert_allclose(table["value"], again["value"], atol=1e-6)
    v = table.set_index(["shape", "expression", "measure"])["value"]
    # (at resolution 32 the head's mouth_top and mouth_bottom are one vertex: its mouth opening measures 0)
    assert v[(0.0, "surprise", "brow_raise")] > 0.01 and v[(1.0, "surprise", "brow_raise")] > 0.01
    assert v[(0.0, "happiness", "mouth_corner_raise")] > 0.005
    ag = pd.read_csv(out / "expression_agreement.csv")
    assert len(ag) == 2 * len(MEASURES) and ag["judged"].any()
    lines = [r.getMessage() for r in caplog.records if "largest relative difference" in r.getMessage()]
    assert len(lines) == 2 and all(ln.startswith("tiny_expr: a ") for ln in lines)
