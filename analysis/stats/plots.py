"""Figures in the style of thesis Figs. 6.4, 6.12 and 6.16 (PNG + SVG, matplotlib Agg)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from appeal.figures import plain_text

__all__ = ["save_figure", "interaction_plot", "bar_plot", "realism_vs_appeal_plot", "realism_vs_appeal_figure", "reference_plot"]

#: Node markers of :func:`realism_vs_appeal_plot`, one per ``point`` level (cycled beyond ten).
MARKERS = ["o", "s", "^", "D", "v", "P", "X", "<", ">", "*"]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


@plain_text
def save_figure(fig, stem: str | Path) -> list[Path]:
    """Save ``fig`` as ``stem.png`` (150 dpi) and ``stem.svg``; close it; return both paths."""
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.with_suffix(".png"), stem.with_suffix(".svg")]
    fig.savefig(paths[0], dpi=150, bbox_inches="tight")
    fig.savefig(paths[1], bbox_inches="tight")
    _plt().close(fig)
    return paths


@plain_text
def interaction_plot(ci: pd.DataFrame, x: str, trace: str | None, ylabel: str, stem: str | Path,
                     title: str | None = None, ylim: tuple[float, float] | None = None,
                     x_levels: Sequence[str] | None = None, trace_levels: Sequence[str] | None = None,
                     interval: str = "95% within-subject CI") -> list[Path]:
    """Mean rating vs the levels of ``x``, one line per level of ``trace``, 95% CI bars.

    Parameters
    ----------
    ci : DataFrame
        From :func:`analysis.stats.intervals.within_ci` with ``factors=[trace, x]``.
    x, trace : str
        Factor on the x axis; factor drawn as separate lines (None: one line).
    ylabel : str
        The rating scale.
    stem : path
        Output path without suffix.
    interval : str
        What the bars are (named on the y axis).
    """
    plt = _plt()
    xl = list(x_levels) if x_levels is not None else list(dict.fromkeys(ci[x]))
    tl = list(trace_levels) if trace_levels is not None else (list(dict.fromkeys(ci[trace])) if trace else [None])
    fig, ax = plt.subplots(figsize=(5.2, 3.8))
    colors = plt.get_cmap("viridis")(np.linspace(0, 0.9, len(tl)))
    pos = np.arange(len(xl))
    offset = np.linspace(-0.08, 0.08, len(tl)) if len(tl) > 1 else [0.0]
    for t, col, off in zip(tl, colors, offset):
        part = ci if t is None else ci[ci[trace] == t]
        part = part.set_index(x).reindex(xl)
        ax.errorbar(pos + off, part["mean"], yerr=part["ci"], marker="o", ms=4, capsize=3, lw=1.5, color=col,
                    label=str(t) if t is not None else None)
    ax.set_xticks(pos, xl)
    ax.set_xlabel(x)
    ax.set_ylabel(f"mean {ylabel} ({interval})")
    if ylim:
        ax.set_ylim(*ylim)
    if trace:
        ax.legend(title=trace, fontsize=8, title_fontsize=8, frameon=False, loc="best")
    ax.set_title(title or f"{ylabel}: {x}" + (f" × {trace}" if trace else ""), fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    return save_figure(fig, stem)


@plain_text
def bar_plot(ci: pd.DataFrame, factor: str, ylabel: str, stem: str | Path, title: str | None = None,
             ylim: tuple[float, float] | None = None) -> list[Path]:
    """Bar chart of the cell means of one factor with 95% within-subject CI bars."""
    plt = _plt()
    levels = list(dict.fromkeys(ci[factor]))
    part = ci.set_index(factor).reindex(levels)
    fig, ax = plt.subplots(figsize=(4.2, 3.4))
    ax.bar(np.arange(len(levels)), part["mean"], yerr=part["ci"], capsize=4, color="#5b8bd0", edgecolor="#2a4d80")
    ax.set_xticks(np.arange(len(levels)), levels)
    ax.set_xlabel(factor)
    ax.set_ylabel(f"mean {ylabel}")
    if ylim:
        ax.set_ylim(*ylim)
    ax.set_title(title or f"{ylabel} by {factor}", fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    return save_figure(fig, stem)


@plain_text
def realism_vs_appeal_plot(x_ci: pd.DataFrame, y_ci: pd.DataFrame, line: str, point: str, stem: str | Path,
                           x_label: str = "realism", y_label: str = "appeal",
                           lim: tuple[float, float] | None = (1, 7)) -> list[Path]:
    """Realism-vs-appeal diagram (thesis Fig. 6.16) saved as ``stem.png`` and ``stem.svg``.

    See :func:`realism_vs_appeal_figure` for the parameters.
    """
    return save_figure(realism_vs_appeal_figure(x_ci, y_ci, line, point, x_label, y_label, lim), stem)


@plain_text
def realism_vs_appeal_figure(x_ci: pd.DataFrame, y_ci: pd.DataFrame, line: str, point: str,
                             x_label: str = "realism", y_label: str = "appeal",
                             lim: tuple[float, float] | None = (1, 7)):
    """Realism-vs-appeal diagram (thesis Fig. 6.16): one graph per ``line`` level, nodes = ``point`` levels.

    Parameters
    ----------
    x_ci, y_ci : DataFrame
        :func:`analysis.stats.intervals.within_ci` tables of the two scales with
        ``factors=[line, point]``.
    line, point : str
        E.g. ``"shape"`` (one graph per shape level, told apart by colour) and ``"material"``
        (its nodes, told apart by marker).
    x_label, y_label : str
        The two scales' names.
    lim : (float, float) or None
        Both axes' range (the rating scale).

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = _plt()
    key = [line, point]
    merged = x_ci.merge(y_ci, on=key, suffixes=("_x", "_y"))
    lines = list(dict.fromkeys(x_ci[line]))
    points = list(dict.fromkeys(x_ci[point]))
    # nodes are told apart by marker (a legend of its own), not by text beside each node:
    # with 5 x 5 nodes such labels collide with each other and with the error bars
    markers = [MARKERS[i % len(MARKERS)] for i in range(len(points))]
    fig, ax = plt.subplots(figsize=(6.6, 4.4), layout="constrained")
    colors = plt.get_cmap("plasma")(np.linspace(0, 0.85, len(lines)))
    for lv, col in zip(lines, colors):
        part = merged[merged[line] == lv].set_index(point).reindex(points)
        ax.plot(part["mean_x"], part["mean_y"], "-", color=col, lw=1.5, label=str(lv))
        ax.errorbar(part["mean_x"], part["mean_y"], xerr=part["ci_x"], yerr=part["ci_y"], fmt="none",
                    ecolor=col, capsize=2, lw=0.8)
        for (p, r), m in zip(part.iterrows(), markers):
            ax.plot(r["mean_x"], r["mean_y"], m, color=col, ms=5, mec="white", mew=0.5, label="_nolegend_")
    if lim:
        ax.set_xlim(*lim)
        ax.set_ylim(*lim)
    ax.set_xlabel(f"mean {x_label}")
    ax.set_ylabel(f"mean {y_label}")
    ax.set_title(f"{x_label} vs {y_label}: one graph per {line}, nodes = {point}", fontsize=10)
    first = ax.legend(title=line, fontsize=7, title_fontsize=8, frameon=False, loc="upper left",
                      bbox_to_anchor=(1.02, 1.0), borderaxespad=0)
    ax.add_artist(first)
    handles = [plt.Line2D([], [], ls="none", marker=m, color="0.35", ms=5) for m in markers]
    ax.legend(handles, [str(p) for p in points], title=point, fontsize=7, title_fontsize=8, frameon=False,
              loc="lower left", bbox_to_anchor=(1.02, 0.0), borderaxespad=0)
    ax.grid(alpha=0.3)
    return fig


