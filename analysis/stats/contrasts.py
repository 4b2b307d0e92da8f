"""Polynomial (trend) contrasts on an ordered within factor via per-subject contrast scores.

For each subject the factor's level means (averaged over the other within cells) are
combined with R's orthonormal ``contr.poly`` weights; the contrast is tested against zero
with F(1, n − rank(X)) — the intercept of the between-subject model (type III, sum
contrasts) when there are between factors, a one-sample test otherwise. This is the
"linear vs u-shaped (quadratic)" analysis of thesis §7.4.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from scipy import stats

from analysis.stats.anova import _between_matrix, contr_poly
from analysis.stats.design import Design, prepare_design
from appeal.errors import AppealInputError

__all__ = ["polynomial_contrasts", "contrasts_from_design", "compare_trends", "CONTRAST_NAMES", "CONTRAST_COLUMNS"]

CONTRAST_NAMES = ("linear", "quadratic", "cubic", "quartic", "quintic")
#: Columns of the contrast table.
CONTRAST_COLUMNS = ["factor", "contrast", "F", "num_df", "den_df", "p", "pes", "estimate"]


def _name(degree: int) -> str:
    return CONTRAST_NAMES[degree - 1] if degree <= len(CONTRAST_NAMES) else f"degree {degree}"


def contrasts_from_design(design: Design, factor: str, max_degree: int | None = None) -> pd.DataFrame:
    """Polynomial contrasts of ``factor`` for a prepared :class:`Design` (see :func:`polynomial_contrasts`)."""
    if factor not in design.within:
        raise AppealInputError(
            f"{design.source}: factor: '{factor}' is not a within factor (expected one of: {', '.join(design.within)})")
    names = list(design.within)
    k = len(design.within[factor])
    axis = names.index(factor)
    Ycube = design.Y.reshape(design.n, *design.shape)
    other = tuple(a + 1 for a in range(len(names)) if a != axis)
    level_means = Ycube.mean(axis=other) if other else Ycube  # n × k
    P = contr_poly(k)
    if max_degree is not None:
        P = P[:, :max_degree]
    scores = level_means @ P  # n × m
    X, _ = _between_matrix(design)
    XtX_inv = np.linalg.inv(X.T @ X)
    B = XtX_inv @ X.T @ scores
    resid = scores - X @ B
    dfe = design.n - X.shape[1]
    sse = (resid**2).sum(axis=0)
    ssh = B[0] ** 2 / XtX_inv[0, 0]
    F = ssh / (sse / dfe)
    return pd.DataFrame({
        "factor": factor, "contrast": [_name(j + 1) for j in range(P.shape[1])], "F": F, "num_df": 1.0,
        "den_df": float(dfe), "p": stats.f.sf(F, 1, dfe), "pes": ssh / (ssh + sse), "estimate": B[0],
    })[CONTRAST_COLUMNS]


def polynomial_contrasts(
    data: pd.DataFrame,
    dv: str,
    subject: str,
    factor: str,
    within: Sequence[str] | None = None,
    between: Sequence[str] = (),
    aggregate: str | None = None,
    drop_incomplete: bool = False,
    levels: Sequence | None = None,
    max_degree: int | None = None,
) -> pd.DataFrame:
    """Linear, quadratic, cubic … contrasts of an ordered within factor.

    Parameters
    ----------
    data, dv, subject, between, aggregate, drop_incomplete
        As for :func:`analysis.stats.anova.rm_anova`.
    factor : str
        The ordered within factor (levels equally spaced in the order given).
    within : sequence of str, optional
        All within factors of the design (default: just ``factor``); the contrast uses the
        factor's level means averaged over the other within cells.
    levels : sequence, optional
        Level order of ``factor`` (default: categorical order, else sorted values).
    max_degree : int, optional
        Highest polynomial degree (default: k − 1).

    Returns
    -------
    DataFrame
        Columns factor, contrast (linear, quadratic, …), F, num_df (1), den_df (n − rank X),
        p, pes (partial η² = SS/(SS + SSE)) and estimate (mean contrast score, orthonormal
        weights). Equal to ``car::Anova(lm(score ~ between), type = 3)`` on the scores.
    """
    within = list(within) if within else [factor]
    if factor not in within:
        within = [factor, *within]
    lv: Mapping[str, Sequence] = {factor: levels} if levels is not None else {}
    design = prepare_design(data, dv, subject, within, between, aggregate, drop_incomplete, levels=lv)
    return contrasts_from_design(design, factor, max_degree)


def compare_trends(table: pd.DataFrame) -> dict:
    """Which of the linear and the quadratic ("u-shaped") contrast explains more variance.

    Parameters
    ----------
    table : DataFrame
        Rows of :func:`polynomial_contrasts` for one factor (linear and quadratic present).

    Returns
    -------
    dict
        ``factor``, ``winner`` ("linear" or "quadratic"), ``shape`` ("linear" or
        "u-shaped"), ``pes_linear``, ``pes_quadratic`` and ``text`` (a sentence in the style
        of thesis §7.4).
    """
    rows = table.set_index("contrast")
    if not {"linear", "quadratic"} <= set(rows.index):
        raise ValueError("compare_trends needs the linear and the quadratic contrast (a factor with >= 3 levels)")
    lin, quad = rows.loc["linear"], rows.loc["quadratic"]
    from analysis.stats.reporting import format_contrast

    winner = "quadratic" if quad.pes > lin.pes else "linear"
    shape = "u-shaped" if winner == "quadratic" else "linear"
    first, second = (quad, lin) if winner == "quadratic" else (lin, quad)
    text = (f"For {table['factor'].iloc[0]}, the {winner} contrast ({format_contrast(first)}) explained more "
            f"variance than the {'linear' if winner == 'quadratic' else 'u-shaped'} contrast "
            f"({format_contrast(second)}), indicating a {shape} form.")
    return {"factor": str(table["factor"].iloc[0]), "winner": winner, "shape": shape,
            "pes_linear": float(lin.pes), "pes_quadratic": float(quad.pes), "text": text}
