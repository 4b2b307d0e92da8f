"""``appeal analyze psychometric``: per-participant and pooled fits of runner-style trial files,
the comparison of thresholds, figures, report and one-line errors (issue 34, the study level)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy import stats

from appeal.psychophysics import ConstantStimuli, PsiProcedure, SimulatedObserver
from cli_errors import one_line_error

ROOT = Path(__file__).resolve().parent.parent
#: The comparison faces' levels on the continuum; the reference (realistic) face is level 0.
LEVELS = np.round(np.linspace(0.05, 1.0, 20), 4)
#: True thresholds (psignifit's, = the difference at 75 % correct without lapses) per expression.
TRUE = {"happiness": 0.3, "anger": 0.6}
TASK = "realism2afc"


def _procedure(kind: str, n_trials: int, seed: int):
    if kind == "psi":
        return PsiProcedure(LEVELS, max_trials=n_trials)
    return ConstantStimuli(LEVELS, max(1, n_trials // len(LEVELS)), seed=seed)


def _track(emotion: str, observer: SimulatedObserver, kind: str, n_trials: int, seed: int) -> list[dict]:
    """One procedure run by a simulated observer, as the runner's main-trial rows."""
    proc, rows = _procedure(kind, n_trials, seed), []
    rng = np.random.default_rng(seed)
    while not proc.finished:
        level = proc.next_level()
        correct = observer.respond(level)
        proc.update(level, correct)
        est = proc.estimate()
        side = ["left", "right"][int(rng.integers(2))]
        rows.append({"phase": "main", "character": "james", "emotion": emotion, "shape": level,
                     "stimulus": f"james_{emotion}_{level:g}.png", "procedure": f"emotion-{emotion}",
                     "procedure_kind": proc.kind, "level": level, "reference_level": 0.0, "difference": level,
                     "pair_type": "different", "reference_side": side,
                     "response_choice": side if correct else {"left": "right", "right": "left"}[side],
                     "rt_choice": round(float(rng.uniform(0.4, 1.5)), 3), "correct": int(correct),
                     "estimate_threshold": est.get("threshold", np.nan),
                     "estimate_threshold_lo": est.get("threshold_lo", np.nan),
                     "estimate_threshold_hi": est.get("threshold_hi", np.nan),
                     "procedure_state": json.dumps(proc.to_dict()) if proc.finished else np.nan})
    return rows


def write_session(root: Path, sid: str, thresholds: dict[str, float], kind: str = "constant", n_trials: int = 100,
                  width: float = 0.3, seed: int = 0) -> Path:
    """A runner-style ``*_beh.tsv`` of one session: 3 practice trials, then one track per expression
    (a simulated observer per expression), one main trial left unanswered (``correct`` n/a), and two
    'same' pairs at the end."""
    rows = [{"phase": "practice", "emotion": "happiness", "difference": 5.0, "level": 5.0, "correct": 0}
            for _ in range(3)]
    for i, (emotion, m) in enumerate(thresholds.items()):
        obs = SimulatedObserver(m, width, 0.02, 0.5, seed=seed * 100 + i)
        rows += [dict(r, block=i + 1) for r in _track(emotion, obs, kind, n_trials, seed * 100 + i)]
    rows[5]["correct"] = np.nan  # no answer
    rows += [{"phase": "main", "emotion": "anger", "difference": 0.0, "level": 0.0, "pair_type": "same", "correct": 1}
             for _ in range(2)]  # a same-different task's 'same' pairs: not points of the function
    table = pd.DataFrame(rows).assign(participant_id=f"sub-{sid}", session=1, part=1)
    table.insert(0, "trial", np.arange(1, len(table) + 1))
    path = root / f"sub-{sid}" / "ses-1" / "beh" / f"sub-{sid}_ses-1_task-{TASK}_beh.tsv"
    path.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(path, sep="\t", index=False, na_rep="n/a")
    return path


def write_analysis(folder: Path, **fields) -> Path:
    """A ``kind: psychometric`` file in ``folder`` reading ``data/sub-*/...`` next to it."""
    doc = {"kind": "psychometric", "title": "Realism threshold (test)",
           "data": f"data/sub-*/ses-*/beh/*_task-{TASK}_beh.tsv", "conditions": ["emotion"],
           "fit": {"method": "ml"}, **fields}
    path = folder / "analysis.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> Path:
    """Five participants, two expressions, constant stimuli (200 trials per expression)."""
    folder = tmp_path_factory.mktemp("psychometric_study")
    for s in range(5):
        shift = 0.04 * (s - 2)
        write_session(folder / "data", f"{s + 1:02d}", {e: m + shift for e, m in TRUE.items()}, n_trials=200,
                      seed=s + 1)
    return folder


