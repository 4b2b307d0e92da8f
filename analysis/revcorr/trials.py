"""The trials of a reverse-correlation study, read and checked before anything is computed.

One row per trial (a CSV/TSV/Parquet table or the runner's BIDS ``*_beh.tsv`` files):

=====================  ==================================================================
``participant_id``     the participant (or the ``sub-<id>`` of the file name)
``response``           one of the six emotions (:data:`~appeal.revcorr.observers.EMOTIONS`)
                       or ``dont_know``; ``n/a`` or empty: no answer, the trial is left out
``intensity``          1-5 (optional; ``n/a`` where the answer is "don't know")
``revcorr_seed``       the seed and the number of the trial in the grammar
``revcorr_trial``      (:func:`appeal.revcorr.grammar.draw_trial`): the AUs and their motions are
                       drawn again from them, exactly as the stimulus was
``revcorr_lateralised``  optional 0/1: the trial was drawn from the lateralised AUs
level columns          any, e.g. ``shape``: a model per participant x level (``levels=``)
=====================  ==================================================================

What a participant's browser sends is hostile until checked: every problem is one line naming the
file, the column, the row and what was expected.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from appeal.errors import AppealInputError
from appeal.revcorr.grammar import Trial, action_units, draw_trial
from appeal.revcorr.observers import DONT_KNOW, EMOTIONS

__all__ = ["MAX_TRIAL_INDEX", "RevcorrTrials", "read_revcorr_trials", "check_revcorr_trials", "simulated_table"]

#: The largest trial number accepted (a session of 100,000 trials is far beyond any study).
MAX_TRIAL_INDEX = 100_000
_MISSING = {"", "n/a", "na", "nan"}


@dataclass(frozen=True)
class RevcorrTrials:
    """Checked trials: the table (answered trials only) and each row's drawn :class:`Trial`."""

    table: pd.DataFrame
    trials: list[Trial]
    aus: tuple[str, ...]
    levels: tuple[str, ...]


def _where(row: pd.Series) -> str:
    src = row.get("source_file", "data")
    return f"{src}: row {row.get('source_row', row.name)}"


def _integers(table: pd.DataFrame, column: str, lo: int, hi: int) -> np.ndarray:
    values = pd.to_numeric(table[column], errors="coerce")
    bad = values.isna() | (values != np.floor(values)) | (values < lo) | (values > hi)
    if bad.any():
        row = table[bad].iloc[0]
        raise AppealInputError(f"{_where(row)}: {column} {str(row[column])[:40]}: expected a whole number {lo}-{hi}")
    return values.astype(np.int64).to_numpy()


def check_revcorr_trials(table: pd.DataFrame, subject: str = "participant_id",
                         levels: Sequence[str] = ()) -> RevcorrTrials:
    """Check a trials table and draw each trial's AUs again (see the module docstring); a ``revcorr:``
    session's data file (``response_emotion``, ``response_intensity``, ``phase``) reads as its main
    trials' ``response`` and ``intensity``."""
    if "response" not in table.columns and "response_emotion" in table.columns:
        attrs = dict(table.attrs)
        table = table.rename(columns={"response_emotion": "response", "response_intensity": "intensity"})
        if "phase" in table.columns:
            table = table[table["phase"].astype(str) == "main"]
        table.attrs.update(attrs)
    for column in (subject, "response", "revcorr_seed", "revcorr_trial", *levels):
        if column not in table.columns:
            raise AppealInputError(f"{table.attrs.get('source', 'data')}: no column '{column}' (expected "
                                   f"{subject}, response, revcorr_seed, revcorr_trial"
                                   f"{', ' + ', '.join(levels) if levels else ''})")
    t = table.copy()
    response = t["response"].astype(str).str.strip().str.lower()
    answered = ~response.isin(_MISSING) & t["response"].notna()
    t, response = t[answered].copy(), response[answered]
    if t.empty:
        raise AppealInputError(f"{table.attrs.get('source', 'data')}: no answered trials")
    known = set(EMOTIONS) | {DONT_KNOW}
    bad = ~response.isin(known)
    if bad.any():
        row = t[bad].iloc[0]
        raise AppealInputError(f"{_where(row)}: response {str(row['response'])[:40]!r}: expected one of "
                               f"{', '.join(sorted(known))}")
    t["response"] = response
    seeds = _integers(t, "revcorr_seed", 0, 2 ** 63 - 1)
    index = _integers(t, "revcorr_trial", 0, MAX_TRIAL_INDEX)
    lateral = _integers(t, "revcorr_lateralised", 0, 1) if "revcorr_lateralised" in t else np.zeros(len(t), int)
    if len(set(lateral)) > 1:
        raise AppealInputError(f"{table.attrs.get('source', 'data')}: revcorr_lateralised: the trials mix lateralised "
                               "and bilateral AUs (expected one or the other)")
    if "intensity" in t:
        given = ~t["intensity"].astype(str).str.strip().str.lower().isin(_MISSING) & t["intensity"].notna()
        t.loc[given, "intensity"] = _integers(t[given], "intensity", 1, 5)
        t["intensity"] = pd.to_numeric(t["intensity"].where(given), errors="coerce")
    aus = action_units(lateralised=bool(lateral[0]))
    trials = [draw_trial(int(s), int(i), aus=aus) for s, i in zip(seeds, index)]
    t[subject] = t[subject].astype(str)
    return RevcorrTrials(t.reset_index(drop=True), trials, aus, tuple(levels))


def read_revcorr_trials(data: str, subject: str = "participant_id", levels: Sequence[str] = ()) -> RevcorrTrials:
    """Read (a file or a quoted glob of ``*_beh.tsv``) and check the trials."""
    from analysis.stats.design import read_ratings

    table = read_ratings(data, subject)
    table.attrs["source"] = data
    return check_revcorr_trials(table, subject, levels)


def simulated_table(observers: dict[str, object], n_trials: int, seed: int = 0,
                    levels: dict[str, dict[str, object]] | None = None) -> pd.DataFrame:
    """The trials table simulated participants would leave: ``observers`` maps a participant id to
    a :class:`~appeal.revcorr.observers.TemplateObserver`, or, with ``levels`` (``{level value:
    {participant: observer}}``, a column ``level``), one observer per participant and level."""
    from analysis.revcorr.planning import simulate_participant

    plan = {None: observers} if levels is None else levels
    frames = []
    for k, (level, group) in enumerate(plan.items()):
        for j, (pid, obs) in enumerate(group.items()):
            s = seed + 1000 * j + k
            session = simulate_participant(obs, n_trials, s)
            df = pd.DataFrame({"participant_id": pid, "trial": np.arange(n_trials), "revcorr_seed": s,
                               "revcorr_trial": np.arange(n_trials), "response": session.answers,
                               "intensity": np.where(session.intensity > 0, session.intensity.astype(float), np.nan)})
            if level is not None:
                df.insert(1, "level", level)
            frames.append(df)
    return pd.concat(frames, ignore_index=True)
