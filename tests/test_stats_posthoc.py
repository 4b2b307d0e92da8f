"""Tukey HSD / Holm / Bonferroni pairwise comparisons against R emmeans on afex models."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from analysis import tukey_hsd
from appeal.errors import AppealInputError
from r_reference_numbers import r_reference

DATA = Path(__file__).parent / "data"

_R = r_reference("anova_reference")  # tests/r_reference/anova_reference.out
# ---- produced by: Rscript tests/r_reference/anova_reference.R   (R 4.2.2, afex 1.2.1, emmeans 1.8.4.1)
# fit <- aov_ez(..., type = 3, fun_aggregate = mean, include_aov = TRUE)
# as.data.frame(summary(pairs(emmeans(fit, ~effect, model = "univariate"), adjust = "tukey")))
# rows: (contrast, estimate, SE, df, t.ratio, p.value)
R_PAIRS_W2_A = _R["R_PAIRS_W2_A"]

R_PAIRS_W2_AB = _R["R_PAIRS_W2_AB"]

R_PAIRS_W4_SHAPE = _R["R_PAIRS_W4_SHAPE"]

R_PAIRS_W4_SHAPE_MATERIAL = _R["R_PAIRS_W4_SHAPE_MATERIAL"]

R_PAIRS_OBK_PHASE = _R["R_PAIRS_OBK_PHASE"]

R_PAIRS_OBK_TREATMENT = _R["R_PAIRS_OBK_TREATMENT"]

R_PAIRS_OBK_TREATMENT_PHASE = _R["R_PAIRS_OBK_TREATMENT_PHASE"]

W2 = ("stats_within2_likert.csv", "rating", ["A", "B"], [])
W4 = ("stats_within4_likert_reps.csv", "appeal", ["character", "shape", "material", "expression"], [])
OBK = ("stats_obk_long.csv", "value", ["phase", "hour"], ["treatment", "gender"])
CASES = {
    "within_main": (W2, "A", R_PAIRS_W2_A),
    "within_interaction_cells": (W2, "A:B", R_PAIRS_W2_AB),
    "within4_main": (W4, "shape", R_PAIRS_W4_SHAPE),
    "within4_interaction_cells": (W4, "shape:material", R_PAIRS_W4_SHAPE_MATERIAL),
    "mixed_within": (OBK, "phase", R_PAIRS_OBK_PHASE),
    "mixed_between_unbalanced": (OBK, "treatment", R_PAIRS_OBK_TREATMENT),
    "mixed_between_x_within_cells": (OBK, "treatment:phase", R_PAIRS_OBK_TREATMENT_PHASE),
}


def _run(spec, effect, adjust="tukey"):
    fname, dv, within, between = spec
    return tukey_hsd(pd.read_csv(DATA / fname), dv, "id", effect, within, between, aggregate="mean", adjust=adjust)


@pytest.mark.parametrize("case", list(CASES))
def test_tukey_equals_emmeans(case):
    spec, effect, ref = CASES[case]
    ours = _run(spec, effect)
    assert len(ours) == len(ref)
    by_pair = {(r.a, r.b): r for r in ours.itertuples()}
    for label, estimate, se, df, t_ratio, p in ref:
        a, b = (x.replace(" ", ":") for x in label.split(" - "))  # emmeans "a1 b2" -> "a1:b2"
        row, sign = (by_pair[(a, b)], 1) if (a, b) in by_pair else (by_pair[(b, a)], -1)
        assert sign * row.diff == pytest.approx(estimate, rel=1e-6, abs=1e-12)
        assert row.se == pytest.approx(se, rel=1e-6)
        assert row.df == pytest.approx(df, rel=1e-6)
        assert sign * row.t == pytest.approx(t_ratio, rel=1e-6, abs=1e-12)
        assert row.q == pytest.approx(abs(t_ratio) * np.sqrt(2), rel=1e-6, abs=1e-12)
        assert row.p == pytest.approx(p, rel=1e-6)


def test_main_effect_uses_its_own_error_term():
    """For a within main effect: MS_error and df of that effect's ANOVA error term."""
    from analysis import rm_anova

    fname, dv, within, between = W2
    df = pd.read_csv(DATA / fname)
    row = rm_anova(df, dv, "id", within).set_index("effect").loc["A"]
    mse = row.error_SS / row.den_df
    ours = _run(W2, "A")
    n_per_mean = 8 * 4  # subjects x levels of B
    assert np.allclose(ours.se, np.sqrt(2 * mse / n_per_mean), rtol=1e-12)
    assert np.all(ours.df == row.den_df)  # one stratum: its df is a count, given exactly


def test_one_stratum_df_is_its_count_exactly():
    """A function of one error stratum gets that stratum's df exactly, not var^2/(var^2/df) rounded.

    With these numbers the Satterthwaite formula gives 13.999999999999998 in floating point.
    Two strata keep the Satterthwaite df (compared with a stated tolerance).
    """
    from types import SimpleNamespace

    from analysis.stats.posthoc import _variance

    fit = SimpleNamespace(error_ms={0: 9.127555772777217, 1: 2.0}, error_df={0: 14.0, 1: 42.0},
                          mask=np.array([0, 1, 1]))
    one = np.array([[[1.0, 0.0, 0.0]]])  # stratum 0 only
    both = np.array([[[1.0, 1.0, 0.0]]])
    var, df = _variance(fit, one, np.ones(1))
    assert df[0] == 14.0 and var[0] == 9.127555772777217
    var, df = _variance(fit, both, np.ones(1))
    v = np.array([9.127555772777217, 2.0])
    assert np.isclose(df[0], v.sum() ** 2 / (v**2 / [14.0, 42.0]).sum(), rtol=1e-12, atol=0)


@pytest.mark.parametrize("method", ["holm", "bonferroni"])
def test_holm_and_bonferroni(method):
    ours = _run(W2, "A:B", adjust=method)
    raw = 2 * stats.t.sf(np.abs(ours.t), ours.df)
    from statsmodels.stats.multitest import multipletests

    expected = multipletests(raw, method=method)[1]
    assert np.allclose(ours.p, expected, rtol=1e-12)
    assert (ours.adjust == method).all()


def test_unknown_effect_and_adjust():
    with pytest.raises(AppealInputError, match="effect: unknown factor C .expected factors of the design: A, B"):
        _run(W2, "A:C")
    with pytest.raises(AppealInputError, match="adjust: expected one of tukey, holm, bonferroni, none .got 'sidak'"):
        _run(W2, "A", adjust="sidak")


def test_holm_leaves_undefined_p_values_out_of_the_family():
    """As R: p.adjust(c(0.01, NA, 0.04), "holm") is 0.02, NA, 0.04 (n counts non-NA values only)."""
    from analysis.stats.posthoc import _adjust

    got = _adjust(np.array([0.01, np.nan, 0.04]), "holm")
    assert got[0] == pytest.approx(0.02) and np.isnan(got[1]) and got[2] == pytest.approx(0.04)
    assert _adjust(np.array([0.01, np.nan, 0.04]), "bonferroni")[[0, 2]] == pytest.approx([0.02, 0.08])
