"""Kenward–Roger inference (analysis.stats.kenward_roger) against R's pbkrtest 0.5.2, lmerTest
and emmeans (tests/r_reference/lmm_reference.R), against a literal n × n transcription of
pbkrtest's ``vcovAdj`` written here, and on a 10,000-row design where n × n would be 800 MB."""

from __future__ import annotations

import time
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from analysis.stats.kenward_roger import kenward_roger, kr_statistics
from analysis.stats.lmm import fit_lmm
from r_reference_numbers import r_reference

DATA = Path(__file__).parent / "data"
R = r_reference("lmm_reference")
DESIGNS = {
    "R_SMALL": ("lmm_small.csv", ["participant", "stimulus", "shape"]),
    "R_NESTED": ("lmm_nested.csv", ["lab", "participant", "group", "condition"]),
}
#: pbkrtest's own tolerances would be tighter; these absorb the two fits' θ differences (~1e-7).
DF_RTOL, F_RTOL, SE_RTOL = 1e-3, 1e-4, 1e-5


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b) / np.abs(b)))


_CACHE: dict = {}


def _fit(name: str, formula: str | None = None):
    key = (name, formula)
    if key not in _CACHE:
        csv, factors = DESIGNS[name]
        fit = fit_lmm(formula or R[name]["formula"], pd.read_csv(DATA / csv), factors=factors)
        _CACHE[key] = (fit, kenward_roger(fit))
    return _CACHE[key]


# ---------------------------------------------------------------------------- against R
@pytest.mark.parametrize("name", list(DESIGNS))
def test_coefficients_match_lmerTest_kr_summary(name):
    """summary(m, ddf = "Kenward-Roger"): SE = sqrt(diag Φ_A), df = get_Lb_ddf(e_j)."""
    fit, kr = _fit(name)
    r = R[name]
    assert fit.mm.columns == r["coef_names"]
    p = len(fit.beta)
    se = np.sqrt(np.diag(kr.vcov))
    df = [kr.ddf(e) for e in np.eye(p)]
    assert _rel(se, r["kr_coef_se"]) < SE_RTOL
    assert _rel(df, r["kr_coef_df"]) < DF_RTOL
    # the adjustment itself, Φ_A − Φ (tiny next to Φ: ~1e-5 of the SEs on R_SMALL, 0 on the
    # balanced R_NESTED), against R's KR minus unadjusted variances
    increment = np.diag(kr.vcov) - np.diag(fit.vcov)
    r_increment = np.array(r["kr_coef_se"]) ** 2 - np.array(r["se"]) ** 2
    if name == "R_SMALL":
        assert np.all(r_increment > 1e-7) and _rel(increment, r_increment) < 1e-4
    else:
        assert np.max(np.abs(increment)) < 1e-12 and np.max(np.abs(r_increment)) < 1e-12


@pytest.mark.parametrize("name", list(DESIGNS))
def test_type3_f_tests_match_lmerTest_kr_anova(name):
    """anova(m, type = 3, ddf = "Kenward-Roger"): F (scaled), den df and p per term."""
    fit, kr = _fit(name)
    r = R[name]
    terms = list(fit.mm.term_columns)
    assert terms == r["anova_terms"]
    p = len(fit.beta)
    for k, term in enumerate(terms):
        res = kr.test(np.eye(p)[fit.mm.term_columns[term]])
        assert res["num_df"] == len(fit.mm.term_columns[term])
        assert _rel(res["F"], r["kr_F"][k]) < F_RTOL, term
        assert _rel(res["den_df"], r["kr_dendf"][k]) < DF_RTOL, term
        assert _rel(res["p"], r["kr_p"][k]) < F_RTOL, term
        assert res["F"] == pytest.approx(res["F_scaling"] * res["F_unscaled"], rel=1e-14)


def _grid(name: str) -> tuple[list[str], np.ndarray]:
    """emmeans' reference-grid rows of the one within factor (sum coding; other factors
    averaged over, so their columns are 0)."""
    fit, _ = _fit(name)
    factor = {"R_SMALL": "shape", "R_NESTED": "condition"}[name]
    cols = fit.mm.term_columns[factor]
    levels = fit.mm.levels[factor]
    rows = np.zeros((len(levels), len(fit.beta)))
    rows[:, 0] = 1.0
    rows[:, cols] = np.vstack([np.eye(len(levels) - 1), -np.ones(len(levels) - 1)])
    return [str(v) for v in levels], rows


