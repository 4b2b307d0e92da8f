"""Single-trial window amplitudes, and the stimulus each trial showed.

``single_trials.csv`` has one row per kept trial x component x cluster: ``subject``, ``trial``
(the event's 1-based position among the recording's events of interest, rejected ones
included: MNE's ``Epochs.selection`` + 1), ``sample`` (the event's sample at the analysed rate,
the recording's unless ``resample_hz``), ``code``, the factor levels of the code, ``stimulus``
and ``beh_trial``, then component, cluster and the window's mean, peak and peak latency
(:mod:`analysis.erp.measures`: the same window and cluster rules as ``amplitudes.csv``, so the
mean of a cell's single-trial means is that cell's ``mean_uV``).

The stimulus of a trial: a trigger code names a condition, not an image (in the shipped
``protocols/erp_stylisation.yaml`` a condition, character x stylisation x emotion, is one face, so
there ``code`` names the image too; in general it does not), so the stimulus comes from the
runner's behavioural file (``experiments``' BIDS ``*_beh.tsv``: one row per trial with
``trial``, ``stimulus`` and the ``trigger`` code sent on the stimulus's onset), given by the
config's ``beh`` (globs; the file's subject id, by ``subject_pattern``, names its recording).
Rule: the file's rows whose ``trigger`` is a code of the event map, in file order (the
presentation order), pair one to one with the recording's events of interest in time order;
the numbers must be equal and each kept trial's code must equal its row's code, else a
one-line error names the file. Without ``beh`` the ``stimulus`` and ``beh_trial`` columns stay
empty.
"""

from __future__ import annotations

import glob
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from appeal.errors import AppealInputError
from appeal.labels import shown

from analysis.erp.config import subject_id
from analysis.erp.measures import cluster_waveform, window_means, window_peaks

__all__ = ["trial_table", "single_trial_table", "find_beh_files", "read_beh_trials", "match_stimuli"]


def trial_table(selection: np.ndarray, events: np.ndarray, cells: Mapping[int, tuple], factors: Sequence[str],
                stimuli: pd.DataFrame | None = None) -> pd.DataFrame:
    """One row per kept trial: trial, sample, code, factor levels, stimulus, beh_trial.

    Parameters
    ----------
    selection : ndarray, shape (n_kept,)
        Each kept epoch's index among the events of interest (``Epochs.selection``).
    events : ndarray, shape (n_kept, 3)
        The kept epochs' events (``Epochs.events``).
    cells : mapping
        code -> cell (levels in ``factors`` order).
    factors : sequence of str
        The condition factors.
    stimuli : pandas.DataFrame | None
        :func:`match_stimuli`'s ``stimulus`` and ``beh_trial`` per kept trial, or None.

    Returns
    -------
    pandas.DataFrame
        ``stimulus`` and ``beh_trial`` empty without ``stimuli``.
    """
    codes = np.asarray(events)[:, 2].astype(int)
    out = pd.DataFrame({"trial": np.asarray(selection, int) + 1, "sample": np.asarray(events)[:, 0].astype(int),
                        "code": codes})
    for i, f in enumerate(factors):
        out[f] = [cells[c][i] for c in codes]
    if stimuli is None:
        out["stimulus"] = pd.Series([None] * len(out), dtype=object)
        out["beh_trial"] = pd.array([pd.NA] * len(out), dtype="Int64")
    else:
        out["stimulus"] = stimuli["stimulus"].to_numpy(object)
        out["beh_trial"] = pd.array(stimuli["beh_trial"].to_numpy(), dtype="Int64")
    return out


def single_trial_table(data: np.ndarray, times: np.ndarray, components: Mapping[str, dict],
                       trials: pd.DataFrame) -> pd.DataFrame:
    """Window mean, peak and peak latency of every trial x component x cluster.

    Parameters
    ----------
    data : ndarray, shape (n_trials, n_channels, n_times)
        The kept epochs in volts.
    times : ndarray, shape (n_times,)
        Sample times in seconds.
    components : mapping
        name -> ``{"window_s": (a, b), "polarity": str, "clusters": {name: channel indices}}``.
    trials : pandas.DataFrame
        :func:`trial_table`'s rows, one per epoch of ``data`` in the same order.

    Returns
    -------
    pandas.DataFrame
        The trial columns, then component, cluster, mean_uV, peak_uV, peak_latency_ms; rows by
        trial, then component and cluster.
    """
    if len(trials) != len(data):
        raise ValueError(f"{len(trials)} trial rows for {len(data)} epochs (expected one row per epoch)")
    parts = []
    for comp, spec in components.items():
        for cname, picks in spec["clusters"].items():
            waves = cluster_waveform(data, picks)
            peak, lat = window_peaks(waves, times, spec["window_s"], spec["polarity"])
            parts.append(trials.assign(component=comp, cluster=cname, mean_uV=window_means(waves, times, spec["window_s"]),
                                       peak_uV=peak, peak_latency_ms=lat, _order=np.arange(len(trials))))
    out = pd.concat(parts, ignore_index=True).sort_values("_order", kind="stable")
    return out.drop(columns="_order").reset_index(drop=True)