@pytest.fixture(scope="module")
def ml_run(study) -> Path:
    from appeal_cli import main

    out = study / "out_ml"
    cfg = write_analysis(study, compare=["emotion"], continuum={"reference": 0.0, "direction": 1})
    assert main(["analyze", "psychometric", str(cfg), "--out", str(out)]) == 0
    return out


def test_fits_recover_each_participants_thresholds(ml_run):
    fits = pd.read_csv(ml_run / "fits.csv")
    assert len(fits) == 10 and list(fits.columns[:2]) == ["participant_id", "emotion"]
    assert {"n_trials", "n_levels", "threshold", "threshold_lo", "width", "lambda", "gamma", "eta", "x_at_pc",
            "point", "point_lo", "point_hi", "log_likelihood", "deviance"} <= set(fits.columns)
    # practice rows and 'same' pairs are left out, the unanswered trial dropped: 200 trials per track, one unanswered
    assert sorted(fits["n_trials"].unique()) == [199, 200] and fits["n_levels"].max() == len(LEVELS)
    for (sid, emotion), row in fits.set_index(["participant_id", "emotion"]).iterrows():
        s = int(sid.removeprefix("sub-")) - 1
        assert row["x_at_pc"] == pytest.approx(TRUE[emotion] + 0.04 * (s - 2), abs=0.1), (sid, emotion)
    np.testing.assert_allclose(fits["point"], fits["threshold"])  # reference 0, direction 1
    assert (fits["gamma"] == 0.5).all() and (fits["deviance"] >= 0).all()


def test_pooled_fit_per_condition(ml_run):
    pooled = pd.read_csv(ml_run / "pooled.csv")
    assert list(pooled["emotion"]) == ["anger", "happiness"] and (pooled["n_participants"] == 5).all()
    assert (pooled["n_trials"] == 5 * 200 - 5 * pooled["emotion"].eq("happiness")).all()
    for _, row in pooled.iterrows():
        assert row["x_at_pc"] == pytest.approx(TRUE[row["emotion"]], abs=0.05)


def test_comparison_is_the_paired_t_test_for_two_levels(ml_run):
    fits = pd.read_csv(ml_run / "fits.csv").pivot(index="participant_id", columns="emotion", values="x_at_pc")
    anova = pd.read_csv(ml_run / "comparison_anova.csv")
    posthoc = pd.read_csv(ml_run / "comparison_posthoc.csv")
    t = stats.ttest_rel(fits["anger"], fits["happiness"])
    row = anova.set_index("effect").loc["emotion"]
    assert row["F"] == pytest.approx(t.statistic ** 2, rel=1e-9) and row["p"] == pytest.approx(t.pvalue, rel=1e-9)
    assert row["p"] < 0.05 and len(posthoc) == 1 and abs(posthoc.loc[0, "t"]) == pytest.approx(abs(t.statistic))


def test_figures_and_report(ml_run):
    from PIL import Image

    pngs = sorted((ml_run / "figures").glob("*.png"))
    assert [p.name for p in pngs] == [f"sub-{s:02d}_psychometric.png" for s in range(1, 6)]
    for p in [*pngs, ml_run / "group_thresholds.png"]:
        with Image.open(p) as im:
            assert im.size[0] > 400 and im.size[1] > 300
    md = (ml_run / "report.md").read_text()
    assert "## Comparison" in md and "figures/sub-01_psychometric.png" in md and "group_thresholds.png" in md
    html = (ml_run / "index.html").read_text()
    assert "fits.csv" in html and "comparison_anova.csv" in html and "<img" in html
    assert json.loads((ml_run / "provenance.json").read_text())["status"] == "ok"


