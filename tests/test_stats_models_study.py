"""``model: anova | mixed | ordinal | both | all`` in a rating study file: the report's mixed-model
and ordinal sections are the library's fits of the trial rows (which the R tests pin down), and
bad model settings are one-line errors before anything is written."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from appeal_cli import main

DATA = Path(__file__).parent / "data" / "clmm_crossed.csv"  # participants x faces, shape x material, 7-point


def _study(tmp_path: Path, **extra) -> Path:
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump({"kind": "ratings", "title": "models", "data": str(DATA), "subject": "participant",
                                     "within": ["shape", "material"], "scales": ["rating"], "aggregate": "mean",
                                     "figures": {"interactions": [{"x": "shape", "trace": "material"}]}, **extra}))
    return study


@pytest.fixture(scope="module")
def all_models(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("models")
    out = tmp / "res"
    assert main(["-q", "analyze", "ratings", str(_study(tmp, model="all")), "--out", str(out)]) == 0
    return out


def test_mixed_section_is_the_lmm_of_the_trials(all_models):
    from analysis.stats.lmm import fit_lmm
    from analysis.stats.lmm_anova import lmm_anova

    res = json.loads((all_models / "results.json").read_text())["scales"]["rating"]
    assert {"anova", "lmm", "ordinal"} <= set(res)
    lmm = res["lmm"]
    d = pd.read_csv(DATA)
    direct = fit_lmm(lmm["formula"], d, factors=["shape", "material", "participant", "stimulus"])
    assert abs(direct.deviance - lmm["reml_criterion"]) < 1e-6 and lmm["n_obs"] == len(d)
    table = lmm_anova(direct)
    assert np.allclose([r["F"] for r in lmm["anova"]], table.F, rtol=1e-6)
    # the structure chosen by the documented fallback is recorded with every candidate
    st = pd.read_csv(all_models / "rating" / "lmm_structures.csv")
    assert st["used"].sum() == 1 and st["structure"].iloc[0] == "maximal"
    for f in ["lmm_anova.csv", "lmm_coefficients.csv", "lmm_variance_components.csv", "lmm_emmeans_shape_by_material.png"]:
        assert (all_models / "rating" / f).is_file(), f
    report = (all_models / "report.md").read_text()
    assert "### Linear mixed model" in report and "### Ordinal (cumulative-link) mixed model" in report


def test_ordinal_section_is_the_clmm_of_the_trials(all_models):
    from analysis.stats.clmm import fit_clmm, likelihood_ratio_tests

    res = json.loads((all_models / "results.json").read_text())["scales"]["rating"]["ordinal"]
    d = pd.read_csv(DATA)
    direct = fit_clmm(res["formula"], d, factors=["shape", "material", "participant", "stimulus"])
    assert abs(direct.loglik - res["loglik"]) < 1e-6 and res["link"] == "logit"
    lr = likelihood_ratio_tests(direct)
    assert np.allclose([r["lr_chisq"] for r in res["lr_tests"]], lr["lr_chisq"], rtol=1e-5)
    probs = pd.read_csv(all_models / "rating" / "clmm_probabilities.csv")
    assert np.allclose(probs.groupby(["shape", "material"])["probability"].sum(), 1.0)
    assert (all_models / "rating" / "clmm_probabilities.png").is_file()


def test_anova_only_by_default(tmp_path):
    out = tmp_path / "res"
    assert main(["-q", "analyze", "ratings", str(_study(tmp_path)), "--out", str(out)]) == 0
    res = json.loads((out / "results.json").read_text())["scales"]["rating"]
    assert "anova" in res and "lmm" not in res and "ordinal" not in res


@pytest.mark.parametrize(("extra", "message"), [
    ({"model": "bayes"}, "model"),
    ({"model": "mixed", "mixed": {"random": "(1 + shape participant)"}}, "mixed.random"),
    ({"model": "mixed", "mixed": {"random": "shape + (1 | participant)"}}, "mixed.random"),
    ({"model": "mixed", "mixed": {"ddf": "wald"}}, "mixed.ddf"),
    ({"model": "mixed", "mixed": {"random": "(1 | nobody)"}}, "nobody"),
])
def test_bad_model_settings_are_one_line_errors(tmp_path, capsys, extra, message):
    out = tmp_path / "res"
    rc = main(["-q", "analyze", "ratings", str(_study(tmp_path, **extra)), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and message in err and len(err.splitlines()) == 1, err
