"""Issue 53 part 2: a reverse-correlation pool rendered in one grid run (``animation.revcorr``), the
``revcorr:`` protocol over it in the real runner with simulated participants, and the analysis of
the data files it writes."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import yaml

from appeal.revcorr.grammar import draw_trial

POOL = """kind: grid
name: pool
characters:
  - name: a
    procedural: {seed: 3, texture_size: 128, resolution: 32}
shapes: [0.0, 1.0]
materials: [original]
expressions: [neutral]
lighting: [flat]
shading: [pbr]
render: {width: 96, height: 72}
animation: {fps: 30, occlusion: blend, revcorr: {seed: 7, trials: 6}}
"""


@pytest.fixture(scope="module")
def pool(tmp_path_factory):
    """Six trials on the procedural head at two shape levels: 12 clips of 39 frames."""
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile

    root = tmp_path_factory.mktemp("revcorr_pool")
    (root / "pool.yaml").write_text(POOL)
    manifest, _ = run_grid(load_study_file(root / "pool.yaml", GridFile), root / "out", n_jobs=1)
    return root / "out", manifest


def test_a_pool_plays_the_same_trials_on_every_level_and_stores_their_parameters(pool):
    from PIL import Image

    out, manifest = pool
    assert len(manifest) == 12 and (manifest["status"] == "rendered").all() and (manifest["n_frames"] == 39).all()
    for shape, level in manifest.groupby("shape"):
        assert level["revcorr_trial"].tolist() == list(range(6))
        assert level["revcorr_aus"].tolist() == [";".join(draw_trial(7, i).aus) for i in range(6)]
    params = pd.read_csv(out / "revcorr_trials.csv")
    first = params[params["revcorr_trial"] == 0]
    assert first["au"].tolist() == list(draw_trial(7, 0).aus)
    assert np.allclose(first["peak_amplitude"], [m.peak_amplitude for m in draw_trial(7, 0).motions])
    # clips start at rest: frame 0 of every clip of a cell is the same image, the apex is not
    for _, level in manifest.groupby("shape"):
        firsts = [np.asarray(Image.open(out / f / "frame_00000.png").convert("RGB")) for f in level["frames"]]
        assert all(np.array_equal(firsts[0], x) for x in firsts[1:])
        r = level.iloc[0]
        apex = np.asarray(Image.open(out / r["frames"] / f"frame_{int(r['apex_frame']):05d}.png").convert("RGB"))
        assert not np.array_equal(apex, firsts[0])


def test_a_pool_refuses_a_second_expression_and_a_performance(tmp_path):
    from appeal.errors import AppealInputError
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid.schema import GridFile

    (tmp_path / "g.yaml").write_text(POOL.replace("expressions: [neutral]", "expressions: [neutral, happy]"))
    with pytest.raises(AppealInputError, match="animation.revcorr"):
        load_study_file(tmp_path / "g.yaml", GridFile)


def test_blended_occlusion_is_the_baked_one_at_rest_and_at_the_apex():
    from stimulus_engine.grid.worker import blend_fraction

    rng = np.random.default_rng(1)
    v0 = rng.normal(size=(50, 3))
    apex = v0 + rng.normal(size=(50, 3))
    assert np.allclose(blend_fraction(v0, v0, apex), 0.0)
    assert np.allclose(blend_fraction(apex, v0, apex), 1.0)
    assert np.allclose(blend_fraction(v0 + 0.25 * (apex - v0), v0, apex), 0.25)


def _protocol(tmp_path, manifest_csv, **revcorr):
    from appeal.assets import protocols_dir

    data = yaml.safe_load((protocols_dir() / "revcorr_stylisation.yaml").read_text())
    data["stimuli"]["manifest"] = str(manifest_csv)
    data["stimuli"].pop("grid")
    data["revcorr"] = revcorr
    data["breaks"] = {"every": 5}
    path = tmp_path / "revcorr.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path, data


def test_the_shipped_protocol_records_the_pool_columns_and_refuses_other_answers(tmp_path):
    from appeal.errors import AppealInputError
    from appeal.studyfile import load_study_file
    from experiments.protocol_schema import REVCORR_COLUMNS, Protocol

    path, data = _protocol(tmp_path, tmp_path / "none.csv")
    proto = load_study_file(path, Protocol)
    assert proto.stimuli.factors == ["character", "shape", "material", *REVCORR_COLUMNS]
    data["responses"][0]["choices"] = data["responses"][0]["choices"][:-1]  # no "don't know"
    data["responses"][0]["skip_intensity_for"] = []
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(AppealInputError, match="revcorr expects the values"):
        load_study_file(path, Protocol)
    data = yaml.safe_load(path.read_text())
    data["responses"][0]["choices"].append({"label": "dk", "value": "dont_know", "key": "7"})
    data["responses"][0]["intensity"]["points"] = 7
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(AppealInputError, match="5-point intensity"):
        load_study_file(path, Protocol)


def test_simulated_sessions_answer_the_pool_and_the_analysis_reads_their_files(pool, tmp_path):
    """Two simulated participants in the real runner (no window): each sees 4 of the 6 pool trials
    at both levels (her own 4, the same at each), answers as the default model's template observer
    does, and ``analyze revcorr`` reads the data files the runner wrote."""
    from analysis.revcorr.study import analyze_revcorr
    from analysis.revcorr.trials import read_revcorr_trials
    from experiments import run_session

    out, _ = pool
    proto, _ = _protocol(tmp_path, out / "manifest.csv", trials=4)
    chosen = {}
    for pid in ("01", "02"):
        res = run_session(proto, pid, out=tmp_path / "data" / f"sub-{pid}" / "ses-1" / "beh", simulate="default",
                          window=False)
        beh = pd.read_csv(next((tmp_path / "data" / f"sub-{pid}" / "ses-1" / "beh").glob("*_beh.tsv")), sep="\t")
        main = beh[beh["phase"] == "main"]
        assert len(main) == 8 and set(main["revcorr_seed"]) == {7} and set(main["revcorr_lateralised"]) == {0}
        by_level = main.groupby("shape")["revcorr_trial"].apply(lambda s: sorted(s.tolist()))
        assert by_level.iloc[0] == by_level.iloc[1]  # the same trials at both levels
        chosen[pid] = by_level.iloc[0]
        assert set(main["response_emotion"]) <= {"happy", "surprise", "fear", "disgust", "anger", "sad", "dont_know"}
        known = main[main["response_emotion"] != "dont_know"]["response_intensity"]
        assert known.between(1, 5).all()
        assert (main["clip_frames"] == 39).all() and (main["clip_frame_errors"] == 0).all()
        assert res is not None
    assert chosen["01"] != chosen["02"]  # seeded per participant
    data = read_revcorr_trials(str(tmp_path / "data" / "sub-*" / "ses-*" / "beh" / "*_beh.tsv"), levels=["shape"])
    assert len(data.table) >= 12  # the answered trials (a lapse or a late answer may leave one out)
    res = analyze_revcorr(data, tmp_path / "analysis", n_permutations=19, alpha=0.06, seed=1)
    assert set(res.models["participant_id"].astype(str)) == {"01", "02"}
