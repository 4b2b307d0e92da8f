"""Reverse correlation of facial expressions (issue 53): the grammar, simulated participants with known
AU models, and the analysis that must recover them."""

from __future__ import annotations

import doctest

import numpy as np
import pandas as pd
import pytest

from analysis.revcorr import models as M
from analysis.revcorr.planning import expected_models, map_correlation, recovery_table, simulate_participant
from appeal.errors import AppealInputError
from appeal.revcorr import grammar as G
from appeal.revcorr.observers import PROTOTYPES, TemplateObserver


def test_doctests():
    for module in (G, M):
        assert doctest.testmod(module).failed == 0


def test_trials_move_one_to_six_aus_median_three_and_repeat_from_their_seed():
    trials = G.draw_trials(11, 3000)
    counts = np.array([len(t.motions) for t in trials])
    assert counts.min() == 1 and counts.max() == 6 and np.median(counts) == 3
    assert all(len(set(t.aus)) == len(t.aus) and set(t.aus) <= set(G.ACTION_UNITS) for t in trials)
    assert G.draw_trial(11, 17) == trials[17] and G.draw_trial(12, 17) != trials[17]
    presence = G.presence_matrix(trials)
    assert presence.sum(axis=1).tolist() == counts.tolist()
    assert np.all(np.abs(presence.mean(axis=0) - counts.mean() / len(G.ACTION_UNITS)) < 0.03)  # AUs equally likely
    for t in trials[:200]:
        for m in t.motions:
            lo = {k: v[0] for k, v in G.PARAMETER_RANGES.items()}
            hi = {k: v[1] for k, v in G.PARAMETER_RANGES.items()}
            assert all(lo[k] <= getattr(m, k) <= hi[k] for k in G.PARAMETER_RANGES)


def test_lateralised_aus_draw_each_side():
    aus = G.action_units(lateralised=True)
    assert len(aus) == 2 * len(G.BILATERAL) + 1 and "AU26" in aus and "AU12_L" in aus and "AU12" not in aus
    assert set(G.draw_trial(3, 0, aus=aus).aus) <= set(aus)


def test_time_courses_rise_to_the_peak_and_fall_back():
    t = np.linspace(0, 1, 301)
    for trial in G.draw_trials(5, 100):
        for m in trial.motions:
            c = G.au_curve(m, t)
            assert np.all(c[t <= m.onset] == 0) and np.all(c[t >= m.offset] == 0)
            assert c.max() == pytest.approx(m.peak_amplitude, abs=0.02)
            rise, fall = c[(t > m.onset) & (t <= m.peak_latency)], c[(t >= m.peak_latency) & (t < m.offset)]
            assert np.all(np.diff(rise) >= -1e-12) and np.all(np.diff(fall) <= 1e-12)
    m = G.AuMotion("AU12", 0.0, 0.0, 0.5, 1.0, 0.0, 1.0)  # at rest at both ends: a smoothstep each way
    assert G.au_curve(m, np.array([0.25]))[0] == pytest.approx(0.5)
    frames = G.trial_curves(G.draw_trial(1, 0), 38)
    assert all(len(v) == 38 for v in frames.values())


@pytest.mark.parametrize("ranges, match", [({"onset": (0.5, 0.2)}, "low <= high"), ({"speed": (0, 1)}, "unknown"),
                                           ({"onset": (0.0, 0.5)}, "onset <= peak_latency"), ({"offset": 3}, "expected")])
def test_bad_ranges_are_one_line_errors(ranges, match):
    with pytest.raises(AppealInputError, match=match) as err:
        G.draw_trial(1, 0, ranges=ranges)
    assert "\n" not in str(err.value)


def test_mutual_information_agrees_with_scikit_learn():
    from sklearn.metrics import mutual_info_score

    rng = np.random.default_rng(0)
    x = (rng.random((500, 4)) < 0.3).astype(float)
    y = np.stack([x[:, 0] * (rng.random(500) < 0.8), rng.random(500) < 0.5], axis=1).astype(float)
    mi = M.mutual_information(x, y)
    for j in range(4):
        for e in range(2):
            assert mi[j, e] == pytest.approx(mutual_info_score(x[:, j], y[:, e]) / np.log(2), abs=1e-12)


