"""Psychophysics sessions (issue 34): pairs along a continuum, procedures that pick each level,
balanced sides, per-trial state, resume, and one-line errors — on drawn faces, simulated
participants and the real runner (window-less; the live keyboard session is in
``test_psychophysics_live.py``)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from appeal.assets import protocols_dir
from appeal.psychophysics import procedure_from_dict
from appeal.studyfile import load_study_file
from appeal_cli import main
from experiments.drawn_faces import draw_face_grid
from experiments.protocol_schema import Protocol
from experiments.session import run_session

LEVELS = [round(float(x), 3) for x in np.linspace(0, 1, 11)]

PROTOCOL = {
    "kind": "protocol", "name": "psy", "task": "psy",
    "stimuli": {"manifest": "stim/manifest.csv", "factors": ["character", "shape", "emotion"]},
    "timing": {"stimulus_s": 0.5, "fixation_s": [0.3, 0.5]},
    "psychophysics": {"continuum": "shape", "reference": 0.0, "conditions": ["emotion"],
                      "procedure": {"method": "psi", "max_trials": 40}},
    "responses": [{"type": "classification", "name": "choice", "prompt": "Which face looks more real?",
                   "choices": [{"label": "left", "value": "left", "key": "left"},
                               {"label": "right", "value": "right", "key": "right"}]}],
}

#: An observer without participant spread, so the true thresholds are known exactly.
MODEL = {"kind": "participant_model", "rt": {"median_s": 0.5, "sigma": 0.1},
         "psychometric": {"threshold": 0.3, "width": 0.4, "lapse": 0.02,
                          "by": {"emotion": {"happiness": {"threshold": 0.2}, "anger": {"threshold": 0.45}}}}}


@pytest.fixture(scope="module")
def stim(tmp_path_factory):
    root = tmp_path_factory.mktemp("psy")
    manifest = draw_face_grid(root / "stim", {"character": ["c1", "c2"], "shape": LEVELS,
                                              "emotion": ["happiness", "anger"]}, size=(120, 90))
    table = pd.read_csv(manifest)
    gone = (table["character"] == "c1") & (table["shape"] == 0.3) & (table["emotion"] == "anger")
    table[~gone].to_csv(manifest.with_name("partial.csv"), index=False)
    return root


def write(root: Path, name: str, changes: dict | None = None, psy: dict | None = None) -> Path:
    data = copy.deepcopy(PROTOCOL)
    data.update(changes or {})
    data["psychophysics"].update(psy or {})
    path = root / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def model(root: Path, **psychometric) -> Path:
    m = copy.deepcopy(MODEL)
    m["psychometric"].update(psychometric)
    path = root / "model.yaml"
    path.write_text(yaml.safe_dump(m))
    return path


def session(proto: Path, out: Path, sim: Path | str = "default", **kw) -> pd.DataFrame:
    res = run_session(proto, "01", out=out, simulate=str(sim), window=False, report=False, **kw)
    assert res.status == "complete"
    return pd.read_csv(res.beh, sep="\t", keep_default_na=False, na_values=["n/a"])


def test_psi_session_rows_carry_level_side_state_and_estimate(stim, tmp_path):
    proto = write(stim, "psi")
    beh = session(proto, tmp_path / "o", model(tmp_path))
    assert len(beh) == 80 and (beh["phase"] == "main").all()
    assert set(beh["procedure"]) == {"emotion-happiness", "emotion-anger"}
    for label, track in beh.groupby("procedure"):
        assert track["procedure_trial"].tolist() == list(range(1, 41))
        # the reference face's position is balanced in every two trials of a track
        sides = track["reference_side"].tolist()
        assert all({a, b} == {"left", "right"} for a, b in zip(sides[::2], sides[1::2]))
        # the comparison is the same item (character) and condition at the level shown
        assert (track["reference_stimulus"].str.contains("shape-0.0_")).all()
        assert (track["emotion"] == label.split("-")[1]).all()
        assert np.allclose(track["difference"], track["level"])  # reference 0: the difference is the level
        assert (track["correct"] == (track["response_choice"] == track["reference_side"]).astype(int)).all()
        # each row's state is the procedure after that answer: rebuilt, it gives the row's estimate
        last = track.iloc[-1]
        proc = procedure_from_dict(json.loads(last["procedure_state"]))
        assert proc.n_trials == 40 and proc.finished
        assert proc.estimate()["threshold"] == pytest.approx(last["estimate_threshold"])
        assert [x for x, _ in proc.history] == track["difference"].tolist()
    # the 95 % interval of each track holds the observer's threshold
    final = beh.groupby("procedure").tail(1).set_index("procedure")
    for label, true in (("emotion-happiness", 0.2), ("emotion-anger", 0.45)):
        assert final.loc[label, "estimate_threshold_lo"] <= true <= final.loc[label, "estimate_threshold_hi"]
    assert final.loc["emotion-happiness", "estimate_threshold"] < final.loc["emotion-anger", "estimate_threshold"]


def test_resumed_session_continues_the_same_procedures(stim, tmp_path):
    proto = write(stim, "psi")
    sim = model(tmp_path)
    whole = session(proto, tmp_path / "whole", sim, seed=3)
    out = tmp_path / "cut"
    session(proto, out, sim, seed=3)
    beh = next(out.glob("*_beh.tsv"))
    lines = beh.read_text().splitlines(keepends=True)
    beh.write_text("".join(lines[:1 + 25]))  # as if the session had stopped after 25 trials
    resumed = session(proto, out, sim, resume=True)
    assert resumed["trial"].tolist() == list(range(1, len(resumed) + 1))
    # the next trial is the one the uninterrupted session showed: it depends only on the answers so far
    cols = ["procedure", "stimulus", "level", "reference_side", "fixation_frames"]
    assert resumed.iloc[25][cols].tolist() == whole.iloc[25][cols].tolist()
    # and its procedure went on from the 25 answers on disk
    track = resumed.iloc[25]["procedure"]
    before = resumed.iloc[:25]
    state = json.loads(resumed.iloc[25]["procedure_state"])
    kept = before[before["procedure"] == track]
    assert [x for x, _ in state["history"]][:len(kept)] == kept["difference"].tolist()
    assert len(state["history"]) == len(kept) + 1
    assert resumed.groupby("procedure").size().tolist() == [40, 40] and resumed["part"].iloc[-1] == 2


def test_staircase_constant_stimuli_interleaving_and_practice(stim, tmp_path):
    stair = write(stim, "stair", psy={"interleave": 2, "practice_trials": 3, "conditions": [],
                                      "procedure": {"method": "staircase", "down": 2, "max_reversals": 6,
                                                    "max_trials": 50}})
    beh = session(stair, tmp_path / "s", model(tmp_path))
    practice = beh[beh["phase"] == "practice"]
    assert len(practice) == 3 and (practice["level"] == 1.0).all() and practice["estimate_threshold"].isna().all()
    main_rows = beh[beh["phase"] == "main"]
    assert set(main_rows["procedure"]) == {"all_1", "all_2"}
    for _, track in main_rows.groupby("procedure"):
        assert track["procedure_kind"].eq("updown").all() and track["level"].iloc[0] == 1.0  # starts easiest
        proc = procedure_from_dict(json.loads(track.iloc[-1]["procedure_state"]))
        assert proc.finished and len(proc.reversals) >= 6 or proc.n_trials == 50
    const = write(stim, "const", psy={"levels": [0.1, 0.3, 0.5, 0.7], "procedure": {"method": "constant",
                                                                                     "trials_per_level": 3}})
    beh = session(const, tmp_path / "c", model(tmp_path))
    counts = beh.groupby(["procedure", "level"]).size()
    assert len(counts) == 8 and (counts == 3).all()


def test_same_different_in_sequence(stim, tmp_path):
    proto = write(stim, "sd", {"responses": [{"type": "classification", "name": "pair", "choices": [
        {"label": "same", "value": "same", "key": "s"}, {"label": "different", "value": "different", "key": "d"}]}]},
        psy={"task": "same_different", "presentation": "sequence", "isi_s": 0.2, "conditions": [],
             "procedure": {"method": "psi", "max_trials": 30}})
    beh = session(proto, tmp_path / "o", model(tmp_path, false_alarm=0.1))
    same = beh[beh["pair_type"] == "same"]
    assert 0 < len(same) < len(beh) and (same["difference"] == 0).all() and (same["level"] == 0).all()
    assert (beh["correct"] == (beh["response_pair"] == beh["pair_type"]).astype(int)).all()
    assert set(beh["reference_side"]) == {"first", "second"}
    assert (beh["second_onset_s"] > beh["onset_s"]).all()
    state = json.loads(beh.iloc[-1]["procedure_state"])
    assert len(state["history"]) == 30 == (beh["pair_type"] == "different").sum()  # 'same' pairs do not move it
    assert state["guess"] == 0.0


def test_shipped_protocol_runs_on_a_dense_drawn_continuum(tmp_path):
    """The shipped realism 2AFC protocol, on a drawn 21-level continuum with its factors."""
    proto = protocols_dir() / "realism_2afc.yaml"
    load_study_file(proto, Protocol)
    shapes = [round(float(x), 3) for x in np.linspace(0, 1, 21)]
    manifest = draw_face_grid(tmp_path / "stim", {"character": ["lps"], "shape": shapes, "material": ["m"],
                                                  "expression": ["neutral", "happiness", "anger"]}, size=(120, 90))
    res = run_session(proto, "01", out=tmp_path / "o", stimuli=manifest, simulate="default", window=False,
                      report=False)
    beh = pd.read_csv(res.beh, sep="\t", keep_default_na=False, na_values=["n/a"])
    assert res.status == "complete" and len(beh) == 4 + 3 * 60
    assert beh[beh["phase"] == "main"].groupby("expression").size().tolist() == [60, 60, 60]


@pytest.mark.parametrize("psy, changes, message", [
    ({"reference": 1.5}, None, "psychophysics.reference: 1.5 is outside the continuum [0, 1]"),
    ({"reference": 0.05}, None, "psychophysics.reference: 0.05 is not one of the continuum's 11 levels"),
    ({"levels": [0.2, 0.33]}, None, "psychophysics.levels: 0.33 is not one of the continuum's 11 levels"),
    ({"reference": 0.5}, None, "comparison levels lie on both sides of the reference 0.5"),
    ({}, {"stimuli": {"manifest": "stim/partial.csv", "factors": ["character", "shape", "emotion"]}},
     "psychophysics: no image for emotion=anger, character=c1, shape=0.3;"),
    ({"items": ["character"], "conditions": []}, None, "psychophysics: two images for the same condition, item and "
                                                       "level"),
    ({}, {"stimuli": {"manifest": "stim/manifest.csv", "factors": ["character", "emotion", "shape"]},
          "psychophysics": {"continuum": "character", "reference": 0, "procedure": {"method": "psi", "max_trials": 4}}},
     "psychophysics.continuum: factor 'character' has the level 'c1', expected numbers"),
])
def test_bad_levels_and_images_are_one_line_errors_before_any_output(stim, tmp_path, psy, changes, message, capsys):
    proto = write(stim, "bad", changes, psy)
    out = tmp_path / "o"
    assert main(["run", str(proto), "--participant", "01", "--simulate", "default", "--no-window",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and str(proto) in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("psy, changes, message", [
    ({"procedure": {"method": "psi"}}, None,
     "psychophysics.procedure: method 'psi' needs a stopping rule: max_trials or max_ci_width"),
    ({"procedure": {"method": "staircase", "trials_per_level": 4}}, None, "psychophysics.procedure:"),
    ({"procedure": {"method": "constant", "trials_per_level": 4, "down": 3}}, None,
     "down: not used by method 'constant'"),
    ({}, {"responses": [{"type": "likert", "name": "r", "low": "a", "high": "b"}]},
     "expected exactly one classification response answering the pair with the choice values left and right"),
    ({"presentation": "sequence"}, None, "psychophysics (2afc, sequence) expects the values first and second"),
    ({"continuum": "size"}, None, "psychophysics: unknown factor 'size'"),
    ({"conditions": ["shape"]}, None, "shape: a factor may be the continuum, a condition"),
    ({}, {"practice": {"files": ["x.png"]}}, "practice: not used with psychophysics"),
])
def test_bad_protocols_are_refused_by_validate(stim, psy, changes, message, capsys):
    proto = write(stim, "invalid", changes, psy)
    assert main(["validate", str(proto)]) != 0
    out = capsys.readouterr()
    assert message in out.err + out.out


def test_web_export_refuses_psychophysics(stim, tmp_path, capsys):
    proto = write(stim, "web")
    assert main(["export", "web", str(proto), "--out", str(tmp_path / "site")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "psychophysics: each next pair depends on the answers so far" in err[0]
    assert not (tmp_path / "site").exists()


def test_validate_checks_the_levels_against_the_stimuli(stim, capsys):
    """``appeal validate`` finds what a session would refuse, before anyone sits down."""
    good = write(stim, "valid")
    assert main(["validate", str(good)]) == 0
    bad = write(stim, "badref", psy={"reference": 0.05})
    assert main(["validate", str(bad)]) != 0
    out = capsys.readouterr()
    assert "psychophysics.reference: 0.05 is not one of the continuum's 11 levels" in out.err + out.out


def test_a_morph_between_two_photographs_is_a_continuum_too(shared_data, tmp_path):
    """A 2-D morph (``appeal faces continuum``: its manifest's ``weight`` 0..1) addressed by value: 2AFC
    between photograph A and the morph towards photograph B, by constant stimuli."""
    folder = shared_data / "faces2d" / "london-frl" / "neutral_front"
    a, b = sorted(folder.glob("*.jpg"))[:2]
    morphs = tmp_path / "morph"
    assert main(["faces", "continuum", str(a), str(b), "--steps", "6", "--size", "300x300",
                 "--out", str(morphs)]) == 0
    data = copy.deepcopy(PROTOCOL)
    data["stimuli"] = {"manifest": str(morphs / "manifest.csv"), "factors": ["weight"]}
    data["psychophysics"] = {"continuum": "weight", "reference": 0.0,
                             "procedure": {"method": "constant", "trials_per_level": 2}}
    proto = tmp_path / "morph.yaml"
    proto.write_text(yaml.safe_dump(data))
    beh = session(proto, tmp_path / "o")
    assert sorted(beh["level"].unique()) == [0.2, 0.4, 0.6, 0.8, 1.0] and len(beh) == 10
    assert (beh["reference_stimulus"] == pd.read_csv(morphs / "manifest.csv")["file"].iloc[0]).all()
