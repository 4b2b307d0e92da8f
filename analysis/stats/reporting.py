"""Results as text in the thesis's style, and tables as Markdown / HTML.

``F*(1.98, 39.6) = 178.67, p < 0.0001, ε = 0.495`` when Mauchly's test is significant
(Greenhouse–Geisser applied, marked with an asterisk as thesis §6.2 does), otherwise
``F(4, 80) = 44.23, p < 0.0001``; partial η² appended as in thesis §7.4.
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping

import pandas as pd

__all__ = ["format_p", "format_f", "format_es", "format_df", "format_effect", "format_contrast", "format_comparison", "anova_text",
           "markdown_table", "html_table", "sphericity_corrected"]


def format_p(p: float) -> str:
    """``p < 0.0001`` or ``p = 0.021`` (three decimals)."""
    if p is None or (isinstance(p, float) and math.isnan(p)):
        return "p = n/a"
    if p < 0.0001:
        return "p < 0.0001"
    if p < 0.001:
        return f"p = {p:.4f}"
    return f"p = {p:.3f}"


def format_f(F: float) -> str:
    """An F value with two decimals; ``∞`` with no error variance, ``n/a`` when undefined."""
    if math.isnan(F):
        return "n/a"
    return "∞" if math.isinf(F) else f"{F:.2f}"


def format_es(x: float) -> str:
    """An effect size with three decimals, ``n/a`` when undefined (0/0)."""
    return "n/a" if math.isnan(x) else f"{x:.3f}"


def format_df(x: float) -> str:
    """Degrees of freedom: integers as is, corrected ones with up to two decimals."""
    if abs(x - round(x)) < 1e-9:
        return str(int(round(x)))
    return f"{x:.2f}".rstrip("0").rstrip(".")


def sphericity_corrected(row: Mapping, alpha: float = 0.05) -> bool:
    """True when the Greenhouse–Geisser correction applies to this ANOVA row.

    That is when Mauchly's test is significant at ``alpha``, or when it is undefined for a
    multi-df effect (more df than error df) so that sphericity cannot be checked.
    """
    gg, mp = row.get("gg_eps"), row.get("mauchly_p")
    if gg is None or math.isnan(gg):
        return False
    if mp is None or math.isnan(mp):
        return True
    return mp < alpha


def format_effect(row: Mapping, alpha: float = 0.05, pes: bool = True) -> str:
    """One ANOVA row as ``F*(df1, df2) = F, p …, ε = …`` or ``F(df1, df2) = F, p …``.

    Parameters
    ----------
    row : mapping
        A row of :func:`analysis.stats.anova.rm_anova` (a Series or dict).
    alpha : float
        Significance level of Mauchly's test.
    pes : bool
        Append the partial η².
    """
    row = dict(row)
    if sphericity_corrected(row, alpha):
        e = row["gg_eps"]
        text = (f"F*({format_df(row['num_df'] * e)}, {format_df(row['den_df'] * e)}) = {format_f(row['F'])}, "
                f"{format_p(row['p_gg'])}, ε = {e:.3f}")
    else:
        text = (f"F({format_df(row['num_df'])}, {format_df(row['den_df'])}) = {format_f(row['F'])}, "
                f"{format_p(row['p'])}")
    if pes:
        text += f", ηp² = {format_es(row['pes'])}"
    if row.get("note"):
        text += f" ({row['note']})"
    return text


def format_contrast(row: Mapping) -> str:
    """A contrast row as ``F(1, 32) = 68.50, p < 0.0001, ηp² = 0.682``."""
    row = dict(row)
    return (f"F({format_df(row['num_df'])}, {format_df(row['den_df'])}) = {format_f(row['F'])}, "
            f"{format_p(row['p'])}, ηp² = {format_es(row['pes'])}")


def format_comparison(row: Mapping) -> str:
    """A post-hoc row as ``s2 vs s3: Δ = 0.41, p = 0.003``."""
    row = dict(row)
    return f"{row['a']} vs {row['b']}: Δ = {row['diff']:.2f}, {format_p(row['p'])}"


def anova_text(table: pd.DataFrame, alpha: float = 0.05, title: str | None = None) -> str:
    """Markdown bullet list: every effect with its test, significant ones in bold.

    Parameters
    ----------
    table : DataFrame
        From :func:`analysis.stats.anova.rm_anova`.
    alpha : float
        Significance level (for Mauchly and for the bold marking).
    title : str, optional
        A line put before the list.
    """
    lines = [title, ""] if title else []
    for _, row in table.iterrows():
        corrected = sphericity_corrected(row, alpha)
        p = row["p_gg"] if corrected else row["p"]
        name = f"**{row['effect']}**" if p < alpha else row["effect"]
        lines.append(f"- {name}: {format_effect(row, alpha)}")
    return "\n".join(lines)


def _fmt(v) -> str:
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        if v != 0 and (abs(v) < 1e-3 or abs(v) >= 1e5):
            return f"{v:.3e}"
        return f"{v:.4g}" if abs(v) < 1 else f"{v:.4f}".rstrip("0").rstrip(".")
    return str(v)


def markdown_table(df: pd.DataFrame) -> str:
    """A DataFrame as a GitHub-flavoured Markdown table (numbers rounded for reading)."""
    cols = [str(c) for c in df.columns]
    lines = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
    for row in df.itertuples(index=False):
        lines.append("| " + " | ".join(_fmt(v) for v in row) + " |")
    return "\n".join(lines)


def html_table(df: pd.DataFrame) -> str:
    """A DataFrame as an HTML table (numbers rounded for reading)."""
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in df.columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(_fmt(v))}</td>" for v in row) + "</tr>"
                   for row in df.itertuples(index=False))
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
