"""Protocol -> trial list (pure, no window): ordering constraints, jitter, triggers, anchors, breaks."""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy import stats

from appeal.assets import protocols_dir
from appeal.errors import AppealInputError
from experiments import (build_trials, check_order, constrained_order, fixation_frame_range, load_protocol,
                         load_stimuli, run_lengths, seconds_to_frames, select_stimuli)
from experiments.drawn_faces import draw_face_grid
from experiments.protocol_schema import Selection

ERP_FACTORS = {"character": ["james", "lps"], "stylisation": list(range(6)), "emotion": ["angry", "happy", "neutral"]}
GRID2 = {"character": ["c1", "c2"], "shape": [0, 1, 2], "material": [0, 1, 2],
         "expression": ["neutral", "anger", "happiness", "sadness", "surprise"]}


@pytest.fixture(scope="module")
def erp_manifest(tmp_path_factory):
    return draw_face_grid(tmp_path_factory.mktemp("erp"), ERP_FACTORS, size=(64, 48))


@pytest.fixture(scope="module")
def grid2_manifest(tmp_path_factory):
    return draw_face_grid(tmp_path_factory.mktemp("g2"), GRID2, size=(64, 48))


def _erp(erp_manifest, seed=0, hz=60.0):
    proto = load_protocol(protocols_dir() / "erp_stylisation.yaml")
    stim = load_stimuli(proto.stimuli, override=erp_manifest)
    return proto, build_trials(proto, stim, seed=seed, refresh_hz=hz)


def test_erp_540_trials_no_immediate_repeat(erp_manifest):
    proto, trials = _erp(erp_manifest)
    assert len(trials) == 2 * 6 * 3 * 15 == 540
    seq = [t.stimulus for t in trials]
    assert all(a != b for a, b in zip(seq, seq[1:]))
    assert set(pd.Series(seq).value_counts()) == {15}
    assert [t.trial for t in trials] == list(range(1, 541))
    assert all(t.stimulus_frames == 36 for t in trials)  # 600 ms at 60 Hz


def test_erp_fixation_uniform_400_500ms(erp_manifest):
    for hz in (60.0, 100.0, 144.0):
        _, trials = _erp(erp_manifest, seed=3, hz=hz)
        ms = np.array([t.fixation_frames for t in trials]) / hz * 1000
        assert ms.min() >= 400 - 1e-9 and ms.max() <= 500 + 1e-9
        lo, hi = fixation_frame_range(0.4, 0.5, hz)
        counts = np.bincount([t.fixation_frames - lo for t in trials], minlength=hi - lo + 1)
        assert len(counts) == hi - lo + 1 and counts.min() > 0  # every frame count in the range occurs
        # chi-square against the discrete uniform: not rejected at 0.1 %
        assert stats.chisquare(counts).pvalue > 0.001
    assert fixation_frame_range(0.4, 0.5, 60) == (24, 30)


def test_erp_one_trigger_per_onset_and_codes_match_conditions(erp_manifest):
    proto, trials = _erp(erp_manifest)
    table = {(c["character"], str(c["stylisation"]), c["emotion"]): c["code"] for c in proto.triggers.codes}
    for t in trials:
        assert t.trigger == table[(t.factors["character"], t.factors["stylisation"], t.factors["emotion"])]
    assert pd.Series([t.trigger for t in trials]).value_counts().eq(15).all()


def test_trigger_coverage_error(erp_manifest, tmp_path):
    proto = load_protocol(protocols_dir() / "erp_stylisation.yaml")
    proto = proto.model_copy(deep=True)
    proto.triggers.codes = proto.triggers.codes[1:]  # drop james/0/angry
    stim = load_stimuli(proto.stimuli, override=erp_manifest)
    with pytest.raises(AppealInputError) as exc:
        build_trials(proto, stim, seed=0, refresh_hz=60, source="erp.yaml")
    assert exc.value.lines == ["erp.yaml: triggers.codes: no code for condition character=james, stylisation=0, "
                               "emotion=angry (stimulus character-james_stylisation-0_emotion-angry.png)"]


