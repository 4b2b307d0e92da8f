"""Protocol + stimuli + seed + refresh rate -> the plain list of trials a runner walks.

Everything here is pure and needs no window: ordering constraints, fixation jitter in whole
frames, breaks, anchors/practice/end-of-session items and trigger codes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd

from appeal.errors import AppealInputError
from appeal.levels import level_key
from appeal.triggers import trigger_table
from experiments.clips import ClipPlan, flips_per_frame, plan_clip, rate_problem
from experiments.ordering import constrained_order
from experiments.protocol_schema import REVCORR_COLUMNS, ExtraTrialsSpec, Protocol, TimingSpec
from experiments.psychophysics import PairPlan, PsychophysicsPlan
from experiments.stimuli import StimulusSet, select_stimuli

__all__ = ["Trial", "seconds_to_frames", "fixation_frame_range", "fixation_sampler", "build_trials",
           "protocol_trigger_codes", "trials_frame", "insert_repeat", "pair_trial_maker", "revcorr_subset"]


@dataclass
class Trial:
    """One presentation: what to show, for how many frames, what to ask, which trigger."""

    trial: int
    phase: str
    block: str
    repetition: int
    stimulus: str
    path: str
    factors: dict[str, str]
    stimulus_frames: int
    fixation_frames: int | None = None
    iti_frames: int = 0
    respond: bool = True
    trigger: int | None = None
    break_before: bool = False
    title: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    clip: ClipPlan | None = None
    repeat_of: int | None = None
    pair: PairPlan | None = None

    def as_dict(self) -> dict[str, Any]:
        """A flat dict (factors as columns; a clip's plan as ``clip_frames``, ``clip_fps``, ...; a pair
        trial's psychophysics fields, :data:`experiments.psychophysics.PSYCHOPHYSICS_COLUMNS`)."""
        d = asdict(self)
        d.pop("extra")
        d.pop("clip")
        d.pop("pair")
        d.update(self.extra.get("psy", {}))
        factors = d.pop("factors")
        if self.clip is not None:
            d.update(clip_frames=self.clip.n_frames, clip_fps=self.clip.fps,
                     clip_flips_per_frame=self.clip.flips_per_frame)
        return {**d, **factors}


def seconds_to_frames(seconds: float, refresh_hz: float) -> int:
    """Whole frames closest to ``seconds`` at ``refresh_hz`` (at least one)."""
    return max(1, int(round(seconds * refresh_hz)))


def fixation_frame_range(lo_s: float, hi_s: float, refresh_hz: float) -> tuple[int, int]:
    """The whole-frame counts whose duration lies within ``[lo_s, hi_s]``.

    Raises
    ------
    AppealInputError
        If no whole number of frames fits in the interval.
    """
    lo = math.ceil(lo_s * refresh_hz - 1e-9)
    hi = math.floor(hi_s * refresh_hz + 1e-9)
    if hi < lo:
        raise AppealInputError(f"timing.fixation_s: [{lo_s}, {hi_s}] s holds no whole frame at {refresh_hz:g} Hz")
    return max(lo, 1), max(hi, 1)


def fixation_sampler(timing: TimingSpec, refresh_hz: float,
                     rng: np.random.Generator) -> Callable[[], int | None]:
    """A function drawing each trial's fixation in whole frames (None: no fixation)."""
    fix_range = None
    if isinstance(timing.fixation_s, tuple):
        fix_range = fixation_frame_range(*timing.fixation_s, refresh_hz)
    elif timing.fixation_s is not None and timing.fixation_s > 0:
        n = seconds_to_frames(timing.fixation_s, refresh_hz)
        fix_range = (n, n)

    def fixation() -> int | None:
        return None if fix_range is None else int(rng.integers(fix_range[0], fix_range[1] + 1))
    return fixation


def pair_trial_maker(protocol: Protocol, refresh_hz: float) -> Callable[..., Trial]:
    """The function a :class:`~experiments.psychophysics.PsychophysicsPlan` makes its trials with:
    frames from the protocol's timing, the fixation from the trial's own generator, a break
    before every ``breaks.every``-th trial."""
    timing = protocol.timing
    frames = seconds_to_frames(timing.stimulus_s, refresh_hz)
    iti = int(round(timing.iti_s * refresh_hz))
    isi = seconds_to_frames(protocol.psychophysics.isi_s, refresh_hz) if protocol.psychophysics.isi_s > 0 else 0
    layout = protocol.psychophysics.presentation

    def make(*, number: int, phase: str, block: str, repetition: int, row: Mapping[str, Any], pair: tuple[str, str],
             psy: dict[str, Any], rng: np.random.Generator) -> Trial:
        every = protocol.breaks.every if protocol.breaks is not None else 0
        return Trial(trial=number, phase=phase, block=block, repetition=repetition, stimulus=row["stimulus"],
                     path=row["path"], factors={f: row[f] for f in protocol.stimuli.factors}, stimulus_frames=frames,
                     fixation_frames=fixation_sampler(timing, refresh_hz, rng)(), iti_frames=iti,
                     break_before=bool(every) and number > 1 and (number - 1) % every == 0,
                     extra={"psy": psy}, pair=PairPlan(pair, layout, isi))
    return make


def protocol_trigger_codes(protocol: Protocol) -> list[tuple[int, dict[str, str]]]:
    """The protocol's trigger codes as ``(code, {factor: level-string})`` pairs (the table of
    :func:`appeal.triggers.trigger_table`, which the ERP analysis reads too)."""
    if protocol.triggers is None:
        return []
    table = trigger_table(protocol.triggers.codes)
    return [(code, {k: level_key(v) for k, v in levels.items()}) for code, levels in table.items()]


def _code_for(factors: Mapping[str, str], table: list[tuple[int, dict[str, str]]]) -> list[int]:
    return [code for code, cond in table if all(factors.get(k) == v for k, v in cond.items())]


def _assign_triggers(main: pd.DataFrame, protocol: Protocol, source: str) -> dict[str, int]:
    table = protocol_trigger_codes(protocol)
    out: dict[str, int] = {}
    problems = []
    for _, row in main.iterrows():
        factors = {f: row[f] for f in protocol.stimuli.factors}
        codes = _code_for(factors, table)
        cond = ", ".join(f"{k}={v}" for k, v in factors.items())
        if not codes:
            problems.append(f"{source}: triggers.codes: no code for condition {cond} (stimulus {row['stimulus']})")
        elif len(codes) > 1:
            problems.append(f"{source}: triggers.codes: codes {codes} all match condition {cond}")
        else:
            out[row["stimulus"]] = codes[0]
    if problems:
        raise AppealInputError(problems[:10] + ([f"{source}: triggers.codes: ... {len(problems) - 10} more"]
                                                if len(problems) > 10 else []))
    return out


def _extra(spec: ExtraTrialsSpec | None, phase: str, stimuli: StimulusSet, protocol: Protocol,
           rng: np.random.Generator, source: str) -> list[dict[str, Any]]:
    if spec is None:
        return []
    rows: list[dict[str, Any]] = []
    if spec.select is not None:
        sel = select_stimuli(stimuli, spec.select).table
        rows.extend(sel.to_dict("records"))
    for f in spec.files:
        if not f.is_file():
            if spec.if_missing == "skip":
                continue
            raise AppealInputError(f"{source}: {phase}.files: file not found: {f}")
        rows.append({"stimulus": f.name, "path": str(f),
                     **{fac: level_key(spec.factors.get(fac, "")) for fac in protocol.stimuli.factors}})
    if not rows:
        if spec.if_missing == "skip":
            return []
        raise AppealInputError(f"{source}: {phase}.select: selects no stimulus (set if_missing: skip to allow)")
    if spec.order == "random":
        rows = [rows[i] for i in rng.permutation(len(rows))]
    if spec.n is not None:
        rows = rows[: spec.n]
    return rows


def revcorr_subset(table: pd.DataFrame, protocol: Protocol, seed: int, source: str = "protocol") -> pd.DataFrame:
    """The rows of a reverse-correlation pool a participant sees (``revcorr.trials`` of them at every
    level combination of the other factors, the same trials at each, drawn by ``seed``); the whole
    pool without ``revcorr.trials``.

    Raises
    ------
    AppealInputError
        When the pool holds fewer trials common to every level combination than asked for.
    """
    n = protocol.revcorr.trials
    if n is None:
        return table
    key = table["revcorr_seed"] + ":" + table["revcorr_trial"]
    levels = [f for f in protocol.stimuli.factors if f not in REVCORR_COLUMNS]
    groups = [set(k) for _, k in key.groupby([table[f] for f in levels], sort=False)] if levels else [set(key)]
    common = sorted(set.intersection(*groups), key=lambda k: tuple(int(x) for x in k.split(":")))
    if len(common) < n:
        raise AppealInputError(f"{source}: revcorr.trials: {n} trials asked for, but the pool holds {len(common)} "
                               f"at every level combination of {', '.join(levels) or 'the stimuli'}")
    chosen = set(np.random.default_rng([int(seed), 53]).choice(common, size=n, replace=False).tolist())
    return table[key.isin(chosen)].reset_index(drop=True)


def build_trials(protocol: Protocol, stimuli: StimulusSet, *, seed: int, refresh_hz: float,
                 source: str = "protocol", full_set: StimulusSet | None = None,
                 plan: PsychophysicsPlan | None = None) -> list[Trial]:
    """The whole session as a list of :class:`Trial` (anchors, practice, main, end items).

    Parameters
    ----------
    protocol : Protocol
        The validated protocol.
    stimuli : StimulusSet
        The main-trial images (already filtered by ``stimuli.select``).
    seed : int
        All randomness (orders, fixation jitter, practice picks) derives from it.
    refresh_hz : float
        Frames per second used to turn seconds into frames.
    source : str
        The protocol file, named in errors.
    full_set : StimulusSet, optional
        The unfiltered set anchors/practice/end items select from (default ``stimuli``).
    plan : PsychophysicsPlan, optional
        A psychophysics protocol's tracks (default: made here): the list holds their first
        trial, and grows by one after each answer (:meth:`PsychophysicsPlan.next_trial`).

    Returns
    -------
    list of Trial
        Numbered from 1 in presentation order.
    """
    if protocol.psychophysics is not None:
        plan = plan or PsychophysicsPlan(protocol, stimuli, seed=seed, source=source)
        first = plan.next_trial(1, pair_trial_maker(protocol, refresh_hz))
        return [first] if first is not None else []
    ss = np.random.SeedSequence(seed)
    rng_order, rng_fix, rng_extra = (np.random.default_rng(s) for s in ss.spawn(3))
    full_set = full_set or stimuli
    main = stimuli.table if protocol.revcorr is None else revcorr_subset(stimuli.table, protocol, seed, source)
    factors = protocol.stimuli.factors
    attrs = {r["stimulus"]: {f: r[f] for f in factors} for r in main.to_dict("records")}
    rows_by_stim = {r["stimulus"]: r for r in main.to_dict("records")}
    triggers = _assign_triggers(main, protocol, source) if protocol.triggers is not None else {}
    spec = protocol.order
    stim_ids = list(main["stimulus"])
    kw = dict(no_repeat=spec.no_immediate_repeat, max_run=spec.max_run)

    def ordered(ids: list[str], history: list[str]) -> list[str]:
        if spec.order == "fixed":
            return ids
        return constrained_order(ids, attrs, rng_order, history=history[-max([1, *spec.max_run.values()]):], **kw)

    # (stimulus, block label, repetition) in presentation order
    plan: list[tuple[str, str, int]] = []
    if spec.order == "blocked":
        keys = main[spec.block_by].astype(str).agg("_".join, axis=1) if spec.block_by else pd.Series("1", index=main.index)
        labels = list(dict.fromkeys(keys))
        if spec.block_order == "random":
            labels = [labels[i] for i in rng_order.permutation(len(labels))]
        for label in labels:
            ids = list(main["stimulus"][keys == label])
            if spec.shuffle == "per_repetition":
                for rep in range(spec.repetitions):
                    plan += [(s, label, rep + 1) for s in ordered(ids, [p[0] for p in plan])]
            else:
                seq = ordered(ids * spec.repetitions, [p[0] for p in plan])
                plan += _with_repetitions(seq, label)
    elif spec.shuffle == "per_repetition":
        for rep in range(spec.repetitions):
            plan += [(s, str(rep + 1), rep + 1) for s in ordered(stim_ids, [p[0] for p in plan])]
    else:
        plan = _with_repetitions(ordered(stim_ids * spec.repetitions, []), "1")

    timing = protocol.timing
    fixation = fixation_sampler(timing, refresh_hz, rng_fix)
    stim_frames = seconds_to_frames(timing.stimulus_s, refresh_hz)
    iti = int(round(timing.iti_s * refresh_hz))
    trials: list[Trial] = []
    bad_rates: dict[float, list[str]] = {}

    def add(row: Mapping[str, Any], phase: str, block: str, rep: int, *, respond: bool, frames: int,
            trigger: int | None = None, title: str = "") -> None:
        clip = None
        if row.get("frames") is not None:
            if flips_per_frame(float(row["fps"]), refresh_hz) is None:
                bad_rates.setdefault(float(row["fps"]), []).append(row["stimulus"])
            else:
                clip = plan_clip(dict(row), refresh_hz, frames, clip_end=timing.clip_end, trigger_at=timing.clip_trigger)
                frames = clip.total_flips
        trials.append(Trial(trial=len(trials) + 1, phase=phase, block=block, repetition=rep,
                            stimulus=row["stimulus"], path=row["path"], factors={f: row[f] for f in factors},
                            stimulus_frames=frames, fixation_frames=fixation(), iti_frames=iti,
                            respond=respond and bool(protocol.responses), trigger=trigger, title=title, clip=clip))

    for phase in ("anchors", "practice"):
        extra = getattr(protocol, phase)
        for row in _extra(extra, phase, full_set, protocol, rng_extra, source):
            frames = seconds_to_frames(extra.stimulus_s or timing.stimulus_s, refresh_hz)
            add(row, phase.rstrip("s") if phase == "anchors" else phase, phase, 0,
                respond=extra.respond, frames=frames, title=extra.title)
    n_main = 0
    for stim, block, rep in plan:
        add(rows_by_stim[stim], "main", block, rep, respond=True, frames=stim_frames, trigger=triggers.get(stim))
        if protocol.breaks is not None and n_main > 0 and n_main % protocol.breaks.every == 0:
            trials[-1].break_before = True
        n_main += 1
    extra = protocol.end_of_session
    for row in _extra(extra, "end_of_session", full_set, protocol, rng_extra, source):
        add(row, "end", "end", 0, respond=extra.respond,
            frames=seconds_to_frames(extra.stimulus_s or timing.stimulus_s, refresh_hz), title=extra.title)
    if bad_rates:
        raise AppealInputError([rate_problem(fps, refresh_hz, str(stimuli.source), sorted(set(names))[0],
                                             len(set(names))) for fps, names in sorted(bad_rates.items())])
    return trials


def _with_repetitions(seq: list[str], block: str) -> list[tuple[str, str, int]]:
    seen: dict[str, int] = {}
    out = []
    for s in seq:
        seen[s] = seen.get(s, 0) + 1
        out.append((s, block, seen[s]))
    return out


def _block_end(trials: list[Trial], index: int) -> int:
    """The position after the last trial of ``trials[index]``'s block (same phase and block label)."""
    key = (trials[index].phase, trials[index].block)
    end = index + 1
    while end < len(trials) and (trials[end].phase, trials[end].block) == key:
        end += 1
    return end


def insert_repeat(trials: list[Trial], index: int, max_repeats: int) -> Trial | None:
    """Repeat ``trials[index]`` at the end of its block (``timing.on_dropped_frames: repeat``).

    The copy keeps the stimulus, fixation, trigger and responses of the trial it repeats;
    its ``repeat_of`` is the planned trial's number (the first attempt's); the trials after
    it are renumbered (their numbers are presentation positions). Only trials not yet
    presented move, so rows already written keep their numbers.

    Parameters
    ----------
    trials : list of Trial
        The session's list, changed in place.
    index : int
        The position of the trial that had dropped frames.
    max_repeats : int
        Repeats allowed per planned trial.

    Returns
    -------
    Trial or None
        The inserted copy, or None when the planned trial has been repeated ``max_repeats`` times.
    """
    original = trials[index]
    planned = original.repeat_of if original.repeat_of is not None else original.trial
    if sum(1 for t in trials if t.repeat_of == planned) >= max_repeats:
        return None
    at = _block_end(trials, index)
    copy = replace(original, repeat_of=planned, break_before=False, extra=dict(original.extra))
    trials.insert(at, copy)
    for pos in range(at, len(trials)):
        trials[pos].trial = pos + 1
    return copy


def trials_frame(trials: list[Trial]) -> pd.DataFrame:
    """The trial list as a tidy table (one row per trial, factors as columns)."""
    return pd.DataFrame([t.as_dict() for t in trials])
