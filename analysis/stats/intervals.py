"""Within-subject confidence intervals of cell means (Cousineau 2005 with Morey 2008's correction)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from analysis.stats.design import Design, prepare_design

__all__ = ["within_ci", "within_ci_from_design"]


def within_ci_from_design(design: Design, factors: Sequence[str] | None = None, conf: float = 0.95) -> pd.DataFrame:
    """Cousineau–Morey intervals for a prepared :class:`Design` (see :func:`within_ci`)."""
    wnames = list(design.within)
    factors = list(factors) if factors is not None else wnames + list(design.between)
    wf = [f for f in factors if f in design.within]
    bf = [f for f in factors if f in design.between]
    unknown = [f for f in factors if f not in design.within and f not in design.between]
    if unknown:
        raise ValueError(f"unknown factor(s) {', '.join(unknown)}")
    cube = design.Y.reshape(design.n, *design.shape)
    drop = tuple(1 + i for i, f in enumerate(wnames) if f not in wf)
    Yp = cube.mean(axis=drop) if drop else cube
    keep = [f for f in wnames if f in wf]
    Yp = Yp.reshape(design.n, -1)  # n × M plotted within cells
    M = Yp.shape[1]
    # subjects grouped by the plotted between factors
    if bf:
        bidx = [list(design.between).index(f) for f in bf]
        codes = np.array(np.unravel_index(design.group, design.between_shape))[bidx]
        gkey = np.ravel_multi_index(tuple(codes), tuple(design.between_shape[i] for i in bidx))
        glabels = list(pd.MultiIndex.from_product([design.between[f] for f in bf]))
    else:
        gkey = np.zeros(design.n, int)
        glabels = [()]
    import itertools

    wlabels = list(itertools.product(*(design.within[f] for f in keep)))
    rows = []
    for g, glab in enumerate(glabels):
        Yg = Yp[gkey == g]
        n = Yg.shape[0]
        if n == 0:
            continue
        norm = Yg - Yg.mean(axis=1, keepdims=True) + Yg.mean()
        sd = norm.std(axis=0, ddof=1) if n > 1 else np.full(M, np.nan)
        morey = np.sqrt(M / (M - 1)) if M > 1 else 1.0
        hw = stats.t.ppf(0.5 + conf / 2, n - 1) * sd / np.sqrt(n) * morey
        means = Yg.mean(axis=0)
        for j, wlab in enumerate(wlabels):
            lab = dict(zip(bf, glab if isinstance(glab, tuple) else (glab,)))
            lab.update(zip(keep, wlab))
            rows.append({**{f: lab[f] for f in factors}, "mean": means[j], "ci": hw[j],
                         "lower": means[j] - hw[j], "upper": means[j] + hw[j], "n": n})
    return pd.DataFrame(rows)


def within_ci(
    data: pd.DataFrame,
    dv: str,
    subject: str,
    within: Sequence[str],
    between: Sequence[str] = (),
    factors: Sequence[str] | None = None,
    aggregate: str | None = None,
    drop_incomplete: bool = False,
    conf: float = 0.95,
) -> pd.DataFrame:
    """Within-subject confidence intervals of cell means for error bars.

    Each subject's values (averaged over the within factors not in ``factors``) are
    normalised by removing the subject's mean and adding the grand mean (Cousineau 2005;
    per between group when between factors are plotted); the t interval of the normalised
    values is widened by ``sqrt(M / (M - 1))`` for M plotted within cells (Morey 2008).

    Parameters
    ----------
    data, dv, subject, within, between, aggregate, drop_incomplete
        As for :func:`analysis.stats.anova.rm_anova`.
    factors : sequence of str, optional
        The factors whose cells are plotted (default: all).
    conf : float
        Confidence level.

    Returns
    -------
    DataFrame
        One row per plotted cell: the factor columns, mean, ci (half-width), lower, upper, n.
    """
    design = prepare_design(data, dv, subject, within, between, aggregate, drop_incomplete)
    return within_ci_from_design(design, factors, conf)