@plain_text
def reference_plot(table: pd.DataFrame, scale: str, stem: str | Path, ylim: tuple[float, float] | None = None) -> list[Path]:
    """The matched levels' means (95% CI over participants) with the reference as a band
    (:func:`analysis.stats.reference.reference_table`; thesis §6.4, photographs vs s/m levels)."""
    from scipy import stats

    plt = _plt()
    ref, levels = table.iloc[0], table.iloc[1:]
    half = lambda r: stats.t.ppf(0.975, max(r["n"] - 1, 1)) * r["sd"] / np.sqrt(max(r["n"], 1))  # noqa: E731
    x = np.arange(len(levels))
    fig, ax = plt.subplots(figsize=(1.2 + 0.9 * len(levels), 3.4))
    h = half(ref)
    ax.axhspan(ref["mean"] - h, ref["mean"] + h, color="#f0b070", alpha=0.35, lw=0)
    ax.axhline(ref["mean"], color="#c06010", lw=1.5, label=f"{ref['condition']} (n = {int(ref['n'])})")
    ax.errorbar(x, levels["mean"], yerr=[half(r) for _, r in levels.iterrows()], fmt="o-", color="#2a4d80",
                capsize=4, label="matched levels")
    for i, (_, r) in enumerate(levels.iterrows()):
        if np.isfinite(r.get("p_holm", np.nan)) and r["p_holm"] < 0.05:
            ax.annotate("*", (i, r["mean"]), textcoords="offset points", xytext=(6, 4), fontsize=12)
    ax.set_xticks(x, [c.replace(" / ", "\n") for c in levels["condition"]], fontsize=8)
    ax.set_ylabel(f"mean {scale} (95% CI)")
    if ylim:
        ax.set_ylim(*ylim)
    ax.set_title(f"{scale}: {ref['condition']} vs matched levels (* Holm p < .05)", fontsize=10)
    ax.legend(fontsize=8, loc="best")
    ax.grid(axis="y", alpha=0.3)
    return save_figure(fig, stem)
