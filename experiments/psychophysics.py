"""Psychophysical procedures along a continuum: pairs of faces, tracks that pick each next level.

A protocol with ``psychophysics:`` (:class:`~experiments.protocol_schema.PsychophysicsSpec`)
runs tracks — one procedure (:mod:`appeal.psychophysics.procedures`: psi, up–down staircase or
constant stimuli) per condition — over the *differences* between a comparison level and the
reference level of a continuum factor (e.g. ``shape`` from 0, realistic, to 1, cartoon), read
by value from the stimulus table. Each trial shows the reference face and the comparison face
of one item (the same character, expression ...) side by side or in sequence, the reference's
position balanced within every two trials of a track; the answer is scored, the track's
procedure updated and the next trial made from it, so the trial list grows one trial at a time.

Everything that decides a trial (which track, which item, which side, the fixation) is drawn
from generators seeded by the session seed and the trial's number, and the procedures are
rebuilt from the answers on disk (:meth:`PsychophysicsPlan.replay`), so a resumed session
continues exactly where the answers left each procedure.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from appeal.errors import AppealInputError
from appeal.labels import shown
from appeal.levels import level_key
from appeal.psychophysics import ConstantStimuli, PsiProcedure, UpDownStaircase
from appeal.psychophysics.procedures import Procedure
from experiments.protocol_schema import ClassificationSpec, ProcedureSpec, Protocol, PsychophysicsSpec
from experiments.stimuli import StimulusSet

__all__ = ["PairPlan", "Track", "PsychophysicsPlan", "PSYCHOPHYSICS_COLUMNS", "PSYCHOPHYSICS_DESCRIPTIONS",
           "make_procedure", "continuum_values"]

#: The columns a psychophysics session adds to ``_beh.tsv`` (after the response's).
PSYCHOPHYSICS_COLUMNS = ["procedure", "procedure_kind", "procedure_trial", "level", "reference_level", "difference",
                         "pair_type", "reference_side", "reference_stimulus", "correct", "estimate_threshold",
                         "estimate_threshold_lo", "estimate_threshold_hi", "estimate_level", "procedure_state"]

PSYCHOPHYSICS_DESCRIPTIONS = {
    "procedure": "the track (one procedure per condition): its label",
    "procedure_kind": "psi, updown (staircase) or constant (method of constant stimuli)",
    "procedure_trial": "this trial's number within its track (1-based)",
    "level": "the comparison face's level on the continuum",
    "reference_level": "the reference face's level on the continuum",
    "difference": "|level - reference_level|: the procedure's stimulus variable (0 on a 'same' pair)",
    "pair_type": "different, or same (same_different: both faces the reference)",
    "reference_side": "where the reference face was: left/right (side by side) or first/second (sequence)",
    "reference_stimulus": "the reference face's image",
    "correct": "1: the answer was right (2AFC: chose the reference face; same_different: named the pair type), "
               "0: wrong, n/a: no answer",
    "estimate_threshold": "the track's threshold estimate after this trial, in difference units (psi: posterior mean; "
                          "staircase: mean of the last 6 reversals)",
    "estimate_threshold_lo": "lower end of its 95 % credible interval (psi)",
    "estimate_threshold_hi": "upper end of its 95 % credible interval (psi)",
    "estimate_level": "estimate_threshold as a level of the continuum",
    "procedure_state": "the track's procedure after this trial as JSON (settings and every answer)",
}


@dataclass(frozen=True)
class PairPlan:
    """The two images of a pair trial in presentation order (left, right or first, second)."""

    paths: tuple[str, str]
    layout: str
    isi_frames: int = 0


@dataclass
class Track:
    """One interleaved procedure: its condition, label and the trials it has shown."""

    index: int
    label: str
    condition: dict[str, str]
    procedure: Procedure
    shown: int = 0


def continuum_values(stimuli: StimulusSet, factor: str, where: str) -> dict[str, float]:
    """Each level string of a continuum factor as a number (one-line error for one that is not)."""
    out = {}
    for level in stimuli.levels(factor):
        try:
            out[level] = float(level)
        except ValueError:
            raise AppealInputError(f"{where}: psychophysics.continuum: factor '{factor}' has the level '{level}', "
                                   f"expected numbers (the continuum's values)") from None
    return out


def _find_level(values: Sequence[float], value: float, field: str, where: str) -> float:
    lo, hi = min(values), max(values)
    tol = 1e-6 * max(hi - lo, 1.0)
    if value < lo - tol or value > hi + tol:
        raise AppealInputError(f"{where}: {field}: {value:g} is outside the continuum [{lo:g}, {hi:g}]")
    near = min(values, key=lambda v: abs(v - value))
    if abs(near - value) > tol:
        raise AppealInputError(f"{where}: {field}: {value:g} is not one of the continuum's {len(values)} levels "
                               f"(nearest: {near:g})")
    return near


def make_procedure(spec: ProcedureSpec, differences: Sequence[float], guess: float, seed: int) -> Procedure:
    """The procedure of one track over ``differences`` (increasing: larger is easier)."""
    if spec.method == "psi":
        return PsiProcedure(differences, guess=guess, family=spec.family, max_trials=spec.max_trials,
                            max_ci_width=spec.max_ci_width, min_trials=spec.min_trials)
    if spec.method == "staircase":
        return UpDownStaircase(differences, down=spec.down, up=spec.up, step=spec.step, max_trials=spec.max_trials,
                               max_reversals=spec.max_reversals)
    return ConstantStimuli(differences, int(spec.trials_per_level), seed=seed)


class PsychophysicsPlan:
    """The tracks of a psychophysics session and the trials they ask for.

    Parameters
    ----------
    protocol : Protocol
        A protocol with ``psychophysics``.
    stimuli : StimulusSet
        The main-trial images (their continuum column holds numbers).
    seed : int
        The session seed.
    source : str
        The protocol file, named in errors.

    Raises
    ------
    AppealInputError
        A reference or comparison level outside the continuum or not one of its levels, a
        missing or ambiguous image for a condition × item × level, a stopping rule missing.
    """

    def __init__(self, protocol: Protocol, stimuli: StimulusSet, *, seed: int, source: str = "protocol"):
        psy = protocol.psychophysics
        if psy is None:
            raise ValueError("the protocol has no psychophysics section")
        if stimuli.has_clips:
            raise AppealInputError(f"{source}: psychophysics: the stimuli are clips ({stimuli.source}); pairs are "
                                   "still images")
        self.spec: PsychophysicsSpec = psy
        self.protocol, self.seed, self.source = protocol, int(seed), source
        self.response: ClassificationSpec = protocol.responses[0]  # type: ignore[assignment]
        where = f"{source} ({stimuli.source})"
        values = continuum_values(stimuli, psy.continuum, where)
        numbers = sorted(set(values.values()))
        self.reference = _find_level(numbers, psy.reference, "psychophysics.reference", where)
        wanted = psy.levels or [v for v in numbers if v != self.reference]
        comparisons = sorted({_find_level(numbers, v, "psychophysics.levels", where) for v in wanted})
        if not comparisons:
            raise AppealInputError(f"{where}: psychophysics: the continuum '{psy.continuum}' has no level besides the "
                                   f"reference {self.reference:g}")
        sides = {np.sign(v - self.reference) for v in comparisons}
        if len(sides) > 1:
            raise AppealInputError(f"{where}: psychophysics.levels: comparison levels lie on both sides of the "
                                   f"reference {self.reference:g}; expected one side (list them in 'levels')")
        self.direction = float(sides.pop())
        self.level_of = {round(abs(v - self.reference), 9): v for v in comparisons}
        self.differences = sorted(self.level_of)
        factors = protocol.stimuli.factors
        items = psy.items if psy.items is not None else [
            f for f in factors if f not in {psy.continuum, *psy.conditions, *psy.with_continuum}]
        self.items_factors = items
        table = stimuli.table
        self._rows = self._index(table, values, where)
        self.conditions = [dict(zip(psy.conditions, combo)) for combo in
                           itertools.product(*(stimuli.levels(f) for f in psy.conditions))]
        self.items = list(dict.fromkeys(tuple(r[f] for f in items) for r in table.to_dict("records")))
        self._check_complete(where)
        guess = psy.procedure.guess if psy.procedure.guess is not None else (0.5 if psy.task == "2afc" else 0.0)
        self.tracks: list[Track] = []
        for cond in self.conditions:
            for j in range(psy.interleave):
                label = "_".join(f"{k}-{v}" for k, v in cond.items()) or "all"
                label += f"_{j + 1}" if psy.interleave > 1 else ""
                index = len(self.tracks)
                seed_j = int(np.random.SeedSequence([self.seed, 17, index]).generate_state(1)[0])
                self.tracks.append(Track(index, label, cond, make_procedure(psy.procedure, self.differences, guess,
                                                                            seed_j)))
        self.practice_left = psy.practice_trials

    # ------------------------------------------------------------------ the stimulus table
    def _key(self, row: Mapping[str, str], level: float) -> tuple:
        psy = self.spec
        return (tuple(row[f] for f in psy.conditions), tuple(row[f] for f in self.items_factors), level)

    def _index(self, table: Any, values: Mapping[str, float], where: str) -> dict[tuple, dict[str, Any]]:
        rows: dict[tuple, dict[str, Any]] = {}
        for row in table.to_dict("records"):
            key = self._key(row, values[row[self.spec.continuum]])
            if key in rows:
                differ = [f for f in self.protocol.stimuli.factors if rows[key][f] != row[f]]
                raise AppealInputError(f"{where}: psychophysics: two images for the same condition, item and level "
                                       f"({rows[key]['stimulus']}, {row['stimulus']}: they differ in "
                                       f"{', '.join(differ) or 'nothing'}); name such factors in "
                                       "psychophysics.with_continuum, items or conditions")
            rows[key] = row
        return rows

    def _check_complete(self, where: str) -> None:
        missing = []
        for cond in self.conditions:
            for item in self.items:
                for level in [self.reference, *self.level_of.values()]:
                    if (tuple(cond.values()), item, level) not in self._rows:
                        named = {**cond, **dict(zip(self.items_factors, item)), self.spec.continuum: f"{level:g}"}
                        missing.append(", ".join(f"{k}={v}" for k, v in named.items()))
        if missing:
            more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
            raise AppealInputError(f"{where}: psychophysics: no image for {missing[0]}{more}; every condition and "
                                   "item needs the reference and every comparison level")

    # ------------------------------------------------------------------ trials
    @property
    def max_trials(self) -> int | None:
        """The most trials the session can have (None when a track stops only by its interval width)."""
        total = self.spec.practice_trials
        for t in self.tracks:
            p = t.procedure
            n = len(p.levels) * p.trials_per_level if isinstance(p, ConstantStimuli) else p.max_trials
            if n is None:
                return None
            total += n if self.spec.task == "2afc" else math.ceil(n / (1 - self.spec.same_proportion))
        return total

    @property
    def finished(self) -> bool:
        """Whether every track has stopped."""
        return self.practice_left == 0 and all(t.procedure.finished for t in self.tracks)

    def next_trial(self, number: int, make: Callable[..., Any]) -> Any | None:
        """The trial numbered ``number`` (None when every track has stopped).

        ``make(number=, phase=, block=, repetition=, row=, pair=, psy=, rng=)`` builds the
        runner's :class:`~experiments.trials.Trial` (fixation and frames) from the choice made here.
        """
        if self.finished:
            return None
        rng = np.random.default_rng([self.seed, 23, number])
        psy = self.spec
        practice = self.practice_left > 0
        if practice:
            track = self.tracks[int(rng.integers(len(self.tracks)))]
            difference, shown = self.differences[-1], psy.practice_trials - self.practice_left
        else:
            active = [t for t in self.tracks if not t.procedure.finished]
            track = active[int(rng.integers(len(active)))]
            difference, shown = track.procedure.next_level(), track.shown
        item = self.items[int(rng.integers(len(self.items)))]
        pair_type = "different"
        if psy.task == "same_different" and not practice and rng.random() < psy.same_proportion:
            pair_type = "same"
        level = self.level_of[difference] if pair_type == "different" else self.reference
        cond = tuple(track.condition.values())
        comparison = self._rows[(cond, item, level)]
        reference = self._rows[(cond, item, self.reference)]
        first, second = ("first", "second") if psy.presentation == "sequence" else ("left", "right")
        # the reference's position, balanced within each two trials of a track
        order = np.random.default_rng([self.seed, 29, track.index, shown // 2, int(practice)]).permutation(2)
        ref_first = bool(order[shown % 2] == 0)
        paths = (reference["path"], comparison["path"]) if ref_first else (comparison["path"], reference["path"])
        info = {"procedure": "practice" if practice else track.label,
                "procedure_kind": "practice" if practice else track.procedure.kind,
                "procedure_trial": shown + 1, "level": level, "reference_level": self.reference,
                "difference": abs(level - self.reference), "pair_type": pair_type,
                "reference_side": first if ref_first else second, "reference_stimulus": reference["stimulus"]}
        return make(number=number, phase="practice" if practice else "main", block=info["procedure"],
                    repetition=shown + 1, row=comparison, pair=paths, psy=info, rng=rng)

    def score(self, info: Mapping[str, Any], answer: str | None) -> dict[str, Any]:
        """The row's ``correct``, updates the track's procedure, and the track's state after it.

        Parameters
        ----------
        info : mapping
            The trial's psychophysics fields (:meth:`next_trial`'s ``psy``).
        answer : str or None
            The classification's value (None: no answer; the procedure is not updated and the
            track asks again).
        """
        psy = self.spec
        if psy.task == "2afc":
            correct = None if answer is None else int(answer == info["reference_side"])
        else:
            correct = None if answer is None else int(answer == info["pair_type"])
        if info["procedure"] == "practice":
            if answer is not None:
                self.practice_left = max(0, self.practice_left - 1)
            return {"correct": correct}
        track = next(t for t in self.tracks if t.label == info["procedure"])
        if answer is None:
            return {"correct": None, **self._state(track)}
        track.shown += 1
        if info["pair_type"] == "different":
            track.procedure.update(float(info["difference"]), bool(correct))
        return {"correct": correct, **self._state(track)}

    def _state(self, track: Track) -> dict[str, Any]:
        est = track.procedure.estimate()
        thr = est.get("threshold")
        out = {"estimate_threshold": thr, "estimate_threshold_lo": est.get("threshold_lo"),
               "estimate_threshold_hi": est.get("threshold_hi"),
               "estimate_level": None if thr is None or not np.isfinite(thr) else self.reference + self.direction * thr,
               "procedure_state": json.dumps(track.procedure.to_dict(), separators=(",", ":"))}
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in out.items()}

    def answered(self, trials: list[Any], index: int, answer: str | None, make: Callable[..., Any]) -> dict[str, Any]:
        """Score ``trials[index]``'s answer (:meth:`score`) and append the next trial, if any;
        returns the row's fields. The runner calls it after each trial, :meth:`replay` for each row."""
        fields = self.score(trials[index].extra["psy"], answer)
        nxt = self.next_trial(len(trials) + 1, make)
        if nxt is not None:
            trials.append(nxt)
        return fields

    def replay(self, rows: Sequence[Mapping[str, str]], trials: list[Any], make: Callable[..., Any],
               where: str) -> None:
        """Rebuild the procedures from the rows on disk (a resumed session), growing ``trials``.

        ``trials`` starts with the session's first trial; each row must match the trial it was
        planned as (stimulus and track), and the answers in the rows update the procedures as
        they did when the rows were written. The rows are data anyone can edit: a row past the
        session's last trial, one that does not match its trial, or an answer that is not one of
        the response's choice values (nor ``n/a``) is a one-line error; the ``procedure_state``
        column is never read (the procedures are rebuilt from the answers alone), so the work is
        one procedure update per row.
        """
        answer_col = f"response_{self.response.name}"
        choices = {form for c in self.response.choices for form in (str(c.value), level_key(c.value))}
        for i, row in enumerate(rows):
            trial = row.get("trial", str(i + 1))
            plain = isinstance(trial, str) and trial.isascii() and trial.isdigit() and len(trial) < 10
            number = trial if plain else shown(trial)
            if i >= len(trials):
                raise AppealInputError(f"{where}: trial {number}: {len(rows)} rows, but the procedures stopped after "
                                       f"{len(trials)} trials; was the file edited, or the protocol changed?")
            t = trials[i]
            info = t.extra["psy"]
            stimulus, procedure = row.get("stimulus"), row.get("procedure")
            if stimulus != t.stimulus or procedure != info["procedure"]:
                raise AppealInputError(f"{where}: trial {number} ({shown(stimulus)}, {shown(procedure)}) does not "
                                       f"match the procedure's trial ({t.stimulus}, {info['procedure']}); was the "
                                       "seed, protocol or stimulus set changed?")
            answer = row.get(answer_col)
            if answer not in (None, "", "n/a") and answer not in choices:
                raise AppealInputError(f"{where}: trial {number}: {answer_col}: expected one of "
                                       f"{', '.join(sorted(choices))} or n/a, got {shown(answer)}")
            self.answered(trials, i, None if answer in (None, "", "n/a") else answer, make)
