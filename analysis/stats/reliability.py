"""Cronbach's alpha between rating scales, with Feldt's confidence interval."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from appeal.errors import AppealInputError

__all__ = ["cronbach_alpha"]


def cronbach_alpha(
    data: pd.DataFrame,
    items: Sequence[str],
    by: Sequence[str] | None = None,
    ci: float = 0.95,
) -> pd.Series:
    """Cronbach's alpha of ``items`` (e.g. the appeal, reassurance and attractiveness scales).

    Observations are rows (after averaging rows that share the ``by`` columns, e.g.
    ``[subject, stimulus]`` when stimuli were rated repeatedly); rows with a missing item
    are left out.

    Parameters
    ----------
    data : DataFrame
        One column per item.
    items : sequence of str
        At least two item (scale) columns.
    by : sequence of str, optional
        Columns identifying an observation; repeated rows are averaged.
    ci : float
        Confidence level of Feldt's (1965) F-based interval.

    Returns
    -------
    Series
        alpha, ci_low, ci_high, n (observations), k (items).
    """
    items = list(items)
    src = data.attrs.get("source", "<data>")
    if len(items) < 2:
        raise AppealInputError(f"{src}: items: at least 2 scales expected for Cronbach's alpha (got {len(items)})")
    missing = [c for c in items + list(by or []) if c not in data.columns]
    if missing:
        raise AppealInputError(f"{src}: items: column(s) {', '.join(missing)} not found")
    df = data[list(by or []) + items].copy()
    for c in items:
        df[c] = pd.to_numeric(df[c], errors="coerce")
    if by:
        df = df.groupby(list(by), sort=False)[items].mean()
    X = df[items].dropna().to_numpy(float)
    n, k = X.shape
    if n < 3:
        raise AppealInputError(f"{src}: items: at least 3 complete observations expected (got {n})")
    total_var = X.sum(axis=1).var(ddof=1)
    if total_var == 0:
        raise AppealInputError(f"{src}: items: the summed scales have zero variance; alpha is undefined")
    alpha = k / (k - 1) * (1 - X.var(axis=0, ddof=1).sum() / total_var)
    df1, df2 = n - 1, (n - 1) * (k - 1)
    a = (1 - ci) / 2
    low = 1 - (1 - alpha) * stats.f.ppf(1 - a, df1, df2)
    high = 1 - (1 - alpha) * stats.f.ppf(a, df1, df2)
    return pd.Series({"alpha": alpha, "ci_low": low, "ci_high": high, "n": n, "k": k})
