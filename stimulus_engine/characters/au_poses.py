"""Reverse-correlation trials on a rig: the grammar's AU amplitudes as blendshape weights.

The grammar (:mod:`appeal.revcorr.grammar`) speaks FACS action units; a rig speaks blendshapes.
Each AU moves the blendshapes the FACS recipe file gives it (``stimulus_engine/data/facs_recipes.yaml``,
:func:`~stimulus_engine.characters.expressions.facs_recipes`), all at the AU's amplitude; a
lateralised AU (``AU12_L``) moves only the blendshapes of its side (``mouthSmile_L``).
:func:`trial_frame_weights` gives a trial's weights frame by frame, the input of the clip path
(:mod:`stimulus_engine.grid.animation`), and :func:`apex_weights` those of its apex frame.
:func:`write_trial_performance` writes a trial as a performance CSV (with its parameters in a JSON
beside it), which a grid plays on any character and level with ``animation: {performance: FILE}``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError
from appeal.revcorr.grammar import Trial, trial_curves
from stimulus_engine.characters.expressions import facs_recipes

__all__ = ["au_blendshapes", "au_weights", "trial_frame_weights", "apex_weights", "clip_frames",
           "write_trial_performance"]


def au_blendshapes(au: str) -> tuple[str, ...]:
    """The blendshapes an AU moves (``AU12`` both sides, ``AU12_L`` the left one).

    Examples
    --------
    >>> au_blendshapes("AU12"), au_blendshapes("AU12_R")
    (('mouthSmile_L', 'mouthSmile_R'), ('mouthSmile_R',))
    """
    base, _, side = au.partition("_")
    table = facs_recipes()["action_units"]
    if base not in table:
        raise AppealInputError(f"revcorr: action unit '{au}': not in the FACS recipes (expected one of: "
                               f"{', '.join(table)})")
    shapes = tuple(table[base])
    if side:
        if side not in ("L", "R"):
            raise AppealInputError(f"revcorr: action unit '{au}': a side is _L or _R")
        shapes = tuple(s for s in shapes if s.endswith(f"_{side}"))
        if not shapes:
            raise AppealInputError(f"revcorr: action unit '{au}': {base} has no {side} blendshape")
    return shapes


def au_weights(amplitudes: Mapping[str, float]) -> dict[str, float]:
    """Blendshape weights of AU amplitudes; AUs that share a blendshape add (clipped to 1)."""
    out: dict[str, float] = {}
    for au, a in amplitudes.items():
        for shape in au_blendshapes(au):
            out[shape] = min(1.0, out.get(shape, 0.0) + float(a))
    return out


def clip_frames(seconds: float = 1.25, fps: int = 30) -> int:
    """Frames of a clip of ``seconds`` at ``fps``, both ends shown: ``floor(seconds * fps + 0.5) + 1``
    (1.25 s at 30 fps: 39 frames, 0 to 1.25 s)."""
    return int(np.floor(seconds * fps + 0.5)) + 1


def trial_frame_weights(trial: Trial, n_frames: int) -> list[dict[str, float]]:
    """The trial's blendshape weights at each of ``n_frames`` frames (:func:`clip_frames`)."""
    curves = trial_curves(trial, n_frames)
    return [au_weights({au: float(c[k]) for au, c in curves.items()}) for k in range(n_frames)]


def apex_weights(trial: Trial, n_frames: int = 39) -> tuple[int, dict[str, float]]:
    """The frame where the trial's summed amplitude peaks, and its weights (a static apex image)."""
    curves = trial_curves(trial, n_frames)
    total = np.sum(list(curves.values()), axis=0)
    k = int(np.argmax(total))
    return k, au_weights({au: float(c[k]) for au, c in curves.items()})


def write_trial_performance(trial: Trial, path: str | Path, fps: int = 30, seconds: float = 1.25) -> Path:
    """Write the trial's frames as a performance CSV (``frame``, ``time``, one column per blendshape it
    moves) and its parameters as ``path`` with suffix ``.json`` (seed, index, each AU's six
    parameters, fps, frames, the apex frame). Returns the CSV's path."""
    import json

    import pandas as pd

    from appeal.atomic import atomic_write_text

    path = Path(path)
    n = clip_frames(seconds, fps)
    frames = trial_frame_weights(trial, n)
    names = sorted({s for f in frames for s in f}) or ["jawOpen"]
    table = pd.DataFrame([[f.get(s, 0.0) for s in names] for f in frames], columns=names)
    table.insert(0, "time", np.arange(n) / fps)
    table.insert(0, "frame", np.arange(n))
    atomic_write_text(path, table.to_csv(index=False, float_format="%.6f"))
    apex, _ = apex_weights(trial, n)
    meta = {"seed": trial.seed, "trial": trial.index, "fps": fps, "n_frames": n, "apex_frame": apex,
            "motions": [m.as_dict() for m in trial.motions]}
    atomic_write_text(path.with_suffix(".json"), json.dumps(meta, indent=1))
    return path
