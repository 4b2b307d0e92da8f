"""Pairwise comparisons of estimated marginal means with Tukey HSD (or Holm / Bonferroni).

The comparisons match ``emmeans(<afex model>, ~effect, model = "univariate")`` followed by
``pairs(adjust = "tukey")``: marginal means weight every cell equally; the standard error
of a difference comes from the error strata it touches (for a within main effect just that
effect's own error term, ``MS_error`` with its df; for cells of an interaction or of mixed
between × within effects several strata, combined with Satterthwaite df as emmeans does);
p from the studentized range distribution with as many means as the family has. Between
factors get the usual between-subjects comparison from the between-subject error.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from analysis.stats.anova import AnovaFit, fit_design
from analysis.stats.design import prepare_design
from appeal.errors import AppealInputError

__all__ = ["tukey_hsd", "pairwise_comparisons", "marginal_means", "ADJUSTMENTS", "POSTHOC_COLUMNS"]

ADJUSTMENTS = ("tukey", "holm", "bonferroni", "none")
#: Columns of the comparison table.
POSTHOC_COLUMNS = ["effect", "a", "b", "diff", "se", "df", "t", "q", "p", "adjust"]


def _effect_factors(fit: AnovaFit, effect: str | Sequence[str]) -> tuple[list[str], list[int], list[int]]:
    names = [x for x in (effect.split(":") if isinstance(effect, str) else list(effect)) if x]
    w, b = list(fit.design.within), list(fit.design.between)
    unknown = [x for x in names if x not in w and x not in b]
    if unknown or not names:
        raise AppealInputError(
            f"{fit.design.source}: effect: unknown factor {', '.join(unknown) or '(empty)'} "
            f"(expected factors of the design: {', '.join(b + w)})")
    if len(set(names)) != len(names):
        raise AppealInputError(f"{fit.design.source}: effect: a factor is named twice ({':'.join(names)})")
    return names, [w.index(x) for x in names if x in w], [b.index(x) for x in names if x in b]


def _weights(fit: AnovaFit, names: list[str]) -> tuple[list[str], np.ndarray]:
    """Labels and weights (L × G × C) of the marginal means of the effect's level combinations."""
    d = fit.design
    factors = {**d.between, **d.within}
    combos = list(itertools.product(*(factors[f] for f in names)))
    cells = d.cell_labels()
    groups = d.group_labels()
    wpos = {f: i for i, f in enumerate(d.within)}
    bpos = {f: i for i, f in enumerate(d.between)}
    W = np.zeros((len(combos), d.n_groups, len(cells)))
    for k, combo in enumerate(combos):
        want = dict(zip(names, combo))
        wc = np.array([all(c[wpos[f]] == v for f, v in want.items() if f in wpos) for c in cells], float)
        wg = np.array([all(g[bpos[f]] == v for f, v in want.items() if f in bpos) for g in groups], float)
        W[k] = np.outer(wg / wg.sum(), wc / wc.sum())
    return [":".join(c) for c in combos], W


def _group_means(fit: AnovaFit) -> tuple[np.ndarray, np.ndarray]:
    d = fit.design
    n_g = np.bincount(d.group, minlength=d.n_groups).astype(float)
    sums = np.zeros((d.n_groups, d.Y.shape[1]))
    np.add.at(sums, d.group, d.Y)
    return sums / n_g[:, None], n_g


