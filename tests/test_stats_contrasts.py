"""Polynomial contrasts (per-subject contrast scores) against R, and the trend comparison."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis import compare_trends, polynomial_contrasts
from analysis.stats.anova import contr_poly
from r_reference_numbers import r_reference

DATA = Path(__file__).parent / "data"

_R = r_reference("anova_reference")  # tests/r_reference/anova_reference.out
# ---- produced by: Rscript tests/r_reference/anova_reference.R (function poly_ref):
# per-subject level means of the factor %*% contr.poly(k)[, j], then
# car::Anova(lm(score ~ between, contrasts = contr.sum), type = 3), row "(Intercept)".
# {degree: (F, num_df, den_df, p, pes)}
R_POLY_W2_B = _R["R_POLY_W2_B"]

R_POLY_W4_SHAPE = _R["R_POLY_W4_SHAPE"]

R_POLY_OBK_HOUR = _R["R_POLY_OBK_HOUR"]

CASES = {
    "within2": ("stats_within2_likert.csv", "rating", "B", ["A", "B"], [], R_POLY_W2_B),
    "within4_repeated_trials": ("stats_within4_likert_reps.csv", "appeal", "shape",
                                ["character", "shape", "material", "expression"], [], R_POLY_W4_SHAPE),
    "mixed": ("stats_obk_long.csv", "value", "hour", ["phase", "hour"], ["treatment", "gender"], R_POLY_OBK_HOUR),
}


@pytest.mark.parametrize("case", list(CASES))
def test_contrasts_agree_with_r(case):
    fname, dv, factor, within, between, ref = CASES[case]
    t = polynomial_contrasts(pd.read_csv(DATA / fname), dv, "id", factor, within=within, between=between,
                             aggregate="mean")
    assert list(t.columns[:7]) == ["factor", "contrast", "F", "num_df", "den_df", "p", "pes"]
    assert len(t) == len(ref)
    for j, (F, num_df, den_df, p, pes) in ref.items():
        row = t.iloc[j - 1]
        assert row.F == pytest.approx(F, rel=1e-6)
        assert (row.num_df, row.den_df) == (num_df, den_df)
        assert row.p == pytest.approx(p, rel=1e-6)
        assert row.pes == pytest.approx(pes, rel=1e-6)
    assert list(t.contrast[:2]) == ["linear", "quadratic"]


def test_contr_poly_matches_r():
    # R: contr.poly(4)
    r = np.array([[-0.6708203932499369, 0.5, -0.2236067977499790],
                  [-0.2236067977499789, -0.5, 0.6708203932499369],
                  [0.2236067977499789, -0.5, -0.6708203932499369],
                  [0.6708203932499369, 0.5, 0.2236067977499790]])
    assert np.allclose(contr_poly(4), r, atol=1e-14)


def test_u_shape_detected_on_exact_quadratic():
    rng = np.random.default_rng(0)
    rows = []
    for s in range(12):
        for lv in range(5):
            rows.append((f"s{s}", lv, (lv - 2) ** 2 + 0.3 * lv + rng.normal(0, 0.5) + s * 0.1))
    df = pd.DataFrame(rows, columns=["id", "level", "amp"])
    t = polynomial_contrasts(df, "amp", "id", "level")
    cmp = compare_trends(t)
    assert cmp["winner"] == "quadratic" and cmp["shape"] == "u-shaped"
    assert cmp["pes_quadratic"] > cmp["pes_linear"]
    assert "the quadratic contrast (F(1, 11) = " in cmp["text"] and "u-shaped form" in cmp["text"]
