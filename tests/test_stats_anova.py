"""rm_anova against R (car::Anova univariate tests, Mauchly, GG/HF; afex pes/ges) and its input checks."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from analysis import rm_anova
from analysis.stats.design import prepare_design
from appeal.errors import AppealInputError
from r_reference_numbers import r_reference

DATA = __import__("pathlib").Path(__file__).parent / "data"
NAN = float("nan")

_R = r_reference("anova_reference")  # tests/r_reference/anova_reference.out
# ---- produced by: Rscript tests/r_reference/anova_reference.R   (R 4.2.2, car 3.1.1, afex 1.2.1)
# aov_ez(id, dv, data, within, between, type = 3, fun_aggregate = mean) ; summary(fit$Anova,
# multivariate = FALSE) for SS / F / p / Mauchly / GG / HF and anova(fit, es = c("pes", "ges")).
# Data: tests/data/stats_*.csv written by the same script (set.seed).
R_WITHIN2 = _R["R_WITHIN2"]
R_WITHIN3 = _R["R_WITHIN3"]
R_WITHIN4 = _R["R_WITHIN4"]
R_OBK = _R["R_OBK"]

CASES = {
    "within2_likert": ("stats_within2_likert.csv", "rating", ["A", "B"], [], R_WITHIN2),
    "within3_continuous": ("stats_within3_cont.csv", "y", ["A", "B", "C"], [], R_WITHIN3),
    "within4_likert_repeated_trials": ("stats_within4_likert_reps.csv", "appeal",
                                       ["character", "shape", "material", "expression"], [], R_WITHIN4),
    "mixed_obk_long": ("stats_obk_long.csv", "value", ["phase", "hour"], ["treatment", "gender"], R_OBK),
}


SINGULAR = {("within3_continuous", "B:C"), ("within3_continuous", "A:B:C")}


def _load(name):
    return pd.read_csv(DATA / name)


@pytest.mark.parametrize("case", list(CASES))
def test_agrees_with_r(case):
    fname, dv, within, between, ref = CASES[case]
    table = rm_anova(_load(fname), dv, "id", within, between, aggregate="mean").set_index("effect")
    assert list(table.index) == list(ref)  # names and the car/afex order
    for effect, values in ref.items():
        for col, expected in values.items():
            got = table.loc[effect, col]
            if math.isnan(expected):
                # car leaves sphericity undefined for 1-df and singular effects; so do we,
                # except that singular effects get ε from the trace formula (tested below)
                if (case, effect) not in SINGULAR or col in ("mauchly_W", "mauchly_p"):
                    assert math.isnan(got), (effect, col, got)
                continue
            assert got == pytest.approx(expected, rel=1e-6, abs=0), (effect, col)


def test_singular_effects_use_trace_epsilon():
    """B:C has 6 df with 5 error df: no Mauchly (as car), GG from the trace formula."""
    df = _load("stats_within3_cont.csv")
    table = rm_anova(df, "y", "id", ["A", "B", "C"]).set_index("effect")
    row = table.loc["B:C"]
    assert math.isnan(row.mauchly_W) and math.isnan(row.mauchly_p)
    # independent: GG = (sum λ)² / (d Σ λ²) from the eigenvalues of the covariance of the
    # subjects' B:C interaction contrasts (Helmert basis here, any orthonormal basis works)
    wide = df.pivot_table(index="id", columns=["B", "C"], values="y", aggfunc="mean").to_numpy()
    from scipy.linalg import helmert

    basis = np.kron(helmert(3, full=False).T, helmert(4, full=False).T)  # (12, 6)
    z = wide @ basis
    lam = np.linalg.eigvalsh(np.cov(z, rowvar=False))
    gg = lam.sum() ** 2 / (6 * (lam**2).sum())
    assert row.gg_eps == pytest.approx(gg, rel=1e-10)
    assert 1 / 6 <= row.gg_eps <= 5 / 6 + 1e-12  # rank 5 of 6


def test_pingouin_cross_check_two_way():
    import pingouin as pg

    df = _load("stats_within2_likert.csv")
    ours = rm_anova(df, "rating", "id", ["A", "B"]).set_index("effect")
    theirs = pg.rm_anova(df, dv="rating", within=["A", "B"], subject="id", correction=True).set_index("Source")
    for eff in ("A", "B", "A * B"):
        mine = ours.loc[eff.replace(" * ", ":")]
        assert mine.F == pytest.approx(theirs.loc[eff, "F"], rel=1e-9)
        assert mine.gg_eps == pytest.approx(theirs.loc[eff, "eps"], rel=1e-9)


def test_row_order_does_not_matter():
    df = _load("stats_obk_long.csv")
    a = rm_anova(df, "value", "id", ["phase", "hour"], ["treatment", "gender"])
    b = rm_anova(df.sample(frac=1, random_state=3), "value", "id", ["phase", "hour"], ["treatment", "gender"])
    pd.testing.assert_frame_equal(a, b)


def test_factor_order_names_effects_in_given_order():
    df = _load("stats_within2_likert.csv")
    t = rm_anova(df, "rating", "id", ["B", "A"])
    assert list(t.effect) == ["B", "A", "B:A"]
    ref = rm_anova(df, "rating", "id", ["A", "B"]).set_index("effect")
    assert t.set_index("effect").loc["B:A", "F"] == pytest.approx(ref.loc["A:B", "F"], rel=1e-12)


# ---------------------------------------------------------------- bad input
def _small():
    return _load("stats_within2_likert.csv")


def _message(exc_info):
    return str(exc_info.value)


def test_missing_cell_lists_subjects_and_cells():
    df = _small()
    df = df[~((df.id == "s03") & (df.A == "a2") & (df.B == "b4"))]
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "rating", "id", ["A", "B"])
    assert "1 subject(s) miss cells of the within design: s03 (A=a2, B=b4)" in _message(e)


def test_drop_incomplete_reports_dropped():
    df = _small()
    df = df[~((df.id == "s03") & (df.A == "a2") & (df.B == "b4"))]
    t = rm_anova(df, "rating", "id", ["A", "B"], drop_incomplete=True)
    assert t.attrs["dropped_subjects"] == ["s03"] and t.attrs["n_subjects"] == 7
    full = rm_anova(_small()[lambda d: d.id != "s03"], "rating", "id", ["A", "B"])
    pd.testing.assert_frame_equal(t, full)


def test_repeated_rows_need_aggregate():
    df = _load("stats_within4_likert_reps.csv")
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "appeal", "id", ["character", "shape", "material", "expression"])
    msg = _message(e)
    assert "360 subject x cell combinations have more than one row" in msg
    assert "(e.g. subject sub-01, character=female, shape=s0, material=m0, expression=angry: 2 rows)" in msg
    assert "aggregate: mean" in msg


def test_non_numeric_values_name_rows():
    df = _small()
    df["rating"] = df["rating"].astype(object)
    df.loc[[2, 6], "rating"] = "seven"
    df.attrs["source"] = "ratings.csv"
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "rating", "id", ["A", "B"])
    assert _message(e) == "ratings.csv: rating: non-numeric values in rows 3, 7 (e.g. 'seven'); expected numbers"


def test_out_of_scale_values_name_rows():
    df = _small()
    df.loc[4, "rating"] = 9
    with pytest.raises(AppealInputError) as e:
        prepare_design(df, "rating", "id", ["A", "B"], scale=(1, 7), source="r.csv")
    assert _message(e) == "r.csv: rating: values outside the scale 1..7 in row 5 (e.g. 9)"


def test_one_level_factor():
    df = _small()
    df = df[df.A == "a1"]
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "rating", "id", ["A", "B"])
    assert _message(e) == "<data>: A: a factor needs at least 2 levels (got only 'a1')"


def test_zero_variance_dv():
    df = _small()
    df["rating"] = 4
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "rating", "id", ["A", "B"])
    assert "rating: the DV has zero variance (every value is 4)" in _message(e)


def test_unknown_column_suggests():
    with pytest.raises(AppealInputError) as e:
        rm_anova(_small(), "ratng", "id", ["A", "B"])
    assert _message(e) == "<data>: dv: column 'ratng' not found (did you mean 'rating'?)"


def test_between_factor_must_be_constant_per_subject():
    df = _load("stats_obk_long.csv")
    df.loc[0, "gender"] = "F" if df.loc[0, "gender"] == "M" else "M"
    with pytest.raises(AppealInputError) as e:
        rm_anova(df, "value", "id", ["phase", "hour"], ["treatment", "gender"])
    assert "subjects o01 have more than one level of a between factor" in _message(e)


def test_aggregate_must_be_mean_or_none():
    with pytest.raises(AppealInputError) as e:
        rm_anova(_small(), "rating", "id", ["A", "B"], aggregate="median")
    assert "aggregate: expected 'mean' or none (got 'median')" in _message(e)