def test_participants_answering_at_random_have_models_no_more_often_than_alpha():
    """Family-wise over the AUs: with random answers an emotion's model holds any AU in at most
    alpha = 5 % of the emotions (10 participants x 6 emotions; <= 7 of 60 has p > 0.99 under 5 %)."""
    n_any = 0
    for seed in range(10):
        obs = TemplateObserver(lapse=1.0, seed=seed)
        s = simulate_participant(obs, 1200, seed=100 + seed)
        models = M.au_models(s.presence, s.answers, obs.aus, obs.emotions, n_permutations=300, seed=seed)
        n_any += int(models.groupby("emotion")["in_model"].any().sum())
        assert models["p"].between(1 / 301, 1).all()
    assert n_any <= 7, n_any


def test_simulated_participants_models_are_recovered_and_fewer_trials_recover_less():
    """Known templates (EMFACS prototypes) recovered from 2,400 trials: at least 90 % of the template
    AUs, at most one false AU per emotion, MI maps correlated >= 0.9 with the observer's long-run
    map; 300 trials recover less."""
    table = recovery_table(TemplateObserver(), (300, 2400), n_participants=3, n_permutations=500).set_index("n_trials")
    full, few = table.loc[2400], table.loc[300]
    assert full["hit_rate"] >= 0.9 and full["false_aus"] <= 1.0 and full["worst_map_corr"] >= 0.9, table
    assert few["hit_rate"] < full["hit_rate"] and few["map_corr"] < full["map_corr"], table


def test_the_logistic_image_ranks_the_template_aus_first():
    obs = TemplateObserver(seed=8)
    s = simulate_participant(obs, 2400, seed=9)
    image = M.logistic_image(s.presence, s.answers, obs.aus, obs.emotions)
    for emotion in ("happy", "disgust"):
        top = image[image["emotion"] == emotion].nlargest(len(PROTOTYPES[emotion]), "z")["au"]
        assert set(top) == set(PROTOTYPES[emotion])
    expected = expected_models(obs, n_trials=20000)
    models = M.au_models(s.presence, s.answers, obs.aus, obs.emotions, n_permutations=200)
    assert map_correlation(models, expected) > 0.9


def test_bad_observer_templates_are_one_line_errors():
    with pytest.raises(AppealInputError, match="AU99"):
        TemplateObserver(templates={"happy": ["AU99"]})
    with pytest.raises(AppealInputError, match="answers"):
        M.mi_permutation_test(np.zeros((10, 3)), np.zeros((9, 2)))


def test_every_grammar_au_poses_the_rig_through_its_own_blendshapes(shared_data):
    """The grammar's AUs are the recipe file's, no two move the same blendshape, a lateralised AU moves
    one side, and a trial's frames are weights the ICT rig has (the clip path's input)."""
    from stimulus_engine.characters import au_poses
    from stimulus_engine.characters.expressions import facs_recipes
    from stimulus_engine.characters.ict import load_ict_rig

    assert doctest.testmod(au_poses).failed == 0
    shapes = [au_poses.au_blendshapes(au) for au in G.ACTION_UNITS]
    assert set(G.ACTION_UNITS) <= set(facs_recipes()["action_units"])
    assert len({s for group in shapes for s in group}) == sum(len(g) for g in shapes)
    assert all(len(au_poses.au_blendshapes(au)) == 1 for au in G.action_units(lateralised=True) if "_" in au)
    rig = load_ict_rig(shared_data / "meshes" / "ict-facekit", "identity000", textures=False)
    trial = G.draw_trial(2, 5)
    n = au_poses.clip_frames(1.25, 30)
    frames = au_poses.trial_frame_weights(trial, n)
    assert n == 39 and len(frames) == 39 and all(set(f) <= set(rig.blendshapes) for f in frames)
    k, apex = au_poses.apex_weights(trial, n)
    assert 0 < k < 38 and max(apex.values()) > 0.1
    assert all(v == 0 for v in frames[0].values()) and all(v == 0 for v in frames[-1].values())
    with pytest.raises(AppealInputError, match="AU26_L"):
        au_poses.au_blendshapes("AU26_L")


