"""The audit's report: what differs between levels, as a figure, Markdown and an HTML page.

:func:`plot_flags` draws every factor × measure as a cell coloured by its range of level means
relative to the threshold (flagged cells outlined); :func:`findings_markdown` lists the flagged
measures with their tests in the thesis's style; :func:`write_report` writes ``report.md`` and
``report.html`` beside the audit's tables and figures.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.confounds.design_tests import flagged
from appeal.figures import plain_text

__all__ = ["describe_test", "findings_markdown", "plot_flags", "write_report"]


def _level(v: object) -> str:
    return f"{v:g}" if isinstance(v, (float, np.floating)) else str(v)


def describe_test(row: Mapping) -> str:
    """A :func:`~analysis.confounds.design_tests.design_tests` row's test as text:
    ``F(4, 196) = 12.30, p < 0.0001, ηp² = 0.201`` (GG-corrected ``F*`` when Mauchly's test is
    significant), ``η²`` for a between-items test, or why there is no test."""
    from analysis.stats.reporting import format_df, format_effect, format_es, format_f, format_p

    row = dict(row)
    if not isinstance(row.get("F"), float) or math.isnan(row["F"]):
        return str(row.get("test", "no test"))
    if str(row["test"]).startswith("rm-ANOVA"):
        return format_effect({**row, "pes": row["effect_size"], "note": ""})
    return (f"F({format_df(row['num_df'])}, {format_df(row['den_df'])}) = {format_f(row['F'])}, {format_p(row['p'])}, "
            f"η² = {format_es(row['effect_size'])}")


def findings_markdown(tests: pd.DataFrame, paired: Mapping[str, str] | None = None) -> str:
    """Markdown: per factor, the flagged measures (largest relative range first) with their level
    means, range against the threshold and test; factors with none say so."""
    lines = []
    for factor, rows in tests.groupby("factor", sort=False):
        also = [f for f, g in (paired or {}).items() if g == factor]
        name = factor + (f" (= {', '.join(also)}: the same split of the images)" if also else "")
        hits = flagged(rows)
        if hits.empty:
            lines.append(f"- **{name}**: no measure differs beyond its threshold.")
            continue
        lines.append(f"- **{name}**: {len(hits)} of {len(rows)} measures differ beyond their thresholds:")
        for _, r in hits.iterrows():
            lines.append(f"    - `{r['measure']}`: {r['lowest_mean']:.4g} at {_level(r['lowest_level'])} → "
                         f"{r['highest_mean']:.4g} at {_level(r['highest_level'])} (range {r['range']:.3g}, threshold "
                         f"{r['threshold']:g}, ×{r['relative_range']:.1f}); {describe_test(r)}")
    return "\n".join(lines)


@plain_text
def plot_flags(tests: pd.DataFrame, path: str | Path) -> Path:
    """Heat map: a row per factor, a column per measure, colour = range of level means / threshold
    (capped at 4), the ratio written in the cell, flagged cells (ratio > 1) outlined in black."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    factors = list(dict.fromkeys(tests["factor"]))
    measures = list(dict.fromkeys(tests["measure"]))
    ratio = np.full((len(factors), len(measures)), np.nan)
    for _, r in tests.iterrows():
        ratio[factors.index(r["factor"]), measures.index(r["measure"])] = r["relative_range"]
    fig, ax = plt.subplots(figsize=(0.55 * len(measures) + 2.2, 0.5 * len(factors) + 2.3))
    im = ax.imshow(np.minimum(ratio, 4.0), cmap="Reds", vmin=0, vmax=4, aspect="auto")
    for i in range(len(factors)):
        for j in range(len(measures)):
            v = ratio[i, j]
            if np.isnan(v):
                continue
            ax.text(j, i, f"{v:.1f}" if v < 100 else ">99", ha="center", va="center", fontsize=6.5,
                    color="white" if v > 2.5 else "black")
            if v > 1:
                ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, lw=1.4, ec="black"))
    ax.set_xticks(range(len(measures)))
    ax.set_xticklabels(measures, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(len(factors)))
    ax.set_yticklabels(factors, fontsize=8)
    cb = fig.colorbar(im, ax=ax, fraction=0.03, pad=0.02)
    cb.set_label("range of level means / threshold", fontsize=7)
    cb.ax.tick_params(labelsize=7)
    ax.set_title("What differs between levels (outlined: beyond the threshold)", fontsize=9)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def write_report(out: str | Path, table: pd.DataFrame, tests: pd.DataFrame, *, source: str,
                 figures: Sequence[Path] = (), tables: Sequence[Path] = (), paired: Mapping[str, str] | None = None,
                 thresholds_set: Mapping[str, float] | None = None) -> tuple[Path, Path]:
    """Write ``out/report.md`` and ``out/report.html``: the set, the findings, the figures and tables.

    Parameters
    ----------
    out : path
        The audit's folder (links are relative to it).
    table : DataFrame
        The audit table (one row per image).
    tests : DataFrame
        :func:`~analysis.confounds.design_tests.design_tests` of ``table`` (may be empty: no factors).
    source : str
        What was audited (shown in the title).
    figures, tables : sequences of paths
        Files in ``out`` to show and link.
    paired : mapping, optional
        Factors left out because they repeat another (``{paired: kept}``).
    thresholds_set : mapping, optional
        The thresholds the user set (listed; the others are the defaults).

    Returns
    -------
    (Path, Path)
        The Markdown and HTML files.
    """
    import os

    from appeal.atomic import atomic_write_text
    from appeal.report import ReportSection, write_index_html
    from analysis.stats.reporting import markdown_table

    out = Path(out)
    masks = table["mask"].value_counts().to_dict() if "mask" in table else {}
    warned = table[table.get("warning", pd.Series("", index=table.index)).fillna("") != ""]
    intro = [f"{len(table)} images from `{source}`; face mask: "
             + ", ".join(f"{n} {k}" for k, n in masks.items()) + "."]
    if not tests.empty:
        n_flag = int(tests["flagged"].astype(bool).sum())
        intro.append(f"{tests['factor'].nunique()} factors × {tests['measure'].nunique()} measures tested; "
                     f"**{n_flag} differ between levels beyond their thresholds**. A measure is flagged when the range "
                     f"of its level means exceeds its threshold (in its own units); the test says whether the "
                     f"difference holds across the items.")
    else:
        intro.append("No factor with two levels or more: the measures per image only (no tests).")
    if thresholds_set:
        intro.append("Thresholds set: " + ", ".join(f"`{k}` = {v:g}" for k, v in thresholds_set.items())
                     + "; the others are the defaults (analysis.confounds.DEFAULT_THRESHOLDS).")
    if len(warned):
        intro.append(f"{len(warned)} images with a warning (e.g. {warned['file'].iloc[0]}: {warned['warning'].iloc[0]}).")
    sections = []
    findings = findings_markdown(tests, paired) if not tests.empty else ""
    if findings:
        sections.append(ReportSection("What differs between levels", findings,
                                      figures=[f for f in figures if Path(f).name == "flags.png"]))
    sections.append(ReportSection("Measures per level", figures=[f for f in figures if Path(f).name != "flags.png"]))
    sections.append(ReportSection("Tables", tables=list(tables)))
    html = write_index_html(out / "report.html", f"Stimulus audit: {source}", sections, "\n\n".join(intro))
    md = [f"# Stimulus audit: {source}", "", *("\n\n".join(intro).splitlines()), ""]
    for sec in sections:
        md += [f"## {sec.title}", ""]
        if sec.text:
            md += [sec.text, ""]
        md += [f"![{Path(f).name}]({os.path.relpath(f, out)})" for f in sec.figures]
        md += [f"- [{os.path.relpath(t, out)}]({os.path.relpath(t, out)})" for t in sec.tables]
        md.append("")
    if not tests.empty:
        cols = ["factor", "measure", "range", "threshold", "flagged", "test", "p"]
        md += ["## All tests", "", markdown_table(tests[cols]), ""]
    mdp = atomic_write_text(out / "report.md", "\n".join(md))
    return mdp, html
