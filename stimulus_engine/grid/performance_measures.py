"""How far a performance moves the face, frame by frame, at each stylisation level.

A grid with ``animation: {performance: take.csv}`` plays one captured performance (per-frame
blendshape weights, e.g. from ``appeal stimuli retarget``) on every shape level, each level through
its own expression transfer. Thesis ch. 4's aim is "a semantically equivalent sequence of
different characters": the cartoon should perform the same movement as far, in units of its own
face, as the realistic rig. This module measures that on the clip's geometry, the way
:mod:`stimulus_engine.grid.expression_measures` measures still expressions:

* :func:`frame_landmarks` poses the rig once per distinct frame and keeps its landmarks (with the
  level's neutral) beside the clip's geometry in the cache;
* :func:`performance_measures` gives every frame's :data:`~stimulus_engine.grid.expression_measures.MEASURES`
  against the level's neutral, in face lengths (mouth opening, mouth width, corner raise, brow
  raise, eye opening, overall RMS);
* :func:`performance_agreement` compares each level's trace with the realistic level's (the
  character's smallest shape value): ``gain``, the least-squares slope of the level's values on the
  realistic ones over the frames (1 = the same movement as far; the measure of intensity), the
  ratio of the peaks, and the correlation of the traces (1 = the same timing and shape of the
  movement). A measure is ``judged`` where the realistic level's peak is at least
  :data:`~stimulus_engine.grid.expression_measures.JUDGED_FRACTION` of its largest measure's peak;
* :func:`write_performance_measures` writes ``performance_measures.csv``,
  ``performance_agreement.csv`` and ``performance_measures.png`` (the judged traces over time,
  one line per level).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from stimulus_engine.grid.expression_measures import JUDGED_FRACTION, MEASURES, face_measures

__all__ = ["frame_landmarks", "performance_agreement", "performance_landmarks", "performance_measures",
           "plot_performance_measures", "write_performance_measures"]

logger = logging.getLogger(__name__)

#: The long per-frame landmark table's columns (:func:`performance_landmarks`); frame -1 is the neutral.
LANDMARK_COLUMNS = ("character", "shape", "stylisation", "frame", "landmark", "x", "y", "z")


def frame_landmarks(path: Path, frames: Sequence[dict[str, float]],
                    landmarks: Callable[[dict[str, float]], dict[str, np.ndarray]]) -> Path:
    """The landmarks of the level's neutral and of every frame, in ``path`` (``.npz``; kept: a re-run
    reads it). ``landmarks``: a frame's blendshape weights -> landmark name -> point of the posed
    rig; frames of equal weights are posed once (:func:`~stimulus_engine.grid.animation.frame_keys`)."""
    from stimulus_engine.grid.animation import frame_keys
    from stimulus_engine.grid.cache import save_npz

    path = Path(path)
    if path.exists():
        return path
    neutral = landmarks({})
    names = list(neutral)
    points = np.empty((len(frames), len(names), 3))
    for k, first in enumerate(frame_keys(list(frames))):
        if first == k:
            got = landmarks(frames[k])
            points[k] = [got[n] for n in names]
        else:
            points[k] = points[first]
    save_npz(path, {"names": np.array(names), "neutral": np.array([neutral[n] for n in names]), "frames": points})
    return path


def performance_landmarks(cells: pd.DataFrame) -> pd.DataFrame:
    """The long landmark table (:data:`LANDMARK_COLUMNS`) of every (character, shape) of ``cells``
    (rows with ``character``, ``shape``, ``stylisation`` and ``landmarks_file``, a
    :func:`frame_landmarks` file); frame -1 holds the level's neutral."""
    parts = []
    for r in cells.drop_duplicates(["character", "shape"]).itertuples():
        with np.load(r.landmarks_file) as z:
            names, neutral, frames = z["names"], z["neutral"], z["frames"]
        pts = np.concatenate([neutral[None], frames])
        n_f, n_l = pts.shape[:2]
        parts.append(pd.DataFrame({"character": r.character, "shape": r.shape, "stylisation": r.stylisation,
                                   "frame": np.repeat(np.arange(-1, n_f - 1), n_l), "landmark": np.tile(names, n_f),
                                   "x": pts[..., 0].ravel(), "y": pts[..., 1].ravel(), "z": pts[..., 2].ravel()}))
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=list(LANDMARK_COLUMNS))


