"""Cumulative-link mixed models against R's ordinal::clmm 2022.11 (tightly converged).

Reference numbers: ``tests/r_reference/clmm_reference.R`` (its output ``clmm_reference.out``) on
the data sets it writes (``tests/data/clmm_*.csv``): a crossed participants × stimuli 7-point
design with two within factors (logit; with and without their interaction), a nested probit
design (participants within sites, a between and a within factor), and a single random term with
a covariate on a scale where two categories were never used.

R's nlminb stops at max|grad| 1e-5 … 1e-3 even with tight settings, so the R script also polishes
each clmm fit by Newton steps on numDeriv's gradient and Hessian of clmm's own Laplace objective:
the tight comparisons are with those (estimates and SDs absolute 1e-6, log-likelihoods absolute
1e-8, standard errors, z and cond.H relative 1e-6, predicted probabilities absolute 1e-7 and their
SEs relative 2e-6, LR χ² absolute 1e-6; they agree to 6e-8, 2e-11, 4e-8, 9e-9, 3e-7, 7e-11), the
loose ones with clmm's unpolished output (estimates absolute 1e-4, log-likelihood 1e-5,
``summary(clmm)``'s standard errors relative 1e-3: its deriv12 Hessian has ~1e-4 noise; drop1's LR
χ² absolute 1e-4). With one random term clmm's default
(C) code puts the Hessian of the last-but-one Newton iterate into the Laplace determinant (its
log-likelihood is ~5e-6 off on dataset 3); the tight references for that model come from clmm's R
code path (``useMatrix = TRUE``), whose determinant is at the modes, as ours.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.stats.clmm import fit_clmm, likelihood_ratio_tests
from analysis.stats.clmm_figures import probability_figure, probability_plot
from analysis.stats.formula import FormulaError
from r_reference_numbers import r_reference

R = r_reference("clmm_reference")
ROOT = Path(__file__).parent
MODELS = {
    "R_CLMM_CROSSED": ("clmm_crossed.csv", "rating ~ shape * material + (1 | participant) + (1 | stimulus)", "logit"),
    "R_CLMM_CROSSED_ADDITIVE": ("clmm_crossed.csv", "rating ~ shape + material + (1 | participant) + (1 | stimulus)",
                                "logit"),
    "R_CLMM_NESTED_PROBIT": ("clmm_nested_probit.csv", "rating ~ group * style + (1 | site/participant)", "probit"),
    "R_CLMM_MISSING_CATEGORY": ("clmm_missing_category.csv", "rating ~ expression + luminance + (1 | participant)",
                                "logit"),
}
NAMES = list(MODELS)


def data(name: str) -> pd.DataFrame:
    return pd.read_csv(ROOT / "data" / MODELS[name][0])


def rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b) / np.abs(b)))


@pytest.fixture(scope="module")
def fits():
    return {name: fit_clmm(formula, data(name), link=link) for name, (_, formula, link) in MODELS.items()}


@pytest.fixture(scope="module")
def lr_tables(fits):
    return {name: likelihood_ratio_tests(fit).set_index("term") for name, fit in fits.items()}


@pytest.mark.parametrize("name", NAMES)
def test_estimates_equal_clmm(fits, name):
    r, fit = R[name], fits[name]
    assert fit.converged and not fit.warnings and fit.max_grad < 1e-6
    assert fit.columns == list(r["coef"]) and fit.threshold_names == list(r["thresholds"])
    assert fit.n == r["n"] and fit.n_params == r["edf"]
    assert abs(fit.loglik - r["loglik"]) < 1e-8
    assert abs(fit.loglik - r["loglik_clmm"]) < 1e-5
    assert abs(fit.aic - r["aic"]) < 2e-6
    for key, tol in (("estimate", 1e-6), ("estimate_clmm", 1e-4)):
        assert np.max(np.abs(fit.beta - [v[key] for v in r["coef"].values()])) < tol
        assert np.max(np.abs(fit.theta - [v[key] for v in r["thresholds"].values()])) < tol
    vc = fit.variance_components().set_index("group")
    assert set(vc.index) == set(r["sd"])
    for g, sd in r["sd"].items():
        assert abs(vc.loc[g, "sd"] - sd) < 1e-6
        assert abs(vc.loc[g, "variance"] - sd ** 2) < 2e-6
        assert abs(vc.loc[g, "sd"] - r["sd_clmm"][g]) < 1e-4


@pytest.mark.parametrize("name", NAMES)
def test_standard_errors_and_tests_equal_clmm(fits, name):
    r, fit = R[name], fits[name]
    coef, th = fit.coefficients(), fit.thresholds()
    assert rel(coef["se"], [v["se"] for v in r["coef"].values()]) < 1e-6
    assert rel(coef["z"], [v["z"] for v in r["coef"].values()]) < 1e-6
    assert rel(coef["p"], [v["p"] for v in r["coef"].values()]) < 1e-3  # p = 4e-27 moves by z² × Δz/z
    assert rel(th["se"], [v["se"] for v in r["thresholds"].values()]) < 1e-6
    # summary(clmm)'s own SEs come from a difference Hessian (steps 1e-4) of a noisy objective
    assert rel(coef["se"], [v["se_summary"] for v in r["coef"].values()]) < 1e-3
    assert rel(th["se"], [v["se_summary"] for v in r["thresholds"].values()]) < 1e-3
    assert rel(fit.cond_H, r["cond_H"]) < 1e-6
    assert rel(fit.cond_H, r["cond_H_summary"]) < 1e-2


def test_conditional_modes_equal_ranef(fits):
    r, fit = R["R_CLMM_CROSSED"], fits["R_CLMM_CROSSED"]
    re = fit.random_effects()
    for g, levels in r["ranef"].items():
        tab = re[g].loc[list(levels)]
        assert np.max(np.abs(tab["(Intercept)"] - [v[0] for v in levels.values()])) < 1e-6
        assert rel(tab["cond_var"], [v[1] for v in levels.values()]) < 1e-6


@pytest.mark.parametrize("name, spec", [("R_CLMM_CROSSED", "shape:material"), ("R_CLMM_CROSSED", "shape"),
                                        ("R_CLMM_NESTED_PROBIT", "group:style"),
                                        ("R_CLMM_MISSING_CATEGORY", "expression")])
def test_predicted_probabilities_equal_emmeans(fits, name, spec):
    """emmeans(fit, ~ factors | rating, mode = "prob"): cells, marginal averages, covariate at its mean."""
    ref, fit = R[name][spec], fits[name]
    factors = spec.split(":")
    tab = fit.predicted_probabilities(factors)
    keys = tab[factors + ["category"]].astype(str).agg(":".join, axis=1)
    got = tab.set_index(keys)
    assert sorted(got.index) == sorted(ref)
    prob = np.array([ref[k][0] for k in got.index])
    se = np.array([ref[k][1] for k in got.index])
    assert np.max(np.abs(got["probability"] - prob)) < 1e-7
    assert rel(got["se"], se) < 2e-6
    assert np.allclose(tab.groupby(factors)["probability"].sum(), 1.0, atol=1e-12)
    assert np.allclose(got["upper"] - got["probability"], 1.959963984540054 * got["se"])


@pytest.mark.parametrize("name", NAMES)
def test_likelihood_ratio_tests_equal_refits_and_drop1(lr_tables, name):
    """Each term's columns left out (R: clmm refits on the sum-coded columns); drop1's rows match."""
    r, tab = R[name], lr_tables[name]
    assert list(tab.index) == list(r["lr"])
    for term, ref in r["lr"].items():
        row = tab.loc[term]
        assert row["df"] == ref["df"]
        assert abs(row["lr_chisq"] - ref["lr_chisq"]) < 1e-6
        assert abs(row["loglik"] - ref["loglik"]) < 1e-8
        assert abs(row["aic"] - ref["aic"]) < 2e-6
        assert abs(row["p"] - ref["p"]) < 1e-6 * max(1.0, ref["p"]) + 1e-12
    for term, ref in r["drop1"].items():  # drop1 tests the highest-order terms only (marginality)
        row = tab.loc[term]
        assert row["df"] == ref["df"] and abs(row["lr_chisq"] - ref["lr_chisq"]) < 1e-4
        assert abs(row["aic"] - ref["aic"]) < 1e-4


def test_probit_is_not_logit(fits):
    """The link matters: the crossed data under probit is another model (a test that can fail)."""
    probit = fit_clmm(MODELS["R_CLMM_CROSSED"][1], data("R_CLMM_CROSSED"), link="probit")
    logit = fits["R_CLMM_CROSSED"]
    assert abs(probit.loglik - logit.loglik) > 0.1
    assert np.max(np.abs(probit.theta - logit.theta)) > 0.5


def test_invariant_to_row_order_labels_and_level_order(fits):
    d = data("R_CLMM_MISSING_CATEGORY")
    ref = fits["R_CLMM_MISSING_CATEGORY"]
    shuffled = d.sample(frac=1.0, random_state=3).reset_index(drop=True)
    fit = fit_clmm(MODELS["R_CLMM_MISSING_CATEGORY"][1], shuffled)
    assert abs(fit.loglik - ref.loglik) < 1e-8 and np.max(np.abs(fit.theta - ref.theta)) < 1e-6
    # an ordered Categorical response with labels and its declared unused levels
    labels = ["awful", "bad", "meh", "neutral", "ok", "good", "great"]
    cat = d.assign(rating=pd.Categorical.from_codes(d["rating"] - 1, categories=labels, ordered=True))
    fit = fit_clmm(MODELS["R_CLMM_MISSING_CATEGORY"][1], cat)
    assert fit.categories == ["awful", "bad", "meh", "ok", "good"]
    assert fit.threshold_names == ["awful|bad", "bad|meh", "meh|ok", "ok|good"]
    assert abs(fit.loglik - ref.loglik) < 1e-8
    # the full 1..7 scale given as the response's levels: unused categories dropped, as clmm
    fit = fit_clmm(MODELS["R_CLMM_MISSING_CATEGORY"][1], d, levels={"rating": list(range(1, 8))})
    assert fit.threshold_names == ["1|2", "2|3", "3|5", "5|6"] and abs(fit.loglik - ref.loglik) < 1e-8


def test_gradient_is_exact():
    """The analytic gradient of the Laplace objective equals central differences of its values."""
    from analysis.stats.clmm import _build
    from analysis.stats.clmm_laplace import _start
    from analysis.stats.formula import model_matrices

    for name in ("R_CLMM_CROSSED", "R_CLMM_NESTED_PROBIT"):
        _, formula, link = MODELS[name]
        prob, _, _ = _build(model_matrices(formula, data(name)), link, "t", None, None)
        phi = _start(prob)
        phi[prob.nt: prob.nt + prob.p] = np.linspace(-0.3, 0.3, prob.p)
        phi[prob.nt + prob.p:] = np.linspace(0.4, 0.9, prob.K)
        _, g = prob.value_and_gradient(phi)
        num = np.empty_like(g)
        for i in range(len(phi)):
            e = np.zeros_like(phi)
            e[i] = 1e-5
            num[i] = (prob.objective(phi + e)[0] - prob.objective(phi - e)[0]) / 2e-5
        assert np.max(np.abs(g - num)) < 1e-5 * max(1.0, np.max(np.abs(g)))


def test_figure_has_no_overlaps_and_is_saved(fits, tmp_path):
    import matplotlib.pyplot as plt

    from figure_checks import overlaps

    fit = fits["R_CLMM_CROSSED"]
    fig = probability_figure(fit.predicted_probabilities(), title="appeal")
    try:
        assert overlaps(fig) == []
        assert [ax.get_title() for ax in fig.axes] == ["material = glossy", "material = matte"]
        assert len(fig.axes[0].patches) == 3 * 7
    finally:
        plt.close(fig)
    paths = probability_plot(fits["R_CLMM_MISSING_CATEGORY"], tmp_path / "probs")
    assert [p.suffix for p in paths] == [".png", ".svg"] and all(p.stat().st_size > 1000 for p in paths)


def _bad(d: pd.DataFrame, formula: str, match: str, **kw) -> None:
    with pytest.raises(FormulaError, match=match) as err:
        fit_clmm(formula, d, **kw)
    assert "\n" not in str(err.value)


def test_bad_input_is_one_line():
    d = data("R_CLMM_CROSSED")
    f = MODELS["R_CLMM_CROSSED"][1]
    _bad(d, "rating ~ shape + (1 + shape | participant)", "random intercepts only")
    _bad(d, "rating ~ shape + (0 + shape | participant)", "random intercepts only")
    _bad(d.assign(rating=d["rating"] + 0.5 * (d.index == 7)), f, "holds 2.5: clmm needs ordered categories")
    _bad(d.assign(rating=np.where(d["rating"] > 3, "high", "low")), f, "holds 'low': clmm needs ordered")
    _bad(d.assign(rating=pd.Categorical(d["rating"].astype(str))), f, "unordered categorical")
    _bad(d.assign(rating=4), f, "one category")
    _bad(d[d["stimulus"].isin(["f01", "f02"])], f, "stimulus has 2 levels: clmm needs at least 3")
    _bad(d[d["stimulus"] == "f01"], f, "grouping factor stimulus has one level")
    _bad(d.assign(shape2=d["shape"]), "rating ~ shape + shape2 + (1 | participant)", "cannot be identified")
    _bad(d, "rating ~ shape + material", "no random term")
    _bad(d, "rating ~ 0 + shape + (1 | participant)", "take the intercept's place")
    _bad(d, f, "link 'cloglog' is not one of logit, probit", link="cloglog")
    _bad(d, "rating ~ shape + (1 | rater)", "lack")


def test_two_categories_fit_a_binary_model():
    d = data("R_CLMM_CROSSED")
    fit = fit_clmm("high ~ shape + (1 | participant) + (1 | stimulus)", d.assign(high=1 + (d["rating"] >= 5)))
    assert fit.converged and fit.threshold_names == ["1|2"] and len(fit.columns) == 2


def test_cli_clmm_equals_the_library_and_fails_in_one_line(tmp_path, capsys):
    import json

    from appeal_cli import main

    data = ROOT / "data" / "clmm_crossed.csv"
    formula = "rating ~ shape * material + (1 | participant) + (1 | stimulus)"
    out = tmp_path / "c.json"
    rc = main(["analyze", "clmm", str(data), "--formula", formula, "--probabilities", "shape",
               "--figure", str(tmp_path / "p"), "--json", str(out)])
    assert rc == 0 and (tmp_path / "p.png").is_file()
    res = json.loads(out.read_text())
    fit = fit_clmm(formula, pd.read_csv(data))
    assert np.allclose([r["estimate"] for r in res["coefficients"]], fit.beta, rtol=1e-9)
    assert [r["term"] for r in res["lr_tests"]] == ["shape", "material", "shape:material"]
    capsys.readouterr()
    rc = main(["analyze", "clmm", str(data), "--formula", "rating ~ shape + (1 + shape | participant)"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "intercept" in err