# ------------------------------------------------------------------------------ appeal analyze revcorr
def _two_level_trials(n_trials: int = 2400) -> pd.DataFrame:
    """Two simulated participants; at the stylised level their happy has the jaw (AU26) too and their
    surprise lost it: the analysis must find the change."""
    from analysis.revcorr.trials import simulated_table

    styl = dict(PROTOTYPES, happy=("AU6", "AU12", "AU26"), surprise=("AU1", "AU2", "AU5"))
    real = {f"P{i}": TemplateObserver(seed=i) for i in range(2)}
    stylised = {f"P{i}": TemplateObserver(templates=styl, seed=10 + i) for i in range(2)}
    return simulated_table(real, n_trials, seed=3, levels={"realistic": real, "stylised": stylised})


def test_cli_finds_each_participants_models_per_level_from_bids_files(tmp_path):
    from appeal_cli import main

    table = _two_level_trials().rename(columns={"level": "shape"})
    for pid, sub in table.groupby("participant_id"):  # the runner's layout: one file per session, n/a for none
        folder = tmp_path / "data" / f"sub-{pid}" / "ses-1" / "beh"
        folder.mkdir(parents=True)
        sub = sub.drop(columns="participant_id").astype(object)
        sub.loc[sub.index[:5], "response"] = "n/a"
        sub.to_csv(folder / f"sub-{pid}_ses-1_task-revcorr_beh.tsv", sep="\t", index=False, na_rep="n/a")
    out = tmp_path / "out"
    assert main(["analyze", "revcorr", str(tmp_path / "data" / "sub-*" / "ses-*" / "beh" / "*_beh.tsv"),
                 "--level", "shape", "--permutations", "300", "--out", str(out)]) == 0
    models = pd.read_csv(out / "models.csv", dtype={"participant_id": str})
    assert len(models) == 2 * 2 * 6 * 16 and set(models["n_trials"]) == {2395, 2400}  # 5 unanswered, realistic

    def model(shape, emotion):
        sub = models[(models["shape"] == shape) & (models["emotion"] == emotion) & models["in_model"]]
        return {pid: set(g["au"]) for pid, g in sub.groupby("participant_id")}

    for pid in ("P0", "P1"):
        assert "AU26" in model("stylised", "happy")[pid] and "AU26" not in model("realistic", "happy")[pid]
        assert "AU26" in model("realistic", "surprise")[pid] and "AU26" not in model("stylised", "surprise")[pid]
        assert {"AU6", "AU12"} <= model("realistic", "happy")[pid]
    temporal = pd.read_csv(out / "temporal.csv", dtype={"participant_id": str})
    smile = temporal[(temporal["emotion"] == "happy") & (temporal["au"] == "AU12")]
    assert len(smile) == 4 and (smile["intensity_rho"] > 0.2).all()  # stronger smiles, stronger happiness
    assert (smile["peak_amplitude"] > smile["peak_amplitude_all"]).all()  # happy answers follow larger smiles
    consensus = pd.read_csv(out / "consensus.csv")
    row = consensus[(consensus["shape"] == "stylised") & (consensus["emotion"] == "happy") & (consensus["au"] == "AU26")]
    assert row["share"].item() == 1.0
    agreement = pd.read_csv(out / "agreement.csv")
    assert set(agreement.columns) >= {"shape", "emotion", "participants", "mean_hamming"} and len(agreement) == 12
    assert len(list((out / "figures").glob("sub-*_models.png"))) == 4 and (out / "consensus_shape-stylised.png").is_file()
    assert "happy (shape stylised): AUs in at least half of the models: AU6, AU12, AU26" in (out / "report.md").read_text()
    changes = pd.read_csv(out / "level_agreement.csv", dtype={"participant_id": str}).fillna("")
    for pid in ("P0", "P1"):
        row = changes[(changes["participant_id"] == pid) & (changes["emotion"] == "happy")].iloc[0]
        assert (row["level_a"], row["level_b"], row["only_b"]) == ("realistic", "stylised", "AU26")
    effects = pd.read_csv(out / "level_effects.csv").set_index(["emotion", "au"])
    assert len(effects) == 6 * 16 and {"F", "p", "q", "mi_realistic", "share_stylised"} <= set(effects.columns)
    jaw = effects.loc[("happy", "AU26")]
    assert jaw["share_stylised"] == 1.0 and jaw["share_realistic"] == 0.0 and jaw["mi_stylised"] > jaw["mi_realistic"]