def _variance(fit: AnovaFit, T: np.ndarray, n_g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Variance and Satterthwaite df of linear functions with Q-rotated weights T (P × G × C)."""
    strata = sorted(fit.error_ms)
    onehot = (fit.mask[:, None] == np.array(strata)[None, :]).astype(float)  # C × S
    A = np.einsum("pgc,g->pc", T * T, 1 / n_g) @ onehot  # P × S
    ms = np.array([fit.error_ms[s] for s in strata])
    dfs = np.array([fit.error_df[s] for s in strata])
    v = A * ms
    var = v.sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        df = var**2 / (v**2 / dfs).sum(axis=1)
    # A function of one stratum alone (every within main effect, every between one) has that
    # stratum's error df, a count: give it exactly, not var² / (var² / df) rounded (14.000000000000002).
    # Strata contributing under 1e-12 of the variance change the Satterthwaite df by < 1e-24.
    used = v > 1e-12 * var[:, None]
    alone = used.sum(axis=1) == 1
    df[alone] = dfs[used[alone].argmax(axis=1)]
    return var, df


def marginal_means(fit: AnovaFit, effect: str | Sequence[str]) -> pd.DataFrame:
    """Estimated marginal means of an effect's levels (cells weighted equally, as emmeans).

    Returns
    -------
    DataFrame
        Columns: one per factor of the effect, ``level`` (labels joined by ':'), ``emmean``,
        ``se`` and ``df`` (Satterthwaite over the error strata).
    """
    names, _, _ = _effect_factors(fit, effect)
    labels, W = _weights(fit, names)
    ybar, n_g = _group_means(fit)
    est = np.einsum("lgc,gc->l", W, ybar)
    var, df = _variance(fit, W @ fit.Q, n_g)
    out = pd.DataFrame([lab.split(":") for lab in labels], columns=names)
    out["level"] = labels
    out["emmean"], out["se"], out["df"] = est, np.sqrt(var), df
    return out


def _adjust(p: np.ndarray, method: str) -> np.ndarray:
    """Holm or Bonferroni adjusted p values (statsmodels' ``multipletests``), others unchanged.

    Undefined (NaN) p values stay NaN and do not count in the family, as R's ``p.adjust``.
    """
    if method not in ("holm", "bonferroni"):
        return p
    from statsmodels.stats.multitest import multipletests

    out = np.array(p, dtype=float)
    ok = ~np.isnan(out)
    if ok.any():
        out[ok] = multipletests(out[ok], method=method)[1]
    return out


def pairwise_comparisons(fit: AnovaFit, effect: str | Sequence[str], adjust: str = "tukey") -> pd.DataFrame:
    """All pairwise differences of an effect's marginal means from a fitted design.

    Parameters
    ----------
    fit : AnovaFit
        From :func:`analysis.stats.anova.fit_design`.
    effect : str or sequence of str
        ``"shape"`` or ``"shape:material"`` (cells of the interaction).
    adjust : {"tukey", "holm", "bonferroni", "none"}
        Multiplicity adjustment.

    Returns
    -------
    DataFrame
        Columns effect, a, b (level labels, ':'-joined for interactions), diff (a − b),
        se, df, t, q (= |t|·√2, the studentized range statistic), p, adjust.
    """
    if adjust not in ADJUSTMENTS:
        raise AppealInputError(f"{fit.design.source}: adjust: expected one of {', '.join(ADJUSTMENTS)} (got {adjust!r})")
    names, _, _ = _effect_factors(fit, effect)
    labels, W = _weights(fit, names)
    ybar, n_g = _group_means(fit)
    est = np.einsum("lgc,gc->l", W, ybar)
    T = W @ fit.Q
    i, j = np.triu_indices(len(labels), k=1)
    var, df = _variance(fit, T[i] - T[j], n_g)
    diff = est[i] - est[j]
    se = np.sqrt(var)
    t = diff / se
    q = np.abs(t) * np.sqrt(2)
    if adjust == "tukey":
        p = stats.studentized_range.sf(q, len(labels), df)
    else:
        p = _adjust(2 * stats.t.sf(np.abs(t), df), adjust)
    return pd.DataFrame({
        "effect": ":".join(names), "a": [labels[k] for k in i], "b": [labels[k] for k in j], "diff": diff,
        "se": se, "df": df, "t": t, "q": q, "p": np.minimum(p, 1.0), "adjust": adjust,
    })[POSTHOC_COLUMNS]


def tukey_hsd(
    data: pd.DataFrame,
    dv: str,
    subject: str,
    effect: str | Sequence[str],
    within: Sequence[str],
    between: Sequence[str] = (),
    aggregate: str | None = None,
    drop_incomplete: bool = False,
    adjust: str = "tukey",
) -> pd.DataFrame:
    """Tukey HSD for a within effect, a between effect or the cells of an interaction.

    Equal to ``pairs(emmeans(<afex model>, ~effect, model = "univariate"), adjust = "tukey")``
    (see the module docstring); ``adjust="holm"`` or ``"bonferroni"`` adjusts two-sided t-test
    p values instead.

    Parameters
    ----------
    data, dv, subject, within, between, aggregate, drop_incomplete
        As for :func:`analysis.stats.anova.rm_anova`.
    effect : str or sequence of str
        ``"A"`` or ``"A:B"``.
    adjust : {"tukey", "holm", "bonferroni", "none"}

    Returns
    -------
    DataFrame
        See :func:`pairwise_comparisons`.
    """
    design = prepare_design(data, dv, subject, within, between, aggregate, drop_incomplete)
    return pairwise_comparisons(fit_design(design), effect, adjust)
