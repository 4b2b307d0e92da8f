"""Statistics of window amplitudes: the rating-statistics rm-ANOVA and polynomial contrasts.

Per component, the design is every condition factor x cluster (hemisphere for N170/EPN),
as thesis §7.3 (stylisation 6 x emotion 3 x hemisphere 2). The ANOVA and the contrasts are
:func:`analysis.rm_anova` and :func:`analysis.polynomial_contrasts` (they agree with R's
afex/car/emmeans); this module only arranges the table and collects the results.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import pandas as pd

__all__ = ["component_anovas", "component_contrasts"]


def _within(data: pd.DataFrame, factors: Sequence[str]) -> list[str]:
    return [*factors, "cluster"] if data["cluster"].nunique() > 1 else list(factors)


def component_anovas(amplitudes: pd.DataFrame, factors: Sequence[str], dv: str = "mean_uV") -> pd.DataFrame:
    """rm-ANOVA of ``dv`` per component (factors x cluster); subjects missing a cell are dropped.

    Returns
    -------
    pandas.DataFrame
        ``component`` then the columns of :func:`analysis.rm_anova`.
    """
    from analysis.stats.anova import rm_anova

    out = []
    for comp, sub in amplitudes.groupby("component", sort=False):
        table = rm_anova(sub, dv=dv, subject="subject", within=_within(sub, factors), drop_incomplete=True)
        out.append(table.assign(component=comp))
    res = pd.concat(out, ignore_index=True)
    return res[["component", *[c for c in res.columns if c != "component"]]]


def component_contrasts(amplitudes: pd.DataFrame, factors: Sequence[str], levels: Mapping[str, Sequence],
                        dv: str = "mean_uV", max_degree: int = 2) -> pd.DataFrame:
    """Linear and quadratic (u-shaped) contrasts of every factor with 3+ levels, per component.

    Level order is the config's (``levels:``), else numeric order; contrasts are taken on
    level means over the other factors and clusters, as thesis §7.4.

    Returns
    -------
    pandas.DataFrame
        ``component`` then the columns of :func:`analysis.polynomial_contrasts`.
    """
    from analysis.stats.contrasts import polynomial_contrasts

    out = []
    for comp, sub in amplitudes.groupby("component", sort=False):
        within = _within(sub, factors)
        for f in factors:
            if len(levels[f]) < 3:
                continue
            table = polynomial_contrasts(sub, dv=dv, subject="subject", factor=f, within=within,
                                         levels=list(levels[f]), max_degree=max_degree, drop_incomplete=True)
            out.append(table.assign(component=comp))
    if not out:
        return pd.DataFrame(columns=["component", "factor", "contrast", "F", "num_df", "den_df", "p", "pes"])
    res = pd.concat(out, ignore_index=True)
    return res[["component", *[c for c in res.columns if c != "component"]]]
