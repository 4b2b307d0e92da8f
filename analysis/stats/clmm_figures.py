"""Figures of a cumulative-link mixed model: predicted rating probabilities per condition as
stacked bars (:func:`probability_figure`, saved by :func:`probability_plot`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from analysis.stats.clmm import ClmmFit
from appeal.figures import plain_text

__all__ = ["probability_figure", "probability_plot"]


@plain_text
def probability_figure(probs: pd.DataFrame | ClmmFit, x: str | None = None, panel: str | None = None,
                       title: str | None = None, scale_label: str = "rating"):
    """Stacked bars of the predicted category probabilities per condition (a matplotlib figure).

    Parameters
    ----------
    probs : DataFrame or ClmmFit
        :meth:`ClmmFit.predicted_probabilities` (or a fit: its default table).
    x : str, optional
        The factor along the x axis (default: the first condition column).
    panel : str, optional
        A factor drawn as side-by-side panels (default: the second condition column, if any;
        further condition columns are joined into the bar labels).
    title : str, optional
        Figure title.
    scale_label : str
        What the categories are (legend title).
    """
    from analysis.stats.plots import _plt

    if isinstance(probs, ClmmFit):
        probs = probs.predicted_probabilities()
    cond = [c for c in probs.columns if c not in {"category", "probability", "se", "lower", "upper"}]
    x = x or (cond[0] if cond else None)
    rest = [c for c in cond if c != x]
    panel = panel if panel is not None else (rest[0] if rest else None)
    keys = [c for c in [x, *[c for c in rest if c != panel]] if c]
    cats = list(dict.fromkeys(probs["category"]))
    panels = list(dict.fromkeys(probs[panel])) if panel else [None]
    plt = _plt()
    fig, axes = plt.subplots(1, len(panels), figsize=(1.6 + 2.4 * len(panels), 3.8), sharey=True, squeeze=False)
    colors = plt.get_cmap("RdYlBu")(np.linspace(0.05, 0.95, len(cats)))
    for ax, pv in zip(axes[0], panels):
        sub = probs if pv is None else probs[probs[panel] == pv]
        lab = sub[keys].astype(str).agg(" · ".join, axis=1) if keys else pd.Series("all", index=sub.index)
        labels = list(dict.fromkeys(lab))
        bottom = np.zeros(len(labels))
        for j, cat in enumerate(cats):
            rows = sub["category"] == cat
            val = pd.Series(sub.loc[rows, "probability"].to_numpy(), index=lab[rows].to_numpy()).reindex(labels)
            ax.bar(range(len(labels)), val.fillna(0).to_numpy(), bottom=bottom, color=colors[j], edgecolor="white",
                   linewidth=0.5, label=str(cat))
            bottom += val.fillna(0).to_numpy()
        long = max(map(len, labels)) > 6
        ax.set_xticks(range(len(labels)))
        ax.set_xticklabels(labels, rotation=30 if long else 0, ha="right" if long else "center")
        ax.set_ylim(0, 1)
        ax.set_xlabel(" · ".join(keys))
        if pv is not None:
            ax.set_title(f"{panel} = {pv}", fontsize=10)
    axes[0][0].set_ylabel("predicted probability\n(random effects = 0)")
    handles, labels_ = axes[0][-1].get_legend_handles_labels()
    axes[0][-1].legend(handles[::-1], labels_[::-1], title=scale_label, loc="center left", bbox_to_anchor=(1.02, 0.5),
                       frameon=False)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


@plain_text
def probability_plot(probs: pd.DataFrame | ClmmFit, stem: str | Path, x: str | None = None, panel: str | None = None,
                     title: str | None = None, scale_label: str = "rating") -> list[Path]:
    """:func:`probability_figure` saved as ``stem.png`` and ``stem.svg``; returns both paths."""
    from analysis.stats.plots import save_figure

    return save_figure(probability_figure(probs, x, panel, title, scale_label), stem)