@pytest.mark.parametrize("name", list(DESIGNS))
def test_emmeans_kr_marginal_means_pairs_and_polynomials(name):
    """emmeans(m, ~f, lmer.df = "kenward-roger"): SE from Φ_A, df from Lb_ddf of each vector."""
    fit, kr = _fit(name)
    tag = {"R_SMALL": "shape", "R_NESTED": "condition"}[name]
    r = R[name]
    levels, grid = _grid(name)
    emm = r[f"emm_{tag}_kr"]
    assert levels == emm["levels"]
    res = [kr.contrast(l) for l in grid]
    assert _rel([x["estimate"] for x in res], emm["emmean"]) < 1e-8
    assert _rel([x["se"] for x in res], emm["SE"]) < SE_RTOL
    assert _rel([x["df"] for x in res], emm["df"]) < DF_RTOL
    pairs = r[f"pairs_{tag}_kr"]
    ij = [(i, j) for i in range(len(levels)) for j in range(i + 1, len(levels))]
    vecs = [grid[i] - grid[j] for i, j in ij]
    assert pairs["contrast"] == [f"{levels[i]} - {levels[j]}" for i, j in ij]
    res = [kr.contrast(v) for v in vecs]
    assert _rel([x["se"] for x in res], pairs["SE"]) < SE_RTOL
    assert _rel([x["df"] for x in res], pairs["df"]) < DF_RTOL
    assert _rel([x["t"] for x in res], pairs["t"]) < SE_RTOL
    poly = r[f"poly_{tag}_kr"]
    res = [kr.contrast(c @ grid) for c in (np.array([-1.0, 0, 1]), np.array([1.0, -2, 1]))]
    assert _rel([x["estimate"] for x in res], poly["estimate"]) < 1e-8
    assert _rel([x["se"] for x in res], poly["SE"]) < SE_RTOL
    assert _rel([x["df"] for x in res], poly["df"]) < DF_RTOL
    assert _rel([x["p"] for x in res], poly["p"]) < F_RTOL


# ---------------------------------------------------------------------------- against n × n
def _brute_force_vcovadj(fit) -> dict[str, np.ndarray]:
    """pbkrtest's get_SigmaG + vcovAdj_internal transcribed literally, with n × n matrices."""
    mm, n = fit.mm, fit.n
    G = []
    for blk, C in zip(mm.blocks, fit.random_covariances()):
        Z = np.zeros((n, blk.n_levels * blk.k))
        Z[np.arange(n)[:, None], blk.codes[:, None] * blk.k + np.arange(blk.k)] = blk.Xr
        for j in range(blk.k):
            for i in range(j, blk.k):
                E = np.zeros((blk.k, blk.k))
                E[i, j] = E[j, i] = 1.0
                G.append((C[i, j], Z @ np.kron(np.eye(blk.n_levels), E) @ Z.T))
    G.append((fit.sigma ** 2, np.eye(n)))
    Sigma = sum(g * Gi for g, Gi in G)
    SigmaInv = np.linalg.inv(Sigma)
    X, Phi, m = mm.X, fit.vcov, len(G)
    TT = SigmaInv @ X
    HH = [Gi @ SigmaInv for _, Gi in G]
    OO = [H @ X for H in HH]
    P = np.array([-(O.T @ TT) for O in OO])
    Q = np.array([[OO[r].T @ SigmaInv @ OO[s] for s in range(m)] for r in range(m)])
    K = np.array([[np.sum(HH[r].T * HH[s]) for s in range(m)] for r in range(m)])
    IE2 = np.array([[K[i, j] - 2 * np.sum(Phi * Q[i, j]) + np.sum((Phi @ P[i]) * (P[j] @ Phi))
                     for j in range(m)] for i in range(m)])
    W = 2 * np.linalg.inv(IE2)
    UU = sum(W[i, j] * (Q[i, j] - P[i] @ Phi @ P[j]) for i in range(m) for j in range(m))
    return {"P": P, "Q": Q, "K": K, "IE2": IE2, "W": W, "PhiA": Phi + 2 * Phi @ UU @ Phi,
            "Sigma_diag": np.diag(Sigma)}


def _kr_test_brute(L, beta, Phi, PhiA, P, W):
    """.KR_adjust transcribed literally (loops over i <= j with the factor e)."""
    Theta = L.T @ np.linalg.solve(L @ Phi @ L.T, L)
    A1 = A2 = 0.0
    for i in range(len(P)):
        for j in range(i, len(P)):
            e = 1 if i == j else 2
            ui, uj = Theta @ Phi @ P[i] @ Phi, Theta @ Phi @ P[j] @ Phi
            A1 += e * W[i, j] * np.trace(ui) * np.trace(uj)
            A2 += e * W[i, j] * np.sum(ui * uj.T)
    q = np.linalg.matrix_rank(L)
    ddf, scaling, _ = kr_statistics(A1, A2, q)
    F = scaling * float(beta @ L.T @ np.linalg.solve(L @ PhiA @ L.T, L @ beta)) / q
    return F, ddf


