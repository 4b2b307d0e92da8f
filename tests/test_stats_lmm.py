"""Linear mixed models against lme4 1.1, lmerTest 3.1, afex 1.2 and emmeans 1.8 (tightly converged).

Reference numbers: ``tests/r_reference/lmm_reference.R`` (its output ``lmm_reference.out``) on the
data sets it writes (``tests/data/lmm_*.csv``): a crossed participants × stimuli design with
by-participant random slopes, a nested design (participants within labs, a lab-level factor),
the crossed design unbalanced with missing cells, and a small one.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.stats.formula import FormulaError, model_matrices, parse_formula
from analysis.stats.lmm import fit_lmm
from analysis.stats.lmm_anova import lmm_anova, type3_contrasts
from analysis.stats.lmm_emmeans import emm_pairs, emm_poly, emmeans, poly_coefficients
from analysis.stats.satterthwaite import satterthwaite
from r_reference_numbers import r_reference

R = r_reference("lmm_reference")
DATA = {"R_CROSSED": ("lmm_crossed.csv", ["participant", "stimulus", "shape", "material"]),
        "R_NESTED": ("lmm_nested.csv", ["lab", "participant", "group", "condition"]),
        "R_UNBALANCED": ("lmm_unbalanced.csv", ["participant", "stimulus", "shape", "material"]),
        "R_SMALL": ("lmm_small.csv", ["participant", "stimulus", "shape"])}
DESIGNS = list(DATA)
ROOT = __import__("pathlib").Path(__file__).parent


def rel(a, b, floor=1e-12):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), floor)))


@pytest.fixture(scope="module")
def fits():
    out = {}
    for name, (f, factors) in DATA.items():
        data = pd.read_csv(ROOT / "data" / f)
        reml = fit_lmm(R[name]["formula"], data, factors=factors)
        ml = fit_lmm(R[name]["formula"], data, factors=factors, reml=False)
        out[name] = (reml, ml, satterthwaite(reml))
    return out


@pytest.mark.parametrize("name", DESIGNS)
def test_fit_equals_lme4(fits, name):
    r, (m, ml, _) = R[name], fits[name]
    assert m.converged and not m.singular and not m.warnings
    assert m.mm.columns == r["coef_names"]
    assert abs(m.deviance - r["reml_deviance"]) < 1e-6
    assert abs(ml.deviance - r["ml_deviance"]) < 1e-6
    assert rel(m.beta, r["beta"]) < 1e-6
    assert rel(ml.beta, r["ml_beta"]) < 1e-6
    assert rel(np.sqrt(np.diag(m.vcov)), r["se"]) < 1e-5
    assert rel(m.sigma, r["sigma"]) < 1e-6 and rel(ml.sigma, r["ml_sigma"]) < 1e-6


@pytest.mark.parametrize("name", DESIGNS)
def test_variance_components_equal_varcorr(fits, name):
    r, m = R[name], fits[name][0]
    vc = m.variance_components()
    ours = {}
    for row in vc.itertuples():
        group = row.group
        if row.term2:
            ours[(group, row.term, row.term2, "corr")] = row.corr
        else:
            ours[(group, row.term, "", "var")] = row.variance
    for grp, v1, v2, var, sdcor in zip(r["vc_grp"], r["vc_var1"], r["vc_var2"], r["vc_vcov"], r["vc_sdcor"]):
        grp = {"participant:lab": "lab:participant"}.get(grp, grp)  # lme4 names a nested group inner:outer
        if v2:  # lme4 lists a correlation (var1, var2) as the lower triangle: ours is (term, term2) = (row, column)
            assert abs(ours[(grp, v2, v1, "corr")] - sdcor) < 1e-4 * max(1, abs(sdcor))
        else:
            assert rel(ours[(grp, v1, "", "var")], var) < 1e-4


@pytest.mark.parametrize("name", DESIGNS)
def test_satterthwaite_dfs_equal_lmertest(fits, name):
    r, (m, _, sat) = R[name], fits[name]
    dfs = [sat.ddf(np.eye(len(m.beta))[i]) for i in range(len(m.beta))]
    assert rel(dfs, r["df_satt"]) < 1e-3


@pytest.mark.parametrize("name", DESIGNS)
def test_exact_vcov_jacobian_equals_the_numerical_one(fits, name):
    """Satterthwaite's J = dCov(beta)/d(theta, sigma) in closed form equals lmerTest's way (Richardson
    differences of Cov(beta)), for REML and ML fits and at a point away from the optimum."""
    from analysis.stats.satterthwaite import richardson_jacobian

    for fit in fits[name][:2]:
        for vp in (fit.varpar, fit.varpar * 1.3 + 0.05):
            exact, numeric = fit.vcov_vp_jacobian(vp), richardson_jacobian(fit.vcov_vp, vp)
            assert exact.shape == numeric.shape == (len(fit.beta), len(fit.beta), len(vp))
            assert np.abs(exact - numeric).max() <= 1e-7 * np.abs(numeric).max()


@pytest.mark.parametrize("name", DESIGNS)
def test_type3_anova_equals_afex_mixed(fits, name):
    r, (m, _, sat) = R[name], fits[name]
    table = lmm_anova(m, tests=sat)
    assert list(table.effect) == r["afex_terms"] == r["anova_terms"]
    assert rel(table.F, r["afex_F"]) < 1e-4
    assert rel(table.den_df, r["afex_dendf"]) < 1e-3
    assert rel(table.p, r["afex_p"]) < 1e-4
    assert list(table.num_df) == r["anova_numdf"]


def test_type3_hypotheses_span_the_term_columns(fits):
    """Under sum-to-zero coding a term's type-III hypothesis has the row space of its own columns."""
    m = fits["R_UNBALANCED"][0]
    for term, L in type3_contrasts(m.mm).items():
        cols = m.mm.term_columns[term]
        assert np.allclose(np.delete(L, cols, axis=1), 0, atol=1e-9)
        assert np.linalg.matrix_rank(L[:, cols]) == len(cols)


