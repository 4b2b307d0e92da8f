"""Figures of psychometric fits (matplotlib, Agg; PNG + SVG through :func:`analysis.stats.plots.save_figure`).

* :func:`participant_figure` – one participant's answers binned by level (marker area ∝ trials)
  with the fitted function of every condition, the ``threshold_pc`` line and each threshold's
  credible interval.
* :func:`group_figure` – a per-participant estimate per condition: one line per participant,
  the mean ± its confidence interval.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from analysis.psychometric.fit import FitResult
from analysis.stats.plots import save_figure
from appeal.figures import plain_text

__all__ = ["Curve", "participant_figure", "group_figure"]

#: Largest marker area (points²) of a level, reached by the level with the most trials.
MAX_AREA = 160.0
#: Vertical distance between the threshold bars of a participant's conditions.
BAR_STEP = 0.015


@dataclass
class Curve:
    """One condition of a participant: its label, binned data ``(x, n_correct, n_trials)`` and fit."""

    label: str
    data: NDArray
    fit: FitResult


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _x_grid(curves: Sequence[Curve], n: int = 300) -> NDArray:
    """Where the curves are drawn: from 0 (or the smallest level, for Weibull) to the largest level."""
    xs = np.concatenate([c.data[:, 0] for c in curves])
    weibull = any(c.fit.family == "weibull" for c in curves)  # positive x only
    lo, hi = float(xs.min()), float(xs.max())
    lo = lo if weibull else min(lo, 0.0)
    pad = 0.02 * (hi - lo or 1.0)
    return np.linspace(lo if weibull else lo - pad, hi + pad, n)


def _threshold_bar(ax, curve: Curve, color, offset: float = 0.0) -> None:
    """The threshold at the height the function has there (``offset`` above it, so that the bars of
    several conditions do not hide each other), with its credible interval as a bar."""
    fit, e = curve.fit, curve.fit.estimate
    weibull = fit.family == "weibull"
    x_thr = float(np.exp(e["threshold"]) if weibull else e["threshold"])
    y = float(fit.predict(x_thr)) + offset
    lo, hi = fit.ci.get("threshold", (np.nan, np.nan))
    if np.isfinite(lo) and np.isfinite(hi):
        lo, hi = (np.exp(lo), np.exp(hi)) if weibull else (lo, hi)
        ax.errorbar([x_thr], [y], xerr=[[x_thr - lo], [hi - x_thr]], fmt="none", ecolor=color, elinewidth=2.5,
                    capsize=4, alpha=0.8, zorder=4)
    ax.plot([x_thr], [y], marker="|", markersize=12, markeredgewidth=2, color=color, zorder=5)


@plain_text
def participant_figure(curves: Sequence[Curve], stem: str | Path, threshold_pc: float, xlabel: str,
                       title: str, continuum: tuple[float, float] | None = None) -> list[Path]:
    """One participant's data and fitted functions.

    Parameters
    ----------
    curves : sequence of Curve
        One per condition.
    stem : str or Path
        File stem (``.png`` and ``.svg`` are written).
    threshold_pc : float
        Proportion correct drawn as a dashed line.
    xlabel, title : str
    continuum : (reference, direction), optional
        Adds a top axis with the continuum's level ``reference + direction * x``.

    Returns
    -------
    list of Path
        The PNG and the SVG.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    colors = plt.get_cmap("tab10").colors
    xs = _x_grid(curves)
    n_max = max(float(c.data[:, 2].max()) for c in curves)
    for i, curve in enumerate(curves):
        color = colors[i % len(colors)]
        x, k, n = curve.data.T
        ax.scatter(x, k / n, s=12 + MAX_AREA * n / n_max, color=color, alpha=0.45, edgecolors="none", zorder=2)
        ax.plot(xs, curve.fit.predict(xs), color=color, lw=2,
                label=f"{curve.label} (n = {int(n.sum())})" if len(curves) > 1 else f"n = {int(n.sum())}", zorder=3)
        _threshold_bar(ax, curve, color, BAR_STEP * (i - (len(curves) - 1) / 2))
    ax.axhline(threshold_pc, color="0.4", ls="--", lw=1, zorder=1)
    ax.text(xs[-1], threshold_pc, f" {threshold_pc:g}", va="center", ha="left", color="0.4", fontsize=8)
    gamma = min(c.fit.estimate["gamma"] for c in curves)
    ax.set_ylim(min(gamma, 0.5) - 0.05 if curves[0].fit.nafc else -0.03, 1.03)
    ax.set_xlim(xs[0], xs[-1])
    ax.set_xlabel(xlabel)
    ax.set_ylabel("proportion correct")
    bars = "; bar: the threshold's credible interval" if any(c.fit.ci for c in curves) else ""
    ax.set_title(f"{title}\nmarker area ∝ trials at a level; tick: threshold{bars}", fontsize=9)
    ax.legend(fontsize=8, loc="lower right", frameon=False)
    if continuum is not None:
        ref, sign = continuum
        top = ax.secondary_xaxis("top", functions=(lambda v: ref + sign * v, lambda v: (v - ref) * sign))
        top.set_xlabel("level on the continuum", fontsize=8)
    ax.spines[["right"] + ([] if continuum else ["top"])].set_visible(False)
    return save_figure(fig, stem)


@plain_text
def group_figure(long: pd.DataFrame, summary: pd.DataFrame, subject: str, measure: str, ylabel: str,
                 stem: str | Path, title: str = "") -> list[Path]:
    """Each participant's estimate per condition (thin lines) and the mean ± CI (black).

    Parameters
    ----------
    long : pandas.DataFrame
        Columns ``subject``, ``condition`` (ordered categorical: the x order) and ``measure``.
    summary : pandas.DataFrame
        Columns ``condition``, ``mean``, ``lower``, ``upper`` (as
        :func:`analysis.psychometric.study.condition_summary`).
    subject, measure, ylabel : str
    stem : str or Path
    title : str

    Returns
    -------
    list of Path
        The PNG and the SVG.
    """
    plt = _pyplot()
    order = [c for c in long["condition"].cat.categories if c in set(long["condition"])]
    pos = {c: i for i, c in enumerate(order)}
    fig, ax = plt.subplots(figsize=(max(3.6, 1.3 * len(order) + 1.6), 4.2))
    for _, g in long.sort_values("condition").groupby(subject, sort=True):
        g = g.dropna(subset=[measure])
        ax.plot([pos[c] for c in g["condition"]], g[measure], color="0.6", lw=0.8, marker="o", ms=3, alpha=0.7)
    s = summary[summary["condition"].isin(order)]
    x = [pos[c] for c in s["condition"]]
    err = np.vstack([s["mean"] - s["lower"], s["upper"] - s["mean"]])
    ax.errorbar(x, s["mean"], yerr=np.nan_to_num(err), color="black", lw=2, marker="s", ms=7, capsize=5,
                zorder=5, label="mean ± 95% CI")
    ax.set_xticks(range(len(order)), order, rotation=30 if len(order) > 4 else 0,
                  ha="right" if len(order) > 4 else "center")
    ax.set_xlim(-0.5, len(order) - 0.5)
    ax.set_ylabel(ylabel)
    n = long[subject].nunique()
    ax.set_title(f"{title}\n{n} participant{'s' if n != 1 else ''}: grey lines; black: mean ± 95% CI",
                 fontsize=9)
    ax.spines[["right", "top"]].set_visible(False)
    return save_figure(fig, stem)