BRUTE_CASES = [
    ("R_SMALL", None),
    ("R_NESTED", None),
    # correlated slopes in two crossed terms: the cross-term traces with k_r, k_s > 1
    ("R_SMALL", "rating ~ shape + (1 + shape | participant) + (1 + shape | stimulus)"),
]


@pytest.mark.parametrize(("name", "formula"), BRUTE_CASES)
def test_q_sized_computation_equals_literal_n_by_n_pbkrtest(name, formula):
    fit, kr = _fit(name, formula)
    bf = _brute_force_vcovadj(fit)
    # V = Σ γ_i G_i with pbkrtest's γ (VarCorr elements and σ²) equals σ²(I + ZΛΛ'Z')
    assert bf["Sigma_diag"].shape == (fit.n,)
    scale = np.max(np.abs(bf["P"]))
    np.testing.assert_allclose(kr.P, bf["P"], rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(kr.Q, bf["Q"], rtol=0, atol=1e-9 * np.max(np.abs(bf["Q"])))
    np.testing.assert_allclose(kr.information, bf["IE2"], rtol=1e-8, atol=1e-9 * np.max(np.abs(bf["IE2"])))
    np.testing.assert_allclose(kr.W, bf["W"], rtol=1e-7, atol=1e-9 * np.max(np.abs(bf["W"])))
    np.testing.assert_allclose(kr.vcov, bf["PhiA"], rtol=1e-9, atol=1e-12)
    p = len(fit.beta)
    for term, cols in fit.mm.term_columns.items():
        L = np.eye(p)[cols]
        F, ddf = _kr_test_brute(L, fit.beta, fit.vcov, bf["PhiA"], bf["P"], bf["W"])
        res = kr.test(L)
        assert res["F"] == pytest.approx(F, rel=1e-8), term
        assert res["den_df"] == pytest.approx(ddf, rel=1e-7), term


# ---------------------------------------------------------------------------- the API's edges
def test_ml_fit_is_refitted_by_reml_and_rhs_shifts_the_hypothesis():
    fit, kr = _fit("R_SMALL")
    kr_ml = kenward_roger(fit_lmm(fit.mm, reml=False))
    np.testing.assert_allclose(kr_ml.vcov, kr.vcov, rtol=1e-5)
    L = np.eye(3)[1:]
    at_estimate = kr.test(L, rhs=L @ kr.beta)
    assert at_estimate["F"] == pytest.approx(0.0, abs=1e-20) and at_estimate["p"] == pytest.approx(1.0)
    one = kr.test(np.eye(3)[1])
    c = kr.contrast(np.eye(3)[1])
    assert one["F"] == pytest.approx(c["t"] ** 2 * one["F_scaling"], rel=1e-12)
    assert one["den_df"] == pytest.approx(c["df"], rel=1e-12)
    assert [v.name for v in kr.components][-1] == "Residual" and len(kr.gamma) == len(kr.components) == 8
    assert kr.gamma[-1] == pytest.approx(fit.sigma ** 2)


# ---------------------------------------------------------------------------- scale
@pytest.mark.slow
def test_big_crossed_design_stays_q_sized():
    """40 participants × 250 stimuli (10,000 rows, q = 370): an n × n float64 matrix would be
    800 MB; the whole computation must peak far below one."""
    rng = np.random.default_rng(30)
    n_p, n_s = 40, 250
    part, stim = np.repeat(np.arange(n_p), n_s), np.tile(np.arange(n_s), n_p)
    shape = stim % 3
    y = (4 + 0.3 * (shape - 1) + rng.normal(0, 0.7, n_p)[part] + rng.normal(0, 0.4, (n_p, 3))[part, shape]
         + rng.normal(0, 0.5, n_s)[stim] + rng.normal(0, 0.9, n_p * n_s))
    d = pd.DataFrame({"participant": part, "stimulus": stim, "shape": shape, "rating": y})
    fit = fit_lmm("rating ~ shape + (1 + shape | participant) + (1 | stimulus)", d,
                  factors=["participant", "stimulus", "shape"])
    n = fit.n
    t0 = time.perf_counter()
    kr = kenward_roger(fit)
    elapsed = time.perf_counter() - t0
    tracemalloc.start()
    try:
        kenward_roger(fit)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    print(f"\nkenward_roger on n = {n}, q = {fit.problem.q}: {elapsed:.3f} s, peak {peak / 1e6:.1f} MB "
          f"(one n x n float64: {8 * n * n / 1e6:.0f} MB)")
    assert n == 10_000 and fit.problem.q == 370
    assert peak < 0.05 * 8 * n * n
    res = kr.test(np.eye(3)[1:])
    assert np.isfinite(res["F"]) and 2 < res["den_df"] < n
    assert 0 < stats.f.sf(res["F"], 2, res["den_df"]) < 1