def test_same_seed_same_order_other_seed_other_order(erp_manifest):
    a = [t.stimulus for t in _erp(erp_manifest, seed=5)[1]]
    b = [t.stimulus for t in _erp(erp_manifest, seed=5)[1]]
    c = [t.stimulus for t in _erp(erp_manifest, seed=6)[1]]
    assert a == b and a != c


def test_constrained_order_exact():
    rng = np.random.default_rng(0)
    attrs = {s: {"e": s[0]} for s in ["a1", "a2", "b1", "b2"]}
    items = ["a1", "a2", "b1", "b2"] * 6
    seq = constrained_order(items, attrs, rng, no_repeat=True, max_run={"e": 1})
    assert sorted(seq) == sorted(items)
    assert check_order(seq, attrs, no_repeat=True, max_run={"e": 1}) == []
    assert max(run_lengths([s[0] for s in seq])) == 1
    assert run_lengths(["a", "a", "b", "a"]) == [2, 1, 1]
    assert check_order(["a1", "a1"], attrs, no_repeat=True) == ["positions 0,1: 'a1' twice in a row"]
    with pytest.raises(AppealInputError, match="cannot be met: 'a1' is 3 of 4"):
        constrained_order(["a1", "a1", "a1", "b1"], attrs, rng, no_repeat=True)


def test_unconstrained_order_is_a_uniform_permutation():
    """Position of item 'x' among 4 over many seeds: uniform (chi-square)."""
    pos = [constrained_order(["x", "y", "z", "w"], {}, np.random.default_rng(s)).index("x") for s in range(400)]
    assert stats.chisquare(np.bincount(pos, minlength=4)).pvalue > 0.001


def test_constrained_order_keeps_positions_balanced():
    """With no-repeat, each stimulus is still equally likely at the first position."""
    attrs = {}
    first = [constrained_order(list("abcd") * 5, attrs, np.random.default_rng(s), no_repeat=True)[0]
             for s in range(400)]
    assert stats.chisquare(pd.Series(first).value_counts().to_numpy()).pvalue > 0.001


def test_seconds_to_frames():
    assert seconds_to_frames(0.6, 60) == 36
    assert seconds_to_frames(4.0, 144) == 576
    assert seconds_to_frames(0.001, 60) == 1
    with pytest.raises(AppealInputError, match=r"holds no whole frame at 60 Hz"):
        fixation_frame_range(0.401, 0.41, 60)


def _proto(tmp_path, manifest, **changes):
    data = yaml.safe_load((protocols_dir() / "exp2_stylisation.yaml").read_text())
    data["stimuli"]["manifest"] = str(manifest)
    data["stimuli"].pop("grid")
    data["stimuli"].pop("levels")  # the drawn faces have numeric levels
    for k, v in changes.items():
        data[k] = v
    f = tmp_path / "p.yaml"
    f.write_text(yaml.safe_dump(data))
    return load_protocol(f)