def test_bayes_fit_on_a_psi_track_with_credible_intervals_and_continuum(tmp_path):
    """One participant, one psi track of 80 trials (no conditions): the Bayesian fit's interval covers
    the truth; the continuum runs downwards from a reference at 1.0."""
    from analysis.psychometric import PsychometricAnalysis, analyze_psychometric_study
    from appeal.studyfile import load_study_file

    write_session(tmp_path / "data", "01", {"happiness": 0.4}, kind="psi", n_trials=80, seed=3)
    cfg = load_study_file(write_analysis(
        tmp_path, conditions=[], continuum={"reference": 1.0, "direction": -1},
        fit={"method": "bayes", "grid": {"threshold": 20, "width": 20, "lambda": 8, "eta": 8}}), PsychometricAnalysis)
    out = tmp_path / "out"
    out.mkdir()
    res = analyze_psychometric_study(cfg, out)
    row = res.fits.iloc[0]
    assert row["n_trials"] == 79 and row["method"] == "bayes"
    assert row["threshold_lo"] < 0.4 < row["threshold_hi"] and row["threshold_lo"] < row["threshold"]
    assert row["point"] == pytest.approx(1 - row["threshold"])
    assert (row["point_lo"], row["point_hi"]) == pytest.approx((1 - row["threshold_hi"], 1 - row["threshold_lo"]))
    assert row["point_at_pc"] == pytest.approx(1 - row["x_at_pc"])
    assert res.anova is None and len(res.pooled) == 1 and (out / "figures" / "sub-01_psychometric.png").is_file()


def test_too_few_trials_can_be_skipped(tmp_path):
    from analysis.psychometric import PsychometricAnalysis, analyze_psychometric_study
    from appeal.studyfile import load_study_file

    write_session(tmp_path / "data", "01", TRUE, n_trials=60, seed=1)
    write_session(tmp_path / "data", "02", {"happiness": 0.3}, n_trials=20, seed=2)  # 19 answered: too few
    cfg = load_study_file(write_analysis(tmp_path, fit={"method": "ml", "too_few": "skip"}), PsychometricAnalysis)
    res = analyze_psychometric_study(cfg, tmp_path)
    assert len(res.fits) == 2 and res.skipped == [
        "participant sub-02, emotion=happiness: 19 answered trials over 19 levels of difference; a fit needs at least "
        "20 trials over 3 levels (fit.min_trials; fit.too_few: skip leaves it out)"]
    assert "Skipped (too few trials)" in (tmp_path / "report.md").read_text()


def test_validate_knows_the_kind(study, capsys):
    from appeal_cli import main

    assert main(["validate", str(ROOT / "protocols" / "analysis" / "realism_threshold.yaml")]) == 0
    bad = write_analysis(study, compare=["character"])
    one_line_error(capsys, ["validate", str(bad)], "compare: 'character' is not one of the conditions")


def test_help_teaches():
    from click.testing import CliRunner

    from appeal_cli import _load_commands, cli

    _load_commands()
    res = CliRunner().invoke(cli, ["analyze", "psychometric", "--help"])
    assert res.exit_code == 0 and "appeal analyze psychometric protocols/analysis/realism_threshold.yaml" in res.output
    assert "kind: psychometric" in res.output and "threshold_pc" in res.output


def test_one_line_errors(study, tmp_path, capsys):
    run = ["analyze", "psychometric"]
    # no data file matches
    empty = write_analysis(tmp_path)
    one_line_error(capsys, run + [str(empty), "--out", str(tmp_path / "o1")], "no file matches",
                   f"*_task-{TASK}_beh.tsv")
    # a column the data lack: the file, the role, the column and what was expected
    cfg = write_analysis(study, conditions=["expression"])
    one_line_error(capsys, run + [str(cfg), "--out", str(tmp_path / "o2")], "sub-01_ses-1_task-realism2afc_beh.tsv",
                   "conditions[0]: column 'expression' not found", "expected a condition")
    # too few trials: participant, condition and counts
    few = tmp_path / "few"
    write_session(few / "data", "07", {"anger": 0.5}, n_trials=20, seed=7)
    one_line_error(capsys, run + [str(write_analysis(few)), "--out", str(tmp_path / "o3")],
                   "participant sub-07, emotion=anger: 19 answered trials over 19 levels", "at least 20 trials")
    assert not (tmp_path / "o3").exists()  # checked before the output folder is made
    # an unknown family
    fam = write_analysis(study, fit={"family": "gumbel"})
    one_line_error(capsys, run + [str(fam), "--out", str(tmp_path / "o4")], "fit.family", "'logistic'", "gumbel")
