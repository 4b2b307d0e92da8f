"""Type-III F tests of a linear mixed model, as ``lmerTest::anova(m, type = 3)`` and
``afex::mixed(method = "S")`` report them.

The hypothesis of each term is lmerTest's (``get_contrasts_type3``, SAS's type III): the design
is re-coded with treatment contrasts, each term's contrast is the coefficient map of its cell
indicators, orthogonalised against the terms that contain it, and mapped back into the fitted
(sum-to-zero) coefficients. With sum-to-zero coding its row space is that of the term's own
coefficients (so F is the same), but its basis sets the Satterthwaite df of a multi-df term,
which is why it is followed exactly.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.stats.formula import ModelMatrices, fixed_matrix, term_matrix, term_name
from analysis.stats.lmm import LmmFit

__all__ = ["type3_contrasts", "lmm_anova", "inference", "LMM_ANOVA_COLUMNS"]

#: Columns of :func:`lmm_anova`'s table.
LMM_ANOVA_COLUMNS = ["effect", "F", "num_df", "den_df", "p", "method"]


def _contains(inner: tuple, outer: tuple, factors: set[str]) -> bool:
    a, b = set(inner), set(outer)
    return a < b and {v for v in a if v not in factors} == {v for v in b if v not in factors}


def type3_contrasts(mm: ModelMatrices) -> dict[str, np.ndarray]:
    """Each fixed term's type-III hypothesis matrix over the model's coefficients (lmerTest).

    With a single term lmerTest uses the type-I (sequential) hypothesis, rows of the unit upper
    factor of X'X's LDL' decomposition, and so does this.
    """
    if len(mm.formula.fixed) <= 1 or mm.X.shape[1] <= 1:
        C = np.linalg.cholesky(mm.X.T @ mm.X)
        U = (C / np.diag(C)[None, :]).T
        return {name: U[cols] for name, cols in mm.term_columns.items()}
    Xt, names_t, map_t = fixed_matrix(mm, coding="treatment")
    data, f = mm.data, mm.formula
    parts, rd_names = ([np.ones((len(data), 1))], ["(Intercept)"]) if f.intercept else ([], [])
    for t in f.fixed:
        m, nm = term_matrix(data, t, mm.levels, mm.factors, coding="indicator")
        parts.append(m)
        rd_names += nm
    rdX = np.hstack(parts)
    L = np.linalg.lstsq(Xt, rdX, rcond=None)[0].T  # rows: rdX columns, columns: Xt columns
    L[np.abs(L) < 1e-10] = 0.0
    factors = set(mm.factors)
    order = sorted(range(len(f.fixed)), key=lambda i: -len(f.fixed[i]))  # stable: highest order first
    for i in order:
        t = f.fixed[i]
        outer = [c for u in f.fixed if _contains(t, u, factors) for c in map_t[term_name(u)]]
        if outer:
            A, B = L[:, outer], L[:, map_t[term_name(t)]]
            L[:, map_t[term_name(t)]] = B - A @ np.linalg.lstsq(A, B, rcond=None)[0]
    L[np.abs(L) < 1e-10] = 0.0
    row = {n: i for i, n in enumerate(rd_names)}
    L = L[[row[n] for n in names_t]]  # rows in the order of Xt's columns
    to_fit = np.linalg.lstsq(Xt, mm.X, rcond=None)[0]
    to_fit[np.abs(to_fit) < 1e-10] = 0.0
    out = {}
    for t in f.fixed:
        Lt = L[:, map_t[term_name(t)]].T
        Lt = Lt[np.abs(Lt).sum(axis=1) > 1e-8]
        out[term_name(t)] = Lt @ to_fit
    return out


def lmm_anova(fit: LmmFit, ddf: str = "satterthwaite", tests=None) -> pd.DataFrame:
    """Type-III F tests of every fixed term.

    Parameters
    ----------
    fit : LmmFit
        A REML (or ML) fit from :func:`analysis.stats.lmm.fit_lmm`.
    ddf : {"satterthwaite", "kenward-roger"}
        The denominator degrees of freedom (lmerTest's default is Satterthwaite; Kenward–Roger as
        pbkrtest, REML fits only).
    tests : Satterthwaite or KenwardRoger, optional
        Prepared df machinery (computed when not given).

    Returns
    -------
    DataFrame
        ``effect, F, num_df, den_df, p, method``.
    """
    if tests is None:
        tests = inference(fit, ddf)
    rows = []
    for name, L in type3_contrasts(fit.mm).items():
        res = tests.test(L)
        rows.append({"effect": name, "F": res["F"], "num_df": res["num_df"], "den_df": res["den_df"],
                     "p": res["p"], "method": _METHOD[ddf]})
    return pd.DataFrame(rows, columns=LMM_ANOVA_COLUMNS)


_METHOD = {"satterthwaite": "LMM type III, Satterthwaite", "kenward-roger": "LMM type III, Kenward-Roger"}


def inference(fit: LmmFit, ddf: str = "satterthwaite"):
    """The df machinery for ``ddf``: :class:`~analysis.stats.satterthwaite.Satterthwaite` or
    :class:`~analysis.stats.kenward_roger.KenwardRoger`."""
    if ddf == "satterthwaite":
        from analysis.stats.satterthwaite import satterthwaite

        return satterthwaite(fit)
    if ddf == "kenward-roger":
        if not fit.reml:
            raise ValueError("Kenward-Roger dfs need a REML fit")
        from analysis.stats.kenward_roger import kenward_roger

        return kenward_roger(fit)
    raise ValueError(f"ddf must be 'satterthwaite' or 'kenward-roger', not {ddf!r}")


def coefficient_table(fit: LmmFit, tests) -> pd.DataFrame:
    """Fixed effects with SE, df, t and p (``summary(lmerTest::lmer(...))$coefficients``); ``tests``
    is :func:`inference`'s df machinery. The two-sided p is ``2 * stdtr(df, -|t|)``
    (:func:`scipy.special.stdtr`, the t distribution's CDF, without loading scipy.stats)."""
    from scipy import special

    eye = np.eye(len(fit.beta))
    se = np.sqrt(np.diag(tests.vcov))
    df = np.array([tests.ddf(e) for e in eye])
    t = fit.beta / se
    return pd.DataFrame({"term": fit.mm.columns, "estimate": fit.beta, "se": se, "df": df, "t": t,
                         "p": 2 * special.stdtr(df, -np.abs(t))})
