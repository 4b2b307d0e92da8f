"""Estimated marginal means and their contrasts on a mixed model, as R's emmeans computes them.

The reference grid is every combination of the model's factor levels (covariates at their
mean); a marginal mean averages the grid's predictions over the factors it does not name with
equal weights (emmeans' default). Standard errors come from the covariance of β̂ the inference
uses (the fit's own under Satterthwaite; Kenward–Roger's adjusted one under KR) and every
estimate has its own df (``emm_options(lmer.df = "satterthwaite" | "kenward-roger")``).
Pairwise differences are adjusted with Tukey's studentized range over the family of means,
polynomial contrasts use emmeans' integer coefficients (``poly.emmc``) unadjusted.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from analysis.stats.anova import contr_poly
from analysis.stats.formula import FormulaError, fixed_matrix
from analysis.stats.lmm import LmmFit

__all__ = ["emmeans", "emm_pairs", "emm_poly", "poly_coefficients", "EMM_COLUMNS", "EMM_CONTRAST_COLUMNS"]

#: Columns of :func:`emmeans`' table (after the factor columns).
EMM_COLUMNS = ["emmean", "se", "df", "ci_low", "ci_high"]
#: Columns of the contrast tables.
EMM_CONTRAST_COLUMNS = ["contrast", "estimate", "se", "df", "t", "p", "adjust"]


def _grid(fit: LmmFit, specs: Sequence[str]) -> tuple[pd.DataFrame, np.ndarray, np.ndarray]:
    """The EMMs' cells (first factor fastest, as emmeans) and their weight rows over β."""
    mm = fit.mm
    fixed_vars = list(dict.fromkeys(v for t in mm.formula.fixed for v in t))
    unknown = [s for s in specs if s not in mm.levels or s not in fixed_vars]
    if unknown:
        raise FormulaError(f"emmeans: {', '.join(unknown)} is not a factor of the fixed part of '{mm.formula.text}'")
    factors = [v for v in fixed_vars if v in mm.levels]
    covariates = {v: float(mm.data[v].astype(float).mean()) for v in fixed_vars if v not in mm.levels}
    combos = list(itertools.product(*[range(len(mm.levels[f])) for f in reversed(factors)]))
    grid = pd.DataFrame([[mm.levels[f][c[len(factors) - 1 - i]] for i, f in enumerate(factors)] for c in combos],
                        columns=factors)
    for v, mean in covariates.items():
        grid[v] = mean
    Xg = fixed_matrix(mm, grid)[0]
    cells = list(itertools.product(*[range(len(mm.levels[s])) for s in reversed(specs)]))
    labels = pd.DataFrame([[mm.levels[s][c[len(specs) - 1 - i]] for i, s in enumerate(specs)] for c in cells],
                          columns=list(specs))
    W = np.empty((len(cells), Xg.shape[1]))
    for k, row in labels.iterrows():
        mask = np.ones(len(grid), bool)
        for s in specs:
            mask &= grid[s].astype(str).to_numpy() == str(row[s])
        W[k] = Xg[mask].mean(axis=0)
    return labels, W, Xg


def _estimates(tests, W: np.ndarray, fit: LmmFit) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    est = W @ fit.beta
    se = np.sqrt(np.einsum("ij,jk,ik->i", W, tests.vcov, W))
    df = np.array([tests.ddf(w) for w in W])
    return est, se, df


def emmeans(fit: LmmFit, specs: str | Sequence[str], tests, level: float = 0.95) -> pd.DataFrame:
    """Estimated marginal means of one factor or a combination (``emmeans(m, ~ a * b)``).

    Parameters
    ----------
    fit : LmmFit
        The fitted model.
    specs : str or sequence of str
        Factor(s) whose cells get a mean; ``"shape:material"`` is the same as ``["shape", "material"]``.
    tests : Satterthwaite or KenwardRoger
        Gives the dfs (and, for KR, the adjusted covariance).
    level : float
        Confidence level of the intervals.

    Returns
    -------
    DataFrame
        One row per cell (first factor varying fastest): the factor columns, ``emmean, se, df,
        ci_low, ci_high``.
    """
    specs = specs.split(":") if isinstance(specs, str) else list(specs)
    labels, W, _ = _grid(fit, specs)
    est, se, df = _estimates(tests, W, fit)
    tq = stats.t.ppf(0.5 + level / 2, df)
    out = labels.copy()
    out["emmean"], out["se"], out["df"] = est, se, df
    out["ci_low"], out["ci_high"] = est - tq * se, est + tq * se
    out.attrs["weights"] = W
    return out


def _labels(emm: pd.DataFrame, specs: list[str]) -> list[str]:
    return [" ".join(str(v) for v in row) for row in emm[specs].itertuples(index=False)]


def _contrast_table(fit: LmmFit, tests, C: np.ndarray, names: list[str], adjust: str, family: int) -> pd.DataFrame:
    est, se, df = _estimates(tests, C, fit)
    t = est / se
    if adjust == "tukey":
        p = stats.studentized_range.sf(np.abs(t) * np.sqrt(2), family, df)
    else:
        from analysis.stats.posthoc import _adjust

        p = _adjust(2 * stats.t.sf(np.abs(t), df), adjust)
    return pd.DataFrame({"contrast": names, "estimate": est, "se": se, "df": df, "t": t,
                         "p": np.minimum(p, 1.0), "adjust": adjust})[EMM_CONTRAST_COLUMNS]


def emm_pairs(fit: LmmFit, emm: pd.DataFrame, tests, adjust: str = "tukey") -> pd.DataFrame:
    """All pairwise differences of the means in ``emm`` (``pairs(emm)``: "a - b" for a before b)."""
    specs = [c for c in emm.columns if c not in EMM_COLUMNS]
    W, labels = emm.attrs["weights"], _labels(emm, specs)
    i, j = np.triu_indices(len(W), k=1)
    return _contrast_table(fit, tests, W[i] - W[j], [f"{labels[a]} - {labels[b]}" for a, b in zip(i, j)],
                           adjust, len(W))


def poly_coefficients(k: int, max_degree: int | None = None) -> np.ndarray:
    """emmeans' ``poly.emmc``: orthogonal polynomial coefficients scaled to integers (k × degree)."""
    M = contr_poly(k)[:, : (max_degree or k - 1)].copy()
    for j in range(M.shape[1]):
        con = M[:, j]
        con = con / con[con > 0.01].min()
        z = np.max(np.abs(con - np.round(con)))
        while z > 0.05:
            con = con / z
            z = np.max(np.abs(con - np.round(con)))
        M[:, j] = np.round(con)
    return M


def emm_poly(fit: LmmFit, emm: pd.DataFrame, tests, max_degree: int | None = None) -> pd.DataFrame:
    """Linear, quadratic … contrasts over the means of one ordered factor (``contrast(emm, "poly")``)."""
    from analysis.stats.contrasts import CONTRAST_NAMES

    W = emm.attrs["weights"]
    P = poly_coefficients(len(W), max_degree)
    names = [CONTRAST_NAMES[d] if d < len(CONTRAST_NAMES) else f"degree {d + 1}" for d in range(P.shape[1])]
    return _contrast_table(fit, tests, P.T @ W, names, "none", len(W))
