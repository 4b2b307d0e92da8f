"""Statistics at the edge of what a design can estimate: 2 or 3 participants, more effect df
than error df, no error variance. Defined numbers agree with R; undefined ones are NaN with the
reason in ``note`` (R gives NA there), never an exception."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis import rm_anova
from analysis.stats.posthoc import tukey_hsd
from analysis.stats.reporting import anova_text
from r_reference_numbers import r_reference

DATA = Path(__file__).parent / "data"

# ---- produced by: Rscript tests/r_reference/small_sample_reference.R > tests/r_reference/small_sample_reference.out
# (R 4.2.2, car 3.1.1, afex 1.2.1, emmeans 1.8.4.1): aov_ez(type = 3), summary(fit$Anova,
# multivariate = FALSE), anova(fit, es = c("pes", "ges")); pairs(emmeans(fit, ~effect,
# model = "univariate"), adjust = "tukey"). Data: tests/data/stats_small_*.csv from the same script.
_R = r_reference("small_sample_reference")

CASES = {
    "n2_two_within": ("stats_small_n2.csv", ["A", "B"], [], "R_N2"),
    "n3_five_levels": ("stats_small_n3_5levels.csv", ["A"], [], "R_N3_5LEVELS"),
    "zero_error_variance": ("stats_small_zero_error.csv", ["A"], [], "R_ZERO_ERROR"),
    "n3_two_groups": ("stats_small_n3_between.csv", ["A"], ["group"], "R_N3_BETWEEN"),
}
#: columns where car gives NA (singular error SSP matrix) but we give ε from the trace formula
TRACE_EPSILON = {"gg_eps", "hf_eps", "p_gg", "p_hf"}


def _table(case):
    fname, within, between, _ = CASES[case]
    return rm_anova(pd.read_csv(DATA / fname), "y", "id", within, between).set_index("effect")


@pytest.mark.parametrize("case", list(CASES))
def test_agrees_with_r(case):
    table = _table(case)
    ref = _R[CASES[case][3]]
    assert list(table.index) == list(ref)
    for effect, values in ref.items():
        for col, expected in values.items():
            got = table.loc[effect, col]
            if math.isnan(expected):
                if col in TRACE_EPSILON and not math.isnan(table.loc[effect, "gg_eps"]):
                    assert "trace formula" in table.loc[effect, "note"]
                else:
                    assert math.isnan(got), (effect, col, got)
                continue
            assert got == pytest.approx(expected, rel=1e-6, abs=1e-12), (effect, col)


def test_two_participants_epsilon_is_the_lower_bound_and_hf_undefined():
    """With 1 error df the error SSP matrix has rank 1: GG ε = 1/d, HF's formula is 0/0."""
    row = _table("n2_two_within").loc["A"]
    assert row.gg_eps == pytest.approx(1 / 2, rel=1e-12)
    assert math.isnan(row.hf_eps) and math.isnan(row.p_hf)
    assert row.note == ("Mauchly undefined (1 error df < 2 effect df); ε from the trace formula (car: NA); "
                        "HF ε undefined (0/0 with 1 error df)")
    assert _table("n2_two_within").loc["B"].note == ""  # 1-df effect: nothing to correct


def test_five_levels_three_participants_trace_epsilon():
    """4 effect df, 2 error df: GG ε from the eigenvalues of the subjects' contrast covariance."""
    row = _table("n3_five_levels").loc["A"]
    wide = pd.read_csv(DATA / "stats_small_n3_5levels.csv").pivot(index="id", columns="A", values="y").to_numpy()
    from scipy.linalg import helmert

    lam = np.linalg.eigvalsh(np.cov(wide @ helmert(5, full=False).T, rowvar=False))
    assert row.gg_eps == pytest.approx(lam.sum() ** 2 / (4 * (lam**2).sum()), rel=1e-10)
    assert math.isnan(row.mauchly_W) and "2 error df < 4 effect df" in row.note


def test_zero_error_variance_gives_infinite_f_as_r():
    row = _table("zero_error_variance").loc["A"]
    assert math.isinf(row.F) and row.p == 0 and row.pes == 1 and math.isnan(row.gg_eps)
    assert row.note.startswith("no error variance")
    assert "F(2, 4) = ∞, p < 0.0001" in anova_text(_table("zero_error_variance").reset_index())


@pytest.mark.parametrize("case", ["n2_two_within", "zero_error_variance", "n3_two_groups"])
def test_text_has_no_nan(case):
    text = anova_text(_table(case).reset_index())
    assert "nan" not in text.lower(), text


@pytest.mark.parametrize(("fname", "within", "effect", "name"), [
    ("stats_small_n2.csv", ["A", "B"], "A", "R_PAIRS_N2_A"),
    ("stats_small_n2.csv", ["A", "B"], "A:B", "R_PAIRS_N2_AB"),
    ("stats_small_n3_5levels.csv", ["A"], "A", "R_PAIRS_N3_5LEVELS"),
])
def test_tukey_equals_emmeans_on_small_samples(fname, within, effect, name):
    ours = tukey_hsd(pd.read_csv(DATA / fname), "y", "id", effect, within)
    by_pair = {(r.a, r.b): r for r in ours.itertuples()}
    assert len(ours) == len(_R[name])
    for label, estimate, se, df, t_ratio, p in _R[name]:
        a, b = (x.replace(" ", ":") for x in label.split(" - "))
        row, sign = (by_pair[(a, b)], 1) if (a, b) in by_pair else (by_pair[(b, a)], -1)
        assert sign * row.diff == pytest.approx(estimate, rel=1e-6, abs=1e-12)
        assert row.se == pytest.approx(se, rel=1e-6)
        assert row.df == pytest.approx(df, rel=1e-6)
        assert row.p == pytest.approx(p, rel=1e-6)
