"""Cronbach's alpha, Cousineau–Morey intervals and the mixed model against R."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis import cronbach_alpha, mixed_model_anova, within_ci
from appeal.errors import AppealInputError
from r_reference_numbers import r_reference

DATA = Path(__file__).parent / "data"

_R = r_reference("reliability_intervals_mixed_reference")  # tests/r_reference/reliability_intervals_mixed_reference.out
# ---- produced by: Rscript tests/r_reference/reliability_intervals_mixed_reference.R
# alpha = k/(k-1) (1 - sum(item variances) / var(row sums)); Feldt CI with qf(.975 / .025, n-1, (n-1)(k-1))
R_ALPHA = _R["R_ALPHA"]  # alpha, Feldt 95% CI low, high

# Cousineau normalisation (y - subject mean + grand mean) of the subject x plotted-cell means,
# half-width = qt(.975, n-1) * sd / sqrt(n) * sqrt(M / (M-1)); {cell: (mean, half-width)}
R_CM_A = _R["R_CM_A"]
R_CM_AB = _R["R_CM_AB"]

# lmer(rating ~ A * B + (1 | id), REML, contr.sum) without s03/a2/b4 and s05/a1 (all of a1);
# car::Anova(fit, type = 3): {term: (Chisq, Df, p)}
R_LMER = _R["R_LMER"]
R_LMER_SIGMA = _R["R_LMER_SIGMA"]
R_LMER_SD_ID = _R["R_LMER_SD_ID"]


def test_cronbach_alpha_matches_r_and_pingouin():
    import pingouin as pg

    df = pd.read_csv(DATA / "stats_scales.csv")
    res = cronbach_alpha(df, ["appeal", "reassurance", "attractiveness"])
    assert res["alpha"] == pytest.approx(R_ALPHA[0], rel=1e-9)
    assert res["ci_low"] == pytest.approx(R_ALPHA[1], rel=1e-9)
    assert res["ci_high"] == pytest.approx(R_ALPHA[2], rel=1e-9)
    alpha, ci = pg.cronbach_alpha(df[["appeal", "reassurance", "attractiveness"]])
    assert res["alpha"] == pytest.approx(alpha, rel=1e-9)
    assert (res["n"], res["k"]) == (48, 3)


def test_cronbach_alpha_averages_repeated_rows():
    df = pd.read_csv(DATA / "stats_scales.csv")
    doubled = pd.concat([df, df], ignore_index=True)
    res = cronbach_alpha(doubled, ["appeal", "reassurance", "attractiveness"], by=["id", "stimulus"])
    assert res["alpha"] == pytest.approx(R_ALPHA[0], rel=1e-12) and res["n"] == 48


def test_cronbach_alpha_bad_input():
    df = pd.read_csv(DATA / "stats_scales.csv")
    with pytest.raises(AppealInputError, match="at least 2 scales expected"):
        cronbach_alpha(df, ["appeal"])
    with pytest.raises(AppealInputError, match="column.s. realism not found"):
        cronbach_alpha(df, ["appeal", "realism"])


@pytest.mark.parametrize("factors,ref", [(["A"], R_CM_A), (["A", "B"], R_CM_AB)])
def test_cousineau_morey_matches_r(factors, ref):
    df = pd.read_csv(DATA / "stats_within2_likert.csv")
    ci = within_ci(df, "rating", "id", ["A", "B"], factors=factors)
    got = {":".join(r[f] for f in factors): (r["mean"], r["ci"]) for _, r in ci.iterrows()}
    assert set(got) == set(ref)
    for cell, (mean, hw) in ref.items():
        assert got[cell][0] == pytest.approx(mean, rel=1e-12)
        assert got[cell][1] == pytest.approx(hw, rel=1e-9)
    assert np.allclose(ci.upper - ci.lower, 2 * ci.ci)


def test_mixed_model_agrees_with_lmer():
    """statsmodels REML (tight BFGS) vs lme4 REML."""
    df = pd.read_csv(DATA / "stats_within2_likert.csv")
    df = df[~(((df.id == "s03") & (df.A == "a2") & (df.B == "b4")) | ((df.id == "s05") & (df.A == "a1")))]
    t = mixed_model_anova(df, "rating", "id", ["A", "B"]).set_index("effect")
    for term, (chisq, dof, p) in R_LMER.items():
        assert t.loc[term, "chisq"] == pytest.approx(chisq, rel=1e-6)
        assert t.loc[term, "df"] == dof
        assert t.loc[term, "p"] == pytest.approx(p, rel=1e-5)
    assert t.attrs["sigma"] == pytest.approx(R_LMER_SIGMA, rel=1e-6)
    assert t.attrs["sd_subject"] == pytest.approx(R_LMER_SD_ID, rel=1e-6)
    assert t.attrs["n_obs"] == 91
