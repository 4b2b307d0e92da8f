"""Session report: intended vs shown frames, dropped frames, ISI distribution, trigger-to-flip
offsets and trials per condition (tables as CSV, a figure as PNG + SVG, one HTML page)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from appeal.cells import write_table
from appeal.figures import plain_text
from appeal.report import ReportSection, write_index_html

__all__ = ["session_summary", "write_session_report", "onset_asynchronies", "timing_figure", "overlapping_texts"]


def onset_asynchronies(main: pd.DataFrame) -> np.ndarray:
    """Stimulus-onset asynchronies (ms) between consecutive main trials of the same session part.

    Each ``--resume`` starts a new part whose clock restarts at 0 (column ``part``), so onsets
    of different parts are never subtracted (that gave e.g. -47016 ms across a resume).

    Parameters
    ----------
    main : pandas.DataFrame
        Main-phase rows with ``trial``, ``onset_s`` and (from sessions recorded since parts
        exist) ``part``.

    Returns
    -------
    numpy.ndarray
        One SOA per pair of consecutive trials within a part, in trial order.
    """
    parts = main["part"] if "part" in main else pd.Series(1, index=main.index)
    out = [np.diff(g.sort_values("trial")["onset_s"].to_numpy(float)) * 1000
           for _, g in main.assign(_part=parts).groupby("_part", sort=True)]
    return np.concatenate(out) if out else np.array([])


def session_summary(beh: pd.DataFrame, refresh_hz: float, factors: list[str]) -> dict[str, Any]:
    """Timing and design checks of one session's rows.

    Parameters
    ----------
    beh : pandas.DataFrame
        The ``_beh.tsv`` (as read by pandas).
    refresh_hz : float
        The session's refresh rate.
    factors : list of str
        Factor columns.

    Returns
    -------
    dict
        ``frames`` (DataFrame per phase), ``isi_ms`` (array), ``fixation_ms`` (array),
        ``trigger_ms`` (array), ``per_condition`` (DataFrame), ``numbers`` (dict of scalars).
    """
    period_ms = 1000.0 / refresh_hz
    beh = beh.copy()
    beh["frames_ok"] = beh["shown_frames"] == beh["duration_frames"]
    frames = beh.groupby("phase", sort=False).agg(
        trials=("trial", "size"), intended_frames_median=("duration_frames", "median"),
        shown_frames_median=("shown_frames", "median"), shown_equals_intended=("frames_ok", "sum"),
        max_abs_frame_error=("shown_frames", lambda s: int((s - beh.loc[s.index, "duration_frames"]).abs().max())),
        dropped_frames=("dropped_frames", "sum"),
        shown_ms_median=("shown_s", lambda s: float(np.nanmedian(s) * 1000)),
    ).reset_index()
    main = beh[beh["phase"] == "main"].sort_values("trial")
    isi = onset_asynchronies(main)
    fix = (main["fixation_frames"].to_numpy(float) * period_ms) if "fixation_frames" in main else np.array([])
    trig = main["trigger_flip_ms"].dropna().to_numpy(float) if "trigger_flip_ms" in main else np.array([])
    per_cond = main.groupby(factors, dropna=False).size().rename("trials").reset_index() if factors else pd.DataFrame()
    n_trig = int(main["trigger"].notna().sum()) if "trigger" in main else 0
    numbers = {
        "trials": int(len(beh)), "main_trials": int(len(main)),
        "shown_equals_intended": int(beh["frames_ok"].sum()), "dropped_frames": int(beh["dropped_frames"].sum()),
        "isi_ms_median": float(np.median(isi)) if isi.size else None,
        "isi_ms_min": float(isi.min()) if isi.size else None, "isi_ms_max": float(isi.max()) if isi.size else None,
        "triggers": n_trig, "onsets_with_one_trigger": n_trig,
        "trigger_flip_ms_median": float(np.median(trig)) if trig.size else None,
        "trigger_flip_ms_max_abs": float(np.abs(trig).max()) if trig.size else None,
        "trials_per_condition_min": int(per_cond["trials"].min()) if len(per_cond) else None,
        "trials_per_condition_max": int(per_cond["trials"].max()) if len(per_cond) else None,
    }
    return {"frames": frames, "isi_ms": isi, "fixation_ms": fix, "trigger_ms": trig, "per_condition": per_cond,
            "numbers": numbers}


def _shown_ticklabels(ax: Any, which: str) -> list[Any]:
    """The tick labels matplotlib draws on one axis (ticks inside the view limits)."""
    axis = ax.xaxis if which == "x" else ax.yaxis
    lo, hi = sorted(axis.get_view_interval())
    span = (hi - lo) * 1e-9
    return [t.label1 for t in axis.get_major_ticks()[: len(axis.get_majorticklocs())]
            if lo - span <= t.get_loc() <= hi + span and t.label1.get_visible() and t.label1.get_text()]


def overlapping_texts(fig: Any) -> list[tuple[str, str]]:
    """Pairs of drawn texts (tick labels, axis labels, titles) of a figure that overlap.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure (drawn here first).

    Returns
    -------
    list of (str, str)
        The overlapping texts; empty when every label is readable.
    """
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    texts = [fig._suptitle] if fig._suptitle is not None else []
    for ax in fig.axes:
        texts += [*_shown_ticklabels(ax, "x"), *_shown_ticklabels(ax, "y"), ax.xaxis.label, ax.yaxis.label, ax.title]
    boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in texts if t.get_visible() and t.get_text().strip()]
    return [(a, b) for i, (a, ba) in enumerate(boxes) for b, bb in boxes[i + 1:] if ba.overlaps(bb)]


def _readable_ticks(fig: Any, ax: Any) -> None:
    """Fewer x ticks until this axes' tick labels do not overlap (wide ranges, long numbers)."""
    from matplotlib.ticker import MaxNLocator

    for nbins in (6, 5, 4, 3, 2):
        fig.canvas.draw()
        boxes = [t.get_window_extent() for t in _shown_ticklabels(ax, "x")]
        if not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:]):
            return
        ax.xaxis.set_major_locator(MaxNLocator(nbins=nbins))