def performance_measures(landmarks: pd.DataFrame, fps: float | None = None) -> pd.DataFrame:
    """Every frame's measures against its level's neutral, in face lengths.

    Parameters
    ----------
    landmarks : DataFrame
        :func:`performance_landmarks`'s table (frame -1 the neutral of each character and shape).
    fps : float, optional
        Frames a second: adds a ``time`` column (seconds).

    Returns
    -------
    DataFrame
        Tidy: character, shape, stylisation, frame (, time), measure, value; characters as first
        met, shapes increasing, then frames and :data:`MEASURES` in order.

    Examples
    --------
    >>> pts = {"forehead_top": (0, 10), "chin": (0, -10), "eye_left": (3, 2), "eye_right": (-3, 2),
    ...        "mouth_top": (0, -5), "mouth_bottom": (0, -6), "mouth_left": (2, -5.5), "mouth_right": (-2, -5.5),
    ...        "brow_left": (3, 4), "brow_right": (-3, 4), "eye_left_top": (3, 2.5), "eye_left_bottom": (3, 1.5),
    ...        "eye_right_top": (-3, 2.5), "eye_right_bottom": (-3, 1.5)}
    >>> rows = [dict(character="a", shape=0.0, stylisation=0, frame=f, landmark=k, x=x, z=0.0,
    ...              y=y - (drop if k == "mouth_bottom" else 0)) for f, drop in ((-1, 0), (0, 0), (1, 2))
    ...         for k, (x, y) in pts.items()]
    >>> t = performance_measures(pd.DataFrame(rows), fps=10)
    >>> t[t["measure"] == "mouth_opening"][["frame", "time", "value"]].round(4).to_dict("list")
    {'frame': [0, 1], 'time': [0.0, 0.1], 'value': [0.0, 0.1]}
    """
    rows = []
    for (ch, shape), level in landmarks.groupby(["character", "shape"], sort=False):
        frames = dict(tuple(level.groupby("frame", sort=True)))
        neutral = dict(zip(frames[-1]["landmark"], frames[-1][["x", "y", "z"]].to_numpy(np.float64)))
        stylisation = level["stylisation"].iloc[0]
        for f, g in frames.items():
            if f < 0:
                continue
            posed = dict(zip(g["landmark"], g[["x", "y", "z"]].to_numpy(np.float64)))
            values = face_measures(neutral, posed, f"{ch} at shape {shape}, frame {f}")
            rows += [{"character": ch, "shape": shape, "stylisation": stylisation, "frame": int(f), "measure": m,
                      "value": v} for m, v in values.items()]
    table = pd.DataFrame(rows, columns=["character", "shape", "stylisation", "frame", "measure", "value"])
    if fps:
        table.insert(4, "time", table["frame"] / float(fps))
    order = {c: i for i, c in enumerate(dict.fromkeys(landmarks["character"]))}
    key = pd.DataFrame({"c": table["character"].map(order), "s": table["shape"].astype(float), "f": table["frame"],
                        "m": table["measure"].map({m: i for i, m in enumerate(MEASURES)})})
    return table.loc[key.sort_values(["c", "s", "f", "m"], kind="stable").index].reset_index(drop=True)


def _trace_agreement(real: np.ndarray, level: np.ndarray) -> dict[str, float]:
    """Gain (slope through the origin), peak ratio and correlation of one level's trace against the
    realistic one (NaN where the realistic level does not move)."""
    rr = float(real @ real)
    peak_r, peak = float(np.abs(real).max()), float(np.abs(level).max())
    same = real.std() > 0 and level.std() > 0
    return {"realistic_peak": peak_r, "peak": peak,
            "gain": float(real @ level) / rr if rr > 0 else np.nan,
            "peak_ratio": peak / peak_r if peak_r > 0 else np.nan,
            "correlation": float(np.corrcoef(real, level)[0, 1]) if same else np.nan}


