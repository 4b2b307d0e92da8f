"""Ratings of a reference (e.g. photographs of the real actors) beside the matched stylisation levels.

Thesis §6.4: at the end of Exp. 2 participants rated photographs of the two actors; their mean
realism and appeal are compared with the characters whose shape and material stylisation
match (s0/m0 … s4/m4; the realistic s4/m4 was less appealing than the photographs, an uncanny
valley, while s2/m2 and s3/m3 were the most appealing). :func:`reference_table` gives, per
condition, each participant's mean, then the mean, SD and n over participants, and a paired
t-test of the reference against each matched level (Holm-adjusted over the levels) — as R's
``t.test(paired = TRUE)`` and ``p.adjust(method = "holm")``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from scipy import stats

from analysis.stats.design import level_key
from appeal.errors import AppealInputError

__all__ = ["matched_levels", "reference_table"]


def matched_levels(data: pd.DataFrame, matched: Sequence[str], levels: Mapping[str, Sequence] | None = None,
                   source: str = "data") -> list[tuple]:
    """The level tuples of the ``matched`` factors at equal positions of their level orders.

    Orders come from ``levels`` (the study file's) or the sorted values (numbers as numbers).
    All matched factors need the same number of levels.
    """
    orders = []
    for f in matched:
        if f not in data.columns:
            raise AppealInputError(f"{source}: reference.matched: no column '{f}'")
        if levels and f in levels:
            order = [str(v) for v in levels[f]]
        else:
            values = pd.unique(data[f].dropna())
            try:
                order = [str(v) for v in sorted(values, key=float)]
            except (TypeError, ValueError):
                order = sorted(str(v) for v in values)
        orders.append(order)
    if len({len(o) for o in orders}) != 1:
        sizes = ", ".join(f"{f}: {len(o)}" for f, o in zip(matched, orders))
        raise AppealInputError(f"{source}: reference.matched: the factors need the same number of levels ({sizes})")
    return list(zip(*orders))


def reference_table(reference: pd.DataFrame, main: pd.DataFrame, dv: str, subject: str, matched: Sequence[str],
                    levels: Mapping[str, Sequence] | None = None, name: str = "reference",
                    source: str = "data") -> pd.DataFrame:
    """The reference's ratings beside each matched level of the main ratings.

    Parameters
    ----------
    reference, main : DataFrame
        The reference rows (e.g. the end-of-session photographs) and the main trials.
    dv : str
        The rating column.
    subject : str
        Participant column.
    matched : sequence of str
        Factors whose levels pair by position (``[shape, material]``: s0/m0, s1/m1, …).
    levels : mapping, optional
        Level orders (default: sorted values).
    name : str
        The reference's label.

    Returns
    -------
    DataFrame
        One row per condition (the reference first): ``condition``, the matched factors' levels,
        ``mean``, ``sd``, ``n`` (participants), and for the matched levels ``diff`` (reference −
        level, paired), ``t``, ``df``, ``p`` and ``p_holm``.
    """
    from statsmodels.stats.multitest import multipletests

    ref = reference.dropna(subset=[dv]).groupby(subject)[dv].mean()
    if ref.empty:
        raise AppealInputError(f"{source}: reference: no '{name}' ratings in {dv} (check reference.rows)")
    rows = [{"condition": name, **{f: "" for f in matched}, "mean": ref.mean(), "sd": ref.std(ddof=1), "n": len(ref)}]
    keys = {f: np.array([repr(level_key(v)) for v in main[f]]) for f in matched}  # each row's level, once
    tests = []
    for combo in matched_levels(main, matched, levels, source):
        sel = np.logical_and.reduce([keys[f] == repr(level_key(v)) for f, v in zip(matched, combo)])
        per = main.loc[sel].dropna(subset=[dv]).groupby(subject)[dv].mean()
        both = ref.index.intersection(per.index)
        row = {"condition": " / ".join(f"{f} {v}" for f, v in zip(matched, combo)), **dict(zip(matched, combo)),
               "mean": per.mean(), "sd": per.std(ddof=1), "n": len(per)}
        if len(both) >= 2:
            d = ref.loc[both].to_numpy() - per.loc[both].to_numpy()
            res = stats.ttest_rel(ref.loc[both], per.loc[both])
            row.update(diff=float(d.mean()), t=float(res.statistic), df=len(both) - 1, p=float(res.pvalue))
            tests.append(len(rows))
        rows.append(row)
    out = pd.DataFrame(rows)
    for col in ("diff", "t", "df", "p", "p_holm"):
        if col not in out:
            out[col] = np.nan
    ok = [i for i in tests if np.isfinite(out.loc[i, "p"])]
    if ok:
        out.loc[ok, "p_holm"] = multipletests(out.loc[ok, "p"].to_numpy(), method="holm")[1]
    return out