@pytest.mark.parametrize("name", DESIGNS)
def test_emmeans_and_contrasts_equal_emmeans(fits, name):
    r, (m, _, sat) = R[name], fits[name]
    specs = [k[4:] for k in r if k.startswith("emm_") and not k.endswith("_kr")]
    assert specs
    for spec in specs:
        factors = spec.split("_")
        emm = emmeans(m, factors, sat)
        ref = r[f"emm_{spec}"]
        assert [":".join(map(str, row)) for row in emm[factors].itertuples(index=False)] == ref["levels"]
        assert rel(emm.emmean, ref["emmean"]) < 1e-5 and rel(emm.se, ref["SE"]) < 1e-5 and rel(emm.df, ref["df"]) < 1e-3
        pw, rp = emm_pairs(m, emm, sat), r[f"pairs_{spec}"]
        assert list(pw.contrast) == rp["contrast"]
        assert rel(pw.estimate, rp["estimate"]) < 1e-5 and rel(pw.se, rp["SE"]) < 1e-5
        assert rel(pw.df, rp["df"]) < 1e-3 and rel(pw.t, rp["t"]) < 1e-5
        # Tukey p: R's ptukey integrates numerically (relative error up to ~5e-4 near p = 1e-6) and
        # bottoms out near 1.6e-10; SciPy's studentized_range is the other integrator
        assert np.all(np.abs(pw.p - rp["p"]) <= 1e-3 * np.abs(rp["p"]) + 1e-9)
        if f"poly_{spec}" in r:
            po, rq = emm_poly(m, emm, sat), r[f"poly_{spec}"]
            assert list(po.contrast) == rq["contrast"]
            assert rel(po.estimate, rq["estimate"]) < 1e-5 and rel(po.se, rq["SE"]) < 1e-5
            assert rel(po.df, rq["df"]) < 1e-3 and rel(po.p, rq["p"], floor=1e-12) < 1e-4


def test_poly_coefficients_are_emmeans_integers():
    assert poly_coefficients(3).T.tolist() == [[-1, 0, 1], [1, -2, 1]]
    assert poly_coefficients(5).T.tolist()[:2] == [[-2, -1, 0, 1, 2], [2, -1, -2, -1, 2]]
    assert poly_coefficients(4).T.tolist() == [[-3, -1, 1, 3], [1, -1, -1, 1], [-1, 3, -3, 1]]


def test_formula_parsing_follows_lme4():
    f = parse_formula("rating ~ shape * material + (1 + shape | participant) + (1 | lab/participant)")
    assert [":".join(t) for t in f.fixed] == ["shape", "material", "shape:material"]
    assert [(r.group, r.intercept, r.terms) for r in f.random] == [
        ("participant", True, (("shape",),)), ("lab", True, ()), ("lab:participant", True, ())]
    g = parse_formula("y ~ 0 + a + (a || s)")
    assert not g.intercept and [(r.intercept, r.terms) for r in g.random] == [(True, ()), (False, (("a",),))]
    assert parse_formula("y ~ a - 1").intercept is False


def test_singular_fit_is_reported():
    """No stimulus variance in the data: the stimulus SD goes to the boundary, as lme4's isSingular."""
    rng = np.random.default_rng(4)
    d = pd.DataFrame([(p, s, c) for p in range(12) for s in range(8) for c in "ab"], columns=["p", "s", "c"])
    d["y"] = rng.normal(0, 0.7, 12)[d.p] + (d.c == "b") * 0.5 + rng.normal(0, 1, len(d))
    m = fit_lmm("y ~ c + (1 | p) + (1 | s)", d, factors=["p", "s"])
    if m.theta[1] > 1e-4:  # this seed's stimulus variance estimate is positive: make it zero
        d["y"] -= d.groupby("s").y.transform("mean") - d.y.mean()
        m = fit_lmm("y ~ c + (1 | p) + (1 | s)", d, factors=["p", "s"])
    assert m.singular and any("singular" in w for w in m.warnings)
    assert m.theta[1] < 1e-4 and m.converged