@pytest.mark.parametrize("change, message", [
    (lambda t: t.assign(response=t["response"].where(t.index != 7, "joy")), "row 8: response 'joy': expected one of"),
    (lambda t: t.drop(columns="revcorr_seed"), "no column 'revcorr_seed'"),
    (lambda t: t.assign(revcorr_trial=t["revcorr_trial"].where(t.index != 3, -1)), "revcorr_trial -1: expected a whole"),
    (lambda t: t.assign(intensity=t["intensity"].where(t.index != 0, 9)), "intensity 9"),
    (lambda t: t.assign(response="n/a"), "no answered trials"),
])
def test_cli_bad_trials_are_one_line_errors_and_write_nothing(tmp_path, capsys, change, message):
    from appeal_cli import main

    table = change(_two_level_trials(40).query("level == 'realistic'").reset_index(drop=True))
    table.to_csv(tmp_path / "trials.csv", index=False)
    out = tmp_path / "out"
    assert main(["analyze", "revcorr", str(tmp_path / "trials.csv"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and "trials.csv" in err[0], err
    assert not out.exists()


def test_a_trial_plays_as_a_clip_through_a_grids_performance(tmp_path):
    """A trial written as a performance plays in a grid (the procedural head, both shape levels): 39
    frames, the first and last the neutral still, the apex frame the trial's apex pose."""
    import json

    from PIL import Image

    from appeal.studyfile import load_study_file
    from grid_fixtures import TINY_GRID
    from stimulus_engine.characters.au_poses import write_trial_performance
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.animation import frame_file
    from stimulus_engine.grid.schema import GridFile

    trial = next(t for t in G.draw_trials(21, 50) if {"AU12", "AU26"} & set(t.aus))
    perf = write_trial_performance(trial, tmp_path / "trial_00000.csv", fps=30)
    meta = json.loads(perf.with_suffix(".json").read_text())
    assert meta["n_frames"] == 39 and [m["au"] for m in meta["motions"]] == list(trial.aus)
    # the grid's one expression names its cells (a recipe name, here neutral: the still); the clip plays the trial
    text = TINY_GRID.replace("name: still", "name: revcorr").replace("expressions: [neutral, happy]",
                                                                    "expressions: [neutral]")
    (tmp_path / "g.yaml").write_text(text + f"animation: {{fps: 30, performance: {perf}}}\n")
    manifest, _ = run_grid(load_study_file(tmp_path / "g.yaml", GridFile), tmp_path / "out", n_jobs=1)
    assert (manifest["status"] == "rendered").all() and (manifest["n_frames"] == 39).all()
    for r in manifest.itertuples():
        folder = tmp_path / "out" / r.frames
        first, last = (np.asarray(Image.open(folder / frame_file(k)).convert("RGB")) for k in (0, 38))
        apex = np.asarray(Image.open(folder / frame_file(meta["apex_frame"])).convert("RGB"))
        assert np.array_equal(first, last) and not np.array_equal(first, apex)