def find_beh_files(patterns: Path | Sequence[Path], recordings: Mapping[str, Path], subject_pattern: str,
                   source: str | Path = "config") -> dict[str, Path]:
    """The behavioural file of each recording's subject.

    Parameters
    ----------
    patterns : Path | sequence of Path
        The config's ``beh`` globs.
    recordings : mapping
        subject id -> recording.
    subject_pattern : str
        The config's ``subject_pattern`` (the same ids as the recordings').
    source : str | Path
        The config file (for messages).

    Raises
    ------
    AppealInputError
        One line per pattern that matches nothing, subject with several files, or recording
        without a file.
    """
    single = isinstance(patterns, (str, Path))
    found: dict[str, set[Path]] = {}
    problems = []
    for i, pat in enumerate([patterns] if single else list(patterns)):
        files = sorted(glob.glob(str(pat)))
        if not files:
            problems.append(f"{source}: {'beh' if single else f'beh[{i}]'}: pattern {pat} matches no file "
                            "(expected the runner's *_beh.tsv files)")
        for f in files:
            found.setdefault(subject_id(Path(f), subject_pattern), set()).add(Path(f))
    if problems:
        raise AppealInputError(problems)
    for subj, rec in recordings.items():
        files = sorted(found.get(subj, ()))
        if len(files) > 1:
            problems.append(f"{source}: beh: several files for subject {subj}: {', '.join(map(str, files))} "
                            "(expected one *_beh.tsv per recording)")
        elif not files:
            problems.append(f"{source}: beh: no file for subject {subj} of {rec} (expected one *_beh.tsv per recording)")
    if problems:
        raise AppealInputError(problems)
    return {s: sorted(found[s])[0] for s in recordings}


def read_beh_trials(path: str | Path, codes: Sequence[int]) -> pd.DataFrame:
    """The trials of a ``*_beh.tsv`` that sent a code of the event map, in file order.

    Returns
    -------
    pandas.DataFrame
        beh_trial (the runner's ``trial``), stimulus, code.

    Raises
    ------
    AppealInputError
        When the file cannot be read, lacks a ``trial``, ``stimulus`` or ``trigger`` column, or
        holds a trigger that is not an integer.
    """
    from analysis.stats.design import read_table

    df = read_table(path, all_text=True)  # a participant's file: checked as hostile input
    for col in ("trial", "stimulus", "trigger"):
        if col not in df.columns:
            raise AppealInputError(f"{path}: {col}: no such column (expected the runner's *_beh.tsv with trial, "
                                   "stimulus and trigger columns)")
    sent = ~df["trigger"].str.strip().isin(["", "n/a"])
    trig = pd.to_numeric(df["trigger"].where(sent), errors="coerce")
    bad = np.flatnonzero(sent.to_numpy() & trig.isna().to_numpy())
    if len(bad):
        raise AppealInputError(f"{path}: trigger: row {bad[0] + 1} holds {shown(df['trigger'].iloc[bad[0]])} "
                               "(expected an integer code or n/a)")
    keep = trig.isin([int(c) for c in codes]).to_numpy()
    return pd.DataFrame({"beh_trial": pd.to_numeric(df["trial"][keep], errors="coerce").astype("Int64").to_numpy(),
                         "stimulus": df["stimulus"][keep].to_numpy(object),
                         "code": trig[keep].astype(int).to_numpy()})


def match_stimuli(beh: pd.DataFrame, selection: np.ndarray, codes: np.ndarray, n_events: int,
                  beh_path: str | Path, recording: str | Path) -> pd.DataFrame:
    """The behavioural row of each kept trial (the module's pairing rule, checked).

    Parameters
    ----------
    beh : pandas.DataFrame
        :func:`read_beh_trials` of the subject's file.
    selection : ndarray, shape (n_kept,)
        Each kept epoch's index among the recording's events of interest.
    codes : ndarray, shape (n_kept,)
        The kept epochs' codes.
    n_events : int
        The recording's events of interest, rejected ones included.
    beh_path, recording : str | Path
        For messages.

    Returns
    -------
    pandas.DataFrame
        stimulus, beh_trial per kept trial.

    Raises
    ------
    AppealInputError
        When the numbers of trials differ, or a kept trial's code differs from its row's.
    """
    if len(beh) != n_events:
        raise AppealInputError(f"{beh_path}: trigger: {len(beh)} trials sent codes of the event map, but {recording} "
                               f"has {n_events} such events (expected the same trials in the same order)")
    rows = beh.iloc[np.asarray(selection, int)].reset_index(drop=True)
    wrong = np.flatnonzero(rows["code"].to_numpy() != np.asarray(codes, int))
    if len(wrong):
        i = wrong[0]
        raise AppealInputError(f"{beh_path}: trigger: trial {rows['beh_trial'].iloc[i]} sent code {rows['code'].iloc[i]}, "
                               f"but event {int(selection[i]) + 1} of {recording} has code {int(codes[i])} "
                               "(expected the same trials in the same order)")
    return rows[["stimulus", "beh_trial"]]
