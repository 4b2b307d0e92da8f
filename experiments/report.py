"""Session report: intended vs shown frames, dropped frames, ISI distribution, trigger-to-flip
offsets and trials per condition (tables as CSV, a figure as PNG + SVG, one HTML page)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from appeal.report import ReportSection, write_index_html

__all__ = ["session_summary", "write_session_report"]


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
    isi = np.diff(main["onset_s"].to_numpy(float)) * 1000 if len(main) > 1 else np.array([])
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


def _figure(summary: dict[str, Any], path_png: Path, title: str) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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
    fig.suptitle(title)
    fig.tight_layout()
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
    s["frames"].to_csv(frames_csv, index=False)
    cond_csv = out / "trials_per_condition.csv"
    s["per_condition"].to_csv(cond_csv, index=False)
    numbers_csv = out / "summary.csv"
    pd.DataFrame([s["numbers"]]).T.rename(columns={0: "value"}).rename_axis("measure").to_csv(numbers_csv)
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