@plain_text
def timing_figure(summary: dict[str, Any], title: str) -> Any:
    """The session report's figure: SOA, fixation and trigger-offset histograms, labels readable.

    Parameters
    ----------
    summary : dict
        :func:`session_summary`'s result (``isi_ms``, ``fixation_ms``, ``trigger_ms``).
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    panels = [("isi_ms", "stimulus onset asynchrony (ms)"), ("fixation_ms", "fixation duration (ms)"),
              ("trigger_ms", "trigger - onset flip (ms)")]
    for ax, (key, label) in zip(axes, panels):
        data = summary[key]
        if data.size:
            ax.hist(data, bins=min(40, max(5, len(np.unique(data)))), color="#4477aa", edgecolor="white")
        else:
            ax.text(0.5, 0.5, "none in this session", ha="center", va="center", transform=ax.transAxes)
        ax.set_xlabel(label)
        ax.set_ylabel("trials")
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    fig.suptitle(title)
    fig.tight_layout()
    for ax in axes:
        _readable_ticks(fig, ax)
    fig.tight_layout()
    return fig


@plain_text
def _figure(summary: dict[str, Any], path_png: Path, title: str) -> list[Path]:
    import matplotlib.pyplot as plt

    fig = timing_figure(summary, title)
    fig.savefig(path_png, dpi=110)
    fig.savefig(path_png.with_suffix(".svg"))
    plt.close(fig)
    return [path_png, path_png.with_suffix(".svg")]


def write_session_report(paths: dict[str, Path], refresh_hz: float) -> Path:
    """Write ``paths['report']/index.html`` with the session's timing and design tables."""
    out = Path(paths["report"])
    out.mkdir(parents=True, exist_ok=True)
    beh = pd.read_csv(paths["beh"], sep="\t")
    side = json.loads(Path(paths["sidecar"]).read_text())
    factors = [c for c in side.get("Columns", {}) if side["Columns"][c]["Description"].startswith("factor '")]
    s = session_summary(beh, refresh_hz, factors)
    frames_csv = out / "frames_intended_vs_shown.csv"
    write_table(s["frames"], frames_csv)
    cond_csv = out / "trials_per_condition.csv"
    write_table(s["per_condition"], cond_csv)
    numbers_csv = out / "summary.csv"
    write_table(pd.DataFrame([s["numbers"]]).T.rename(columns={0: "value"}).rename_axis("measure"), numbers_csv, index=True)
    figs = _figure(s, out / "timing.png", f"{side.get('ProtocolName')} sub-{side.get('participant_id')} "
                   f"({side.get('TimingMode')} timing, {refresh_hz:g} Hz)")
    mode = side.get("TimingMode")
    note = {"virtual": "Virtual timing (simulated session): each screen was drawn and flipped once and the clock "
                       "advanced by the intended frames, so shown = intended by construction.",
            "realtime": "Real flips paced to the nominal refresh rate (simulated participant).",
            "live": "Every frame drawn and flipped; durations counted in flips; times are flip stamps."}.get(mode, "")
    n = s["numbers"]
    text = (f"{note}\n\n- trials: {n['trials']} ({n['main_trials']} main); shown = intended frames in "
            f"{n['shown_equals_intended']} of {n['trials']}; dropped frames: {n['dropped_frames']}\n"
            f"- triggers: {n['triggers']}; trigger - flip median {n['trigger_flip_ms_median']} ms\n"
            f"- trials per condition: {n['trials_per_condition_min']} to {n['trials_per_condition_max']}")
    sec = ReportSection("Session timing and design", text=text, figures=figs,
                        tables=[numbers_csv, frames_csv, cond_csv], links=[paths["beh"], paths["sidecar"]])
    return write_index_html(out / "index.html", f"Session report: {side.get('ProtocolName')}", [sec])