def test_exp2_anchors_first_photos_last(tmp_path, grid2_manifest):
    # add photographs of the two actors to the table (shape/material 'photograph')
    df = pd.read_csv(grid2_manifest)
    photos = pd.DataFrame([{"file": df["file"][0], "character": c, "shape": "photograph", "material": "photograph",
                            "expression": "neutral"} for c in ("c1", "c2")])
    photos["file"] = ["photo_c1.png", "photo_c2.png"]
    for f in photos["file"]:
        (grid2_manifest.parent / f).write_bytes((grid2_manifest.parent / df["file"][0]).read_bytes())
    table = grid2_manifest.parent / "with_photos.csv"
    pd.concat([df, photos]).to_csv(table, index=False)
    proto = _proto(tmp_path, table)
    full = load_stimuli(proto.stimuli, override=table, apply_select=False)
    main = select_stimuli(full, proto.stimuli.select)
    trials = build_trials(proto, main, seed=1, refresh_hz=60, full_set=full)
    phases = [t.phase for t in trials]
    assert phases == ["anchor"] * 6 + ["main"] * 90 + ["end"] * 2
    anchors = trials[:6]
    assert all(t.factors["shape"] == t.factors["material"] and t.factors["expression"] == "neutral" for t in anchors)
    assert not any(t.respond for t in anchors) and all(t.respond for t in trials[6:])
    assert {t.stimulus for t in trials[-2:]} == {"photo_c1.png", "photo_c2.png"}
    assert all(t.factors["shape"] != "photograph" for t in trials[6:96])
    assert all(t.stimulus_frames == 240 for t in trials)  # 4 s at 60 Hz
    # breaks every 84 main trials
    assert [t.trial for t in trials if t.break_before] == [6 + 85]


def test_end_items_skipped_when_absent(tmp_path, grid2_manifest):
    proto = _proto(tmp_path, grid2_manifest)
    stim = load_stimuli(proto.stimuli, override=grid2_manifest)
    trials = build_trials(proto, stim, seed=1, refresh_hz=60)
    assert trials[-1].phase == "main" and len(trials) == 96


def test_blocked_and_per_repetition_orders(tmp_path, grid2_manifest):
    proto = _proto(tmp_path, grid2_manifest, anchors=None, breaks=None,
                   order={"order": "blocked", "block_by": ["character"], "repetitions": 2,
                          "shuffle": "per_repetition", "max_run": {"expression": 2}})
    stim = load_stimuli(proto.stimuli, override=grid2_manifest)
    trials = build_trials(proto, stim, seed=4, refresh_hz=60)
    assert len(trials) == 180
    blocks = [t.block for t in trials]
    assert run_lengths(blocks) == [90, 90]  # one block per character
    assert all(t.factors["character"] == t.block for t in trials)
    for b in set(blocks):
        reps = [t.repetition for t in trials if t.block == b]
        assert reps == [1] * 45 + [2] * 45  # each pass complete before the next
    assert max(run_lengths([t.factors["expression"] for t in trials])) <= 2


def test_exp1c_three_passes_in_different_orders(tmp_path, grid2_manifest):
    proto = load_protocol(protocols_dir() / "exp1c_texture.yaml")
    stim = load_stimuli(proto.stimuli, override=grid2_manifest)
    assert set(stim.table["expression"]) == {"neutral"}
    trials = build_trials(proto, stim, seed=2, refresh_hz=60)
    n = len(stim)
    passes = [[t.stimulus for t in trials[i * n:(i + 1) * n]] for i in range(3)]
    assert all(sorted(p) == sorted(passes[0]) for p in passes)
    assert passes[0] != passes[1] != passes[2]
    assert [t.repetition for t in trials] == [1] * n + [2] * n + [3] * n


def test_selection_match_by_declared_level_order(grid2_manifest, tmp_path):
    """The grid's own level names: shape 1.0 ~ paint4 (most stylised), 0.0 ~ original (realistic)."""
    df = pd.read_csv(grid2_manifest)
    df["shape"] = df["shape"].map({0: "1.0", 1: "0.5", 2: "0.0"})
    df["material"] = df["material"].map({0: "paint4", 1: "paint2", 2: "original"})
    named = grid2_manifest.parent / "named.csv"
    df.to_csv(named, index=False)
    proto = load_protocol(protocols_dir() / "exp2_stylisation.yaml")
    full = load_stimuli(proto.stimuli, override=named, apply_select=False)
    anchors = select_stimuli(full, proto.anchors.select).table
    assert sorted(set(zip(anchors["shape"], anchors["material"]))) == [("0", "original"), ("0.5", "paint2"), ("1", "paint4")]
    assert full.levels("shape") == ["1", "0.5", "0"] and full.levels("material") == ["paint4", "paint2", "original"]


