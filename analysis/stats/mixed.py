"""Linear mixed models for incomplete designs, with a type-III Wald table.

When participants skipped trials, the repeated-measures ANOVA would have to drop them.
:func:`mixed_model_anova` fits the same fixed factorial (sum-to-zero contrasts) with a
random intercept per subject (and, optionally, per stimulus, crossed) using statsmodels'
``MixedLM`` (REML), then tests every term with a Wald χ² as ``car::Anova(lmer, type = 3)``.
"""

from __future__ import annotations

import itertools
import re
import warnings
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from appeal.errors import AppealInputError

__all__ = ["mixed_model_anova", "MIXED_COLUMNS"]

#: Columns of the mixed-model table.
MIXED_COLUMNS = ["effect", "chisq", "df", "p", "F", "method"]


def _terms(names: list[str]) -> list[tuple[str, ...]]:
    out = []
    for r in range(1, len(names) + 1):
        out.extend(itertools.combinations(names, r))
    return out


def _gls_cov(X: np.ndarray, groups: np.ndarray, sigma2: float, tau2: float) -> np.ndarray:
    """(Σ_i X_i' V_i^-1 X_i)^-1 with V_i = σ² I + τ² J (random intercept per group)."""
    info = np.zeros((X.shape[1], X.shape[1]))
    for g in pd.unique(groups):
        Xi = X[groups == g]
        s = Xi.sum(axis=0)
        info += (Xi.T @ Xi - tau2 / (sigma2 + len(Xi) * tau2) * np.outer(s, s)) / sigma2
    return np.linalg.inv(info)


def mixed_model_anova(
    data: pd.DataFrame,
    dv: str,
    subject: str,
    within: Sequence[str],
    between: Sequence[str] = (),
    stimulus: str | None = None,
    aggregate: str | None = "mean",
    reml: bool = True,
) -> pd.DataFrame:
    """Type-III Wald tests of a linear mixed model ``dv ~ between * within + (1 | subject)``.

    Parameters
    ----------
    data : DataFrame
        Long format; cells may be missing for some subjects.
    dv, subject, within, between
        As for :func:`analysis.stats.anova.rm_anova`.
    stimulus : str, optional
        Add a crossed random intercept per stimulus (trials are then not aggregated).
    aggregate : {"mean", None}
        Average repeated rows of a subject × cell before fitting (ignored with ``stimulus``).
    reml : bool
        REML (default, as lme4) or maximum likelihood.

    Returns
    -------
    DataFrame
        effect, chisq (Wald χ²), df, p, F (= χ²/df) and method; ``attrs`` carry the
        variance components (``sd_subject``, ``sd_stimulus``, ``sigma``) and ``n_obs``.
    """
    import statsmodels.formula.api as smf

    src = data.attrs.get("source", "<data>")
    within, between = list(within), list(between)
    factors = between + within
    need = [dv, subject, *factors] + ([stimulus] if stimulus else [])
    missing = [c for c in need if c not in data.columns]
    if missing:
        raise AppealInputError(f"{src}: columns: {', '.join(missing)} not found")
    df = data[need].copy()
    df[dv] = pd.to_numeric(df[dv], errors="coerce")
    df = df.dropna()
    if df.empty:
        raise AppealInputError(f"{src}: {dv}: no numeric values")
    alias = {f: f"f{i}" for i, f in enumerate(factors)}
    frame = pd.DataFrame({alias[f]: df[f].astype(str).to_numpy() for f in factors})
    frame["y"] = df[dv].to_numpy(float)
    frame["subj"] = df[subject].astype(str).to_numpy()
    if stimulus:
        frame["stim"] = df[stimulus].astype(str).to_numpy()
    elif aggregate == "mean":
        frame = frame.groupby(["subj", *alias.values()], as_index=False)["y"].mean()
    for f in factors:
        if frame[alias[f]].nunique() < 2:
            raise AppealInputError(f"{src}: {f}: a factor needs at least 2 levels")
    rhs = " * ".join(f"C({alias[f]}, Sum)" for f in factors)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if stimulus:
            frame["one"] = 1
            model = smf.mixedlm(f"y ~ {rhs}", frame, groups="one", re_formula="0",
                                vc_formula={"subj": "0 + C(subj)", "stim": "0 + C(stim)"})
        else:
            model = smf.mixedlm(f"y ~ {rhs}", frame, groups="subj")
        try:  # tight BFGS reaches lme4's optimum to ~1e-9; the default optimiser stops ~1e-5 off
            res = model.fit(reml=reml, method="bfgs", gtol=1e-10)
        except np.linalg.LinAlgError:
            res = model.fit(reml=reml)
    fe = res.fe_params
    if stimulus:
        cov = res.cov_params().loc[fe.index, fe.index].to_numpy()
    else:  # GLS covariance (X' V^-1 X)^-1 at the REML estimates, as lme4's vcov()
        cov = _gls_cov(model.exog, frame["subj"].to_numpy(), float(res.scale), float(res.cov_re.iloc[0, 0]))
    # group the fixed-effect columns by term: 'C(f0, Sum)[S.a1]:C(f1, Sum)[S.b1]' -> (A, B)
    names = {f"f{i}": f for i, f in enumerate(factors)}
    term_of = [":".join(names[a] for a in re.findall(r"C\((f\d+), Sum\)", col)) or "(Intercept)"
               for col in fe.index]
    rows = []
    for name in dict.fromkeys(term_of):
        sl = np.array([t == name for t in term_of])
        b = fe.to_numpy()[sl]
        V = cov[np.ix_(sl, sl)]
        chisq = float(b @ np.linalg.solve(V, b))
        k = len(b)
        rows.append({"effect": name, "chisq": chisq, "df": float(k), "p": stats.chi2.sf(chisq, k), "F": chisq / k,
                     "method": "Wald chi-square (type III), MixedLM " + ("REML" if reml else "ML")})
    order = ["(Intercept)"] + [":".join(t) for t in _terms(factors)]
    table = pd.DataFrame(rows).set_index("effect").reindex([o for o in order if o in {r["effect"] for r in rows}])
    table = table.reset_index()[MIXED_COLUMNS]
    if stimulus:
        vc = dict(zip(model.exog_vc.names, np.sqrt(res.vcomp)))
        table.attrs.update(sd_subject=float(vc.get("subj", np.nan)), sd_stimulus=float(vc.get("stim", np.nan)))
    else:
        table.attrs.update(sd_subject=float(np.sqrt(res.cov_re.iloc[0, 0])), sd_stimulus=float("nan"))
    table.attrs.update(sigma=float(np.sqrt(res.scale)), n_obs=int(len(frame)), converged=bool(res.converged))
    return table