@pytest.mark.parametrize(("formula", "message"), [
    ("rating ~ shape + (1 | nobody)", "lack"),
    ("rating ~ shape + (1 | one)", "one level"),
    ("rating ~ shape + shape2 + (1 | participant)", "cannot be identified"),
    ("rating ~ shape", "no random term"),
    ("rating ~ shape + (1 | row)", "cannot be told apart"),
    ("rating ~ shape + (1 participant)", "cannot read"),
])
def test_bad_models_give_one_line_errors(formula, message):
    d = pd.read_csv(ROOT / "data" / "lmm_small.csv")
    d["one"] = "x"
    d["shape2"] = d["shape"]
    d["row"] = np.arange(len(d))
    with pytest.raises(FormulaError, match=message) as err:
        fit_lmm(formula, d, factors=["shape", "shape2"])
    assert "\n" not in str(err.value)


def test_model_matrix_codes_factors_with_sum_contrasts():
    d = pd.DataFrame({"a": ["x", "y", "z", "x"], "b": [0, 1, 0, 1], "y": [1.0, 2, 3, 4], "g": [1, 1, 2, 2]})
    mm = model_matrices("y ~ a * b + (1 | g)", d, factors=["b"])
    assert mm.columns == ["(Intercept)", "a1", "a2", "b1", "a1:b1", "a2:b1"]
    assert mm.X[:, 1:3].tolist() == [[1, 0], [0, 1], [-1, -1], [1, 0]]
    assert mm.X[:, 3].tolist() == [1, -1, 1, -1]
    assert np.allclose(mm.X[:, 4], mm.X[:, 1] * mm.X[:, 3])


def test_maximal_structure_falls_back_in_the_documented_order():
    """The crossed data have by-participant shape deviations and no by-stimulus shape slopes: the
    maximal and uncorrelated fits are singular; dropping the terms estimated at zero keeps the
    participant shape slopes and the stimulus intercepts and drops the stimulus shape slopes."""
    from analysis.stats.random_structures import fit_with_fallback, structure_table

    d = pd.read_csv(ROOT / "data" / "lmm_crossed.csv")
    fit, attempts = fit_with_fallback(d, "rating ~ shape * material", groups=["participant", "stimulus"],
                                      factors=["shape", "material"])
    table = structure_table(attempts, fit)
    assert list(table.structure[:3]) == ["maximal", "maximal, uncorrelated", "maximal, uncorrelated, zero-variance terms dropped"]
    assert list(table.outcome[:3]) == ["singular fit", "singular fit", "converged"] and table.used.tolist()[2]
    by_group = {}
    for r in fit.formula.random:
        by_group.setdefault(r.group, []).extend([("(Intercept)",)] if r.intercept else list(r.terms))
    assert ("shape",) in by_group["participant"] and ("(Intercept)",) in by_group["stimulus"]
    assert ("shape",) not in by_group["stimulus"] and not fit.singular
    assert "|| participant)" in fit.formula.text  # uncorrelated, written as afex does (expand_re)
    # the formula text is the model: refitting it gives the same fit
    again = fit_lmm(fit.formula.text, d, factors=["shape", "material"])
    assert abs(again.deviance - fit.deviance) < 1e-6


def test_stimulus_confounded_with_cells_is_left_out_or_refused():
    """One stimulus per cell of a full factorial (thesis Exp. 2): its variance cannot be told from the
    fixed effects'. Written explicitly it is a one-line error; under random: maximal it is left out."""
    from analysis.stats.random_structures import fit_with_fallback

    rng = np.random.default_rng(5)
    d = pd.DataFrame([(p, a, b) for p in range(10) for a in range(3) for b in range(2)], columns=["p", "a", "b"])
    d["stimulus"] = d.a.astype(str) + "_" + d.b.astype(str)
    d["y"] = rng.normal(0, 1, 10)[d.p] + d.a * 0.5 + rng.normal(0, 1, len(d))
    with pytest.raises(FormulaError, match="cannot be identified") as err:
        fit_lmm("y ~ a * b + (1 | p) + (1 | stimulus)", d, factors=["a", "b"])
    assert "\n" not in str(err.value)
    fit, attempts = fit_with_fallback(d, "y ~ a * b", groups=["p", "stimulus"], factors=["a", "b"])
    assert "stimulus" not in fit.formula.text and attempts[0].outcome.startswith("left out")


def test_cli_lmm_equals_r_and_fails_in_one_line(tmp_path, capsys):
    import json

    from appeal_cli import main

    out = tmp_path / "lmm.json"
    rc = main(["analyze", "lmm", str(ROOT / "data" / "lmm_nested.csv"), "--formula", R["R_NESTED"]["formula"],
               "--emmeans", "condition", "--json", str(out)])
    assert rc == 0
    res = json.loads(out.read_text())
    assert rel([r["F"] for r in res["anova"]], R["R_NESTED"]["afex_F"]) < 1e-4
    assert [r["condition"] for r in res["emmeans"]] == ["c1", "c2", "c3"] and len(res["pairs"]) == 3
    assert "Type III F tests" in capsys.readouterr().out
    rc = main(["analyze", "lmm", str(ROOT / "data" / "lmm_nested.csv"), "--formula", "y ~ condition + (1 | nolab)"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "nolab" in err and len(err.splitlines()) == 1