def test_selection_match_uses_level_numbers():
    import experiments.stimuli as st

    df = pd.DataFrame({"stimulus": ["a", "b", "c"], "path": ["a", "b", "c"], "shape": ["s0", "s1", "s2"],
                       "material": ["m0", "m2", "m2"]})
    sset = st.StimulusSet(df, ["shape", "material"], __import__("pathlib").Path("x"))
    assert list(select_stimuli(sset, Selection(match=["shape", "material"])).table["stimulus"]) == ["a", "c"]
    assert list(select_stimuli(sset, Selection(exclude={"material": "m2"})).table["stimulus"]) == ["a"]


def test_folder_plus_factor_table_real_photos(shared_data, tmp_path):
    """Any folder of images + a factor table: the London Face Research Lab photos (real files)."""
    folder = shared_data / "faces2d" / "london-frl"
    info = pd.read_csv(folder / "london_info.csv")
    files = sorted(p.name for p in (folder / "neutral_front").glob("*.jpg"))[:6]
    table = pd.DataFrame({"file": [f"neutral_front/{f}" for f in files], "expression": "neutral",
                          "identity": [f.split("_")[0] for f in files]})
    (tmp_path / "factors.csv").write_text(table.to_csv(index=False))
    data = {"kind": "protocol", "name": "frl", "task": "frl",
            "stimuli": {"folder": str(folder), "table": str(tmp_path / "factors.csv"), "factors": ["identity", "expression"]},
            "timing": {"stimulus_s": 1.0}, "order": {"repetitions": 2, "no_immediate_repeat": True},
            "responses": [{"type": "likert", "name": "appeal", "low": "a", "high": "b"}]}
    f = tmp_path / "frl.yaml"
    f.write_text(yaml.safe_dump(data))
    proto = load_protocol(f)
    stim = load_stimuli(proto.stimuli, protocol_file=f)
    assert len(stim) == 6 and all(p.endswith(".jpg") for p in stim.table["path"])
    trials = build_trials(proto, stim, seed=0, refresh_hz=60)
    assert len(trials) == 12 and check_order([t.stimulus for t in trials], {}, no_repeat=True) == []
    assert len(info) >= 6


@pytest.mark.parametrize("edit,expected", [
    (lambda df: df.drop(columns=["emotion"]), "emotion: factor column(s) missing"),
    (lambda df: df.drop(columns=["file"]), "file: column missing"),
    (lambda df: df.assign(file=["nope.png"] + list(df["file"][1:])), "file: 1 image(s) not found"),
    (lambda df: df.iloc[:0], "no rows"),
    (lambda df: pd.concat([df, df.iloc[:1]]), "file: listed twice"),
])
def test_bad_stimulus_tables(erp_manifest, tmp_path, edit, expected):
    proto = load_protocol(protocols_dir() / "erp_stylisation.yaml")
    df = pd.read_csv(erp_manifest)
    bad = erp_manifest.parent / "bad.csv"
    edit(df).to_csv(bad, index=False)
    with pytest.raises(AppealInputError) as exc:
        load_stimuli(proto.stimuli, override=bad)
    assert len(exc.value.lines) == 1 and exc.value.lines[0].startswith(f"{bad}: ")
    assert expected in exc.value.lines[0]


def test_missing_manifest_hints_at_grid_command():
    proto = load_protocol(protocols_dir() / "erp_stylisation.yaml")
    if proto.stimuli.manifest.is_file():
        pytest.skip("the ERP stimuli have been rendered in this checkout")
    with pytest.raises(AppealInputError) as exc:
        load_stimuli(proto.stimuli, protocol_file="erp_stylisation.yaml")
    assert "stimuli.manifest: file not found" in exc.value.lines[0]
    assert "appeal stimuli grid" in exc.value.lines[0] and "grids/erp_stylisation.yaml" in exc.value.lines[0]
