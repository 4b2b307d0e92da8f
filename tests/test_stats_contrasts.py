"""Polynomial contrasts (per-subject contrast scores) against R, and the trend comparison."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis import compare_trends, polynomial_contrasts
from analysis.stats.anova import contr_poly

DATA = Path(__file__).parent / "data"

# ---- produced by: Rscript tests/r_reference/anova_reference.R (function poly_ref):
# per-subject level means of the factor %*% contr.poly(k)[, j], then
# car::Anova(lm(score ~ between, contrasts = contr.sum), type = 3), row "(Intercept)".
# {degree: (F, num_df, den_df, p, pes)}
R_POLY_W2_B = {
    1: (3.5283358320839566, 1, 7, 0.10240837550233201, 0.335127591706539),
    2: (2.3898989898989873, 1, 7, 0.16604049911273211, 0.25451807228915641),
    3: (5.2952270081490171, 1, 7, 0.054899117083324067, 0.43067338282078504),
}

R_POLY_W4_SHAPE = {
    1: (14.704464260598014, 1, 9, 0.0039992053155001785, 0.62032468225995896),
    2: (0.079903147699756899, 1, 9, 0.78382213659345146, 0.0087999999999998947),
}

R_POLY_OBK_HOUR = {
    1: (0.0011528411128768105, 1, 10, 0.97358238947372766, 0.00011527082239336402),
    2: (50.19380049638265, 1, 10, 3.3559586397352322e-05, 0.83386993481827165),
    3: (5.9780216884297523, 1, 10, 0.034552172859803949, 0.37414029127014192),
    4: (22.408191843164797, 1, 10, 0.00079965430808614786, 0.69143604035690454),
}

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
