"""Figures (PNG + SVG, matplotlib Agg): waveforms, difference topographies, window bars, source maps, SME."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from appeal.figures import plain_text

__all__ = [
    "save_figure",
    "plot_waveforms",
    "plot_difference_topomaps",
    "plot_window_bars",
    "plot_source_map",
    "plot_sme",
    "waveforms_figure",
    "difference_topomaps_figure",
    "window_bars_figure",
    "source_map_figure",
    "sme_figure",
]


@plain_text
def save_figure(fig, path_stem: Path) -> list[Path]:
    """Save ``fig`` as ``<stem>.png`` and ``<stem>.svg``; returns both paths."""
    import matplotlib.pyplot as plt

    path_stem = Path(path_stem)
    path_stem.parent.mkdir(parents=True, exist_ok=True)
    out = []
    for ext in ("png", "svg"):
        p = path_stem.with_suffix(f".{ext}")
        fig.savefig(p, dpi=120, bbox_inches="tight")
        out.append(p)
    plt.close(fig)
    return out


def _level_means(grand: Mapping[tuple, np.ndarray], factor_index: int) -> dict:
    """Mean of cell averages per level of one factor."""
    acc: dict = {}
    for cell, data in grand.items():
        acc.setdefault(cell[factor_index], []).append(data)
    return {k: np.mean(v, axis=0) for k, v in acc.items()}


def _label_windows(ax, windows: Mapping[str, Sequence[float]], headroom: float = 0.16) -> None:
    """Shade the component windows and name them in a band above the plotted data.

    The y range grows by ``headroom`` of its height, so the names sit above every curve.
    """
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, hi + headroom * (hi - lo))
    for c, (a, b) in windows.items():
        ax.axvspan(a * 1e3, b * 1e3, color="0.9", zorder=0)
        ax.text((a + b) / 2 * 1e3, 0.985, c, transform=ax.get_xaxis_transform(), ha="center", va="top", fontsize=8)


def plot_waveforms(grand: Mapping[tuple, np.ndarray], times: np.ndarray, ch_names: Sequence[str],
                   channels: Mapping[str, str], factors: Sequence[str], levels: Mapping[str, Sequence],
                   windows: Mapping[str, Sequence[float]], path_stem: Path) -> list[Path]:
    """Save :func:`waveforms_figure` as ``<path_stem>.png`` and ``.svg``."""
    return save_figure(waveforms_figure(grand, times, ch_names, channels, factors, levels, windows), path_stem)


@plain_text
def waveforms_figure(grand: Mapping[tuple, np.ndarray], times: np.ndarray, ch_names: Sequence[str],
                     channels: Mapping[str, str], factors: Sequence[str], levels: Mapping[str, Sequence],
                     windows: Mapping[str, Sequence[float]]):
    """Grand-average waveforms per level of each factor at chosen channels (thesis Fig. 7.5, 7.7).

    Parameters
    ----------
    grand : mapping
        cell -> grand-average data (n_channels, n_times) in volts.
    channels : mapping
        title (e.g. "PO8") -> channel name of the recording (e.g. "B7").
    windows : mapping
        component -> (start, end) s, shaded.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(channels), len(factors), figsize=(6.0 * len(factors), 3.0 * len(channels)),
                             squeeze=False, sharex=True, layout="constrained")
    for j, f in enumerate(factors):
        means = _level_means(grand, j)
        cmap = plt.get_cmap("viridis" if len(levels[f]) > 3 else "tab10")
        for i, (title, ch) in enumerate(channels.items()):
            ax = axes[i, j]
            k = ch_names.index(ch)
            for n, lv in enumerate(levels[f]):
                if lv in means:
                    color = cmap(n / max(len(levels[f]) - 1, 1)) if len(levels[f]) > 3 else cmap(n)
                    ax.plot(times * 1e3, means[lv][k] * 1e6, color=color, lw=1.4, label=str(lv))
            _label_windows(ax, windows)
            ax.axhline(0, color="0.5", lw=0.6)
            ax.axvline(0, color="0.5", lw=0.6)
            ax.set_title(f"{title} ({ch}) by {f}" if title != ch else f"{ch} by {f}", fontsize=10)
            ax.set_ylabel("µV")
            if i == len(channels) - 1:
                ax.set_xlabel("time (ms)")
            if i == 0:  # beside the plot, never over the curves
                ax.legend(title=f, fontsize=7, title_fontsize=8, frameon=False, loc="upper left",
                          bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    fig.suptitle("Grand-average ERPs", fontsize=11)
    return fig


def plot_difference_topomaps(grand: Mapping[tuple, np.ndarray], info, factors: Sequence[str],
                             levels: Mapping[str, Sequence], factor: str, reference, windows: Mapping[str, Sequence[float]],
                             times: np.ndarray, path_stem: Path) -> list[Path]:
    """Save :func:`difference_topomaps_figure` (nothing when the factor has one level)."""
    fig = difference_topomaps_figure(grand, info, factors, levels, factor, reference, windows, times)
    return [] if fig is None else save_figure(fig, path_stem)


@plain_text
def difference_topomaps_figure(grand: Mapping[tuple, np.ndarray], info, factors: Sequence[str],
                               levels: Mapping[str, Sequence], factor: str, reference,
                               windows: Mapping[str, Sequence[float]], times: np.ndarray):
    """Difference topographies (level - reference) of one factor in each window (thesis Fig. 7.6).

    Returns
    -------
    matplotlib.figure.Figure | None
        ``None`` when the factor has no level besides ``reference``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import mne

    from analysis.erp.measures import window_mask

    j = list(factors).index(factor)
    means = _level_means(grand, j)
    others = [lv for lv in levels[factor] if lv != reference and lv in means]
    maps, titles = [], []
    for comp, win in windows.items():
        m = window_mask(times, win)
        for lv in others:
            maps.append((means[lv][:, m].mean(axis=1) - means[reference][:, m].mean(axis=1)) * 1e6)
            titles.append(f"{comp}: {lv} − {reference}")
    if not maps:
        return None
    lim = max(np.abs(np.array(maps)).max(), 1e-3)
    ncol = len(others)
    fig, axes = plt.subplots(len(windows), ncol, figsize=(2.6 * ncol + 0.8, 2.5 * len(windows)), squeeze=False)
    for ax, data, title in zip(axes.ravel(), maps, titles):
        im, _ = mne.viz.plot_topomap(data, info, axes=ax, show=False, cmap="RdBu_r", vlim=(-lim, lim), contours=4,
                                     sensors=True)
        ax.set_title(title, fontsize=9)
    fig.colorbar(im, ax=axes.ravel().tolist(), shrink=0.7, label="µV")
    fig.suptitle(f"Difference topographies: {factor}", fontsize=11)
    return fig


def plot_window_bars(amplitudes: pd.DataFrame, component: str, factors: Sequence[str], levels: Mapping[str, Sequence],
                     path_stem: Path, dv: str = "mean_uV") -> list[Path]:
    """Save :func:`window_bars_figure` as ``<path_stem>.png`` and ``.svg``."""
    return save_figure(window_bars_figure(amplitudes, component, factors, levels, dv), path_stem)


@plain_text
def window_bars_figure(amplitudes: pd.DataFrame, component: str, factors: Sequence[str],
                       levels: Mapping[str, Sequence], dv: str = "mean_uV"):
    """Window means per condition (clusters averaged) with ±1 SEM over subjects (thesis Fig. 7.5, 7.7)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sub = amplitudes[amplitudes["component"] == component]
    per_subj = sub.groupby(["subject", *factors], observed=True)[dv].mean().reset_index()
    x_f = factors[0]
    hue_f = factors[1] if len(factors) > 1 else None
    fig, ax = plt.subplots(figsize=(max(5.0, 0.9 * len(levels[x_f]) * (len(levels[hue_f]) if hue_f else 1) ** 0.5), 3.4),
                           layout="constrained")
    hues = levels[hue_f] if hue_f else [None]
    width = 0.8 / len(hues)
    cmap = plt.get_cmap("tab10")
    for h, hv in enumerate(hues):
        d = per_subj if hv is None else per_subj[per_subj[hue_f] == hv]
        g = d.groupby(x_f, observed=True)[dv]
        mean = g.mean().reindex(levels[x_f])
        sem = (g.std(ddof=1) / np.sqrt(g.count())).reindex(levels[x_f])
        x = np.arange(len(levels[x_f])) + (h - (len(hues) - 1) / 2) * width
        ax.bar(x, mean.values, width=width, yerr=sem.values, capsize=2, color=cmap(h), label=str(hv) if hv is not None else None)
    ax.set_xticks(np.arange(len(levels[x_f])), [str(v) for v in levels[x_f]])
    ax.set_xlabel(x_f)
    ax.set_ylabel(f"{component} mean amplitude (µV)")
    ax.axhline(0, color="0.4", lw=0.6)
    if hue_f:  # beside the bars, never over them
        ax.legend(title=hue_f, fontsize=8, frameon=False, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                  borderaxespad=0.0)
    n = per_subj["subject"].nunique()
    ax.set_title(f"{component}: window mean ± 1 SEM (n = {n})" if n > 1 else f"{component}: window mean (n = 1)",
                 fontsize=10)
    return fig


def plot_source_map(mni: np.ndarray, t: np.ndarray, threshold: float, title: str, path_stem: Path,
                    marks: Mapping[str, Sequence[float]] | None = None) -> list[Path]:
    """Save :func:`source_map_figure` as ``<path_stem>.png`` and ``.svg``."""
    return save_figure(source_map_figure(mni, t, threshold, title, marks), path_stem)


@plain_text
def source_map_figure(mni: np.ndarray, t: np.ndarray, threshold: float, title: str,
                      marks: Mapping[str, Sequence[float]] | None = None):
    """Maximum-intensity projections (sagittal, coronal, axial) of a voxel t map in MNI space."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    views = [("sagittal", 1, 2, 0, "y (mm)", "z (mm)"), ("coronal", 0, 2, 1, "x (mm)", "z (mm)"),
             ("axial", 0, 1, 2, "x (mm)", "y (mm)")]
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.0), layout="constrained")
    vmax = max(float(np.nanmax(np.abs(t))), threshold * 1.01)
    for ax, (name, a, b, depth, xl, yl) in zip(axes, views):
        order = np.argsort(t)  # largest drawn last = on top
        ax.scatter(mni[:, a], mni[:, b], s=6, c="0.85", lw=0)
        sel = order[t[order] >= threshold]
        sc = ax.scatter(mni[sel, a], mni[sel, b], s=14, c=t[sel], cmap="hot_r", vmin=threshold, vmax=vmax, lw=0)
        for label, p in (marks or {}).items():
            ax.plot(p[a], p[b], "c+", ms=12, mew=2)
        ax.set_aspect("equal")
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.set_title(name, fontsize=9)
    fig.colorbar(sc, ax=axes.tolist(), shrink=0.8, label=f"t (≥ {threshold:.2f})")
    fig.suptitle(title, fontsize=11)
    return fig


def plot_sme(sme: pd.DataFrame, threshold_uV: float | None, path_stem: Path) -> list[Path]:
    """Save :func:`sme_figure` as ``<path_stem>.png`` and ``.svg``."""
    return save_figure(sme_figure(sme, threshold_uV), path_stem)


@plain_text
def sme_figure(sme: pd.DataFrame, threshold_uV: float | None = None):
    """SME of the mean amplitude per subject, one panel per component (ERP CORE's data-quality view).

    Each dot is one condition cell x cluster of a subject (dots spread sideways so they do not
    hide each other), red where ``flagged``; the bar is the subject's root mean square over
    them; the dashed line is the threshold.

    Parameters
    ----------
    sme : pandas.DataFrame
        ``sme.csv``: subject, component, sme_uV and (optionally) flagged.
    threshold_uV : float | None
        The flagging threshold (no line when None).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    comps = list(dict.fromkeys(sme["component"]))
    subjects = list(dict.fromkeys(sme["subject"]))
    x_of = {s: i for i, s in enumerate(subjects)}
    width = max(3.2, 0.9 + 0.32 * len(subjects))
    fig, axes = plt.subplots(1, len(comps), figsize=(width * len(comps), 3.4), squeeze=False, layout="constrained")
    rng = np.random.default_rng(0)
    flagged = sme["flagged"].astype(bool) if "flagged" in sme else pd.Series(False, index=sme.index)
    for ax, comp in zip(axes[0], comps):
        d = sme[(sme["component"] == comp) & sme["sme_uV"].notna()]
        x = d["subject"].map(x_of).to_numpy(float) + rng.uniform(-0.22, 0.22, len(d))
        red = flagged[d.index].to_numpy()
        ax.scatter(x[~red], d["sme_uV"].to_numpy()[~red], s=9, color="0.55", lw=0, label="cell x cluster")
        if red.any():
            ax.scatter(x[red], d["sme_uV"].to_numpy()[red], s=12, color="tab:red", lw=0, label="flagged")
        rms = d.groupby("subject", sort=False)["sme_uV"].apply(lambda v: float(np.sqrt(np.mean(np.square(v)))))
        xs = np.array([x_of[s] for s in rms.index], float)
        ax.hlines(rms.to_numpy(), xs - 0.32, xs + 0.32, color="k", lw=1.6, label="RMS per subject")
        if threshold_uV is not None:
            ax.axhline(threshold_uV, color="tab:red", ls="--", lw=1.0, label=f"threshold {threshold_uV:g} µV")
        ax.set_xticks(range(len(subjects)), [str(s) for s in subjects], rotation=90 if len(subjects) > 12 else 0,
                      fontsize=8)
        ax.set_xlim(-0.6, len(subjects) - 0.4)
        ax.set_ylim(0, None)
        ax.set_xlabel("subject")
        ax.set_ylabel("SME (µV)")
        ax.set_title(f"{comp}: SME of the mean amplitude", fontsize=10)
    entries = {label: h for ax in axes[0] for h, label in zip(*ax.get_legend_handles_labels())}  # every panel's
    axes[0, -1].legend(entries.values(), entries.keys(), fontsize=7, frameon=False, loc="upper left",
                       bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    return fig