def performance_agreement(table: pd.DataFrame, fraction: float = JUDGED_FRACTION) -> pd.DataFrame:
    """How far each level performs the realistic level's movement, per character x shape x measure.

    Parameters
    ----------
    table : DataFrame
        :func:`performance_measures`'s table.
    fraction : float
        A measure is judged when the realistic level's peak is at least this fraction of its
        largest measure's peak.

    Returns
    -------
    DataFrame
        character, shape, stylisation, measure, realistic_peak, peak (largest magnitudes over the
        frames), gain (least-squares slope of the level's values on the realistic level's: 1 = as
        far), peak_ratio, correlation (of the two traces), judged.

    Examples
    --------
    >>> t = pd.DataFrame({"character": "a", "shape": [0.0] * 4 + [1.0] * 4, "stylisation": [1] * 4 + [0] * 4,
    ...                   "frame": [0, 1, 2, 3] * 2, "measure": "mouth_opening",
    ...                   "value": [0.0, 0.05, 0.1, 0.02, 0.0, 0.06, 0.12, 0.024]})
    >>> performance_agreement(t)[["shape", "gain", "correlation", "judged"]].round(3)
       shape  gain  correlation  judged
    0    0.0   1.0          1.0    True
    1    1.0   1.2          1.0    True
    """
    rows = []
    for ch, g in table.groupby("character", sort=False):
        shapes = sorted(g["shape"].unique(), key=float)
        wide = g.pivot_table(index="frame", columns=["measure", "shape"], values="value", sort=True)
        realistic = shapes[0]
        for measure in [m for m in MEASURES if m in wide.columns.get_level_values(0)]:
            real = wide[(measure, realistic)].to_numpy(np.float64)
            for s in shapes:
                st = g.loc[g["shape"] == s, "stylisation"].iloc[0]
                rows.append({"character": ch, "shape": s, "stylisation": st, "measure": measure,
                             **_trace_agreement(real, wide[(measure, s)].to_numpy(np.float64))})
    out = pd.DataFrame(rows, columns=["character", "shape", "stylisation", "measure", "realistic_peak", "peak", "gain",
                                      "peak_ratio", "correlation"])
    top = out.groupby("character", sort=False)["realistic_peak"].transform("max")
    out["judged"] = (top > 0) & (out["realistic_peak"] >= fraction * top)
    return out


def plot_performance_measures(table: pd.DataFrame, agreement: pd.DataFrame, path: Path) -> Path:
    """The judged measures' traces over the clip, one line per shape level, a row of panels per
    character (PNG); each panel's legend gives the level's gain against the realistic level."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    judged = agreement[agreement["judged"]]
    chars = list(dict.fromkeys(table["character"]))
    measures = [m for m in MEASURES if m in set(judged["measure"])] or ["total"]
    x = "time" if "time" in table.columns else "frame"
    fig, axes = plt.subplots(len(chars), len(measures), figsize=(max(3.0 * len(measures) + 0.6, 6.4),
                                                                 2.6 * len(chars) + 1.0),
                             squeeze=False, sharex=True, constrained_layout=True)
    cmap = plt.get_cmap("viridis")
    for i, ch in enumerate(chars):
        shapes = sorted(table.loc[table["character"] == ch, "shape"].unique(), key=float)
        gains = agreement[agreement["character"] == ch].set_index(["measure", "shape"])["gain"]
        for j, m in enumerate(measures):
            ax = axes[i, j]
            for k, s in enumerate(shapes):
                g = table[(table["character"] == ch) & (table["measure"] == m) & (table["shape"] == s)]
                gain = gains.get((m, s), np.nan)
                ax.plot(g[x], g["value"], color=cmap(k / max(len(shapes) - 1, 1)), lw=1.4,
                        label=f"shape {float(s):g} (gain {gain:.2f})")
            ax.axhline(0.0, color="0.7", lw=0.8)
            ax.set_title(f"{ch}: {m.replace('_', ' ')}", fontsize=10)
            ax.tick_params(labelsize=8)
            ax.legend(fontsize=6.5, loc="best", framealpha=0.8, handlelength=1.2)
            if j == 0:
                ax.set_ylabel("face lengths", fontsize=9)
            if i == len(chars) - 1:
                ax.set_xlabel("seconds" if x == "time" else "frame", fontsize=9)
    fig.suptitle("How far the performance moves the face at each shape level, frame by frame\n"
                 "(gain: least-squares slope on the realistic level's trace; 1 = as far)", fontsize=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write_performance_measures(out: Path, landmarks: pd.DataFrame, fps: float | None = None) -> list[Path]:
    """``performance_measures.csv``, ``performance_agreement.csv`` and ``performance_measures.png``
    in ``out`` from :func:`performance_landmarks`'s table; nothing (``[]``) with fewer than two shape
    levels of a character. One log line per character and level with its judged gains."""
    from appeal.cells import write_table

    if landmarks.empty or landmarks.groupby("character")["shape"].nunique().max() < 2:
        return []
    table = performance_measures(landmarks, fps)
    agreement = performance_agreement(table)
    for (ch, s), g in agreement[agreement["judged"]].groupby(["character", "shape"], sort=False):
        logger.info("performance on %s at shape %s: gain %s", ch, s,
                    ", ".join(f"{r.measure} {r.gain:.2f} (r {r.correlation:.2f})" for r in g.itertuples()))
    out = Path(out)
    return [write_table(table, out / "performance_measures.csv", float_format="%.6f"),
            write_table(agreement, out / "performance_agreement.csv", float_format="%.5f"),
            plot_performance_measures(table, agreement, out / "performance_measures.png")]
