"""The schema of a procedure's state, checked before a procedure is built from it.

A state read back (:func:`procedure_from_json`, :func:`procedure_from_dict`, ``Cls.from_dict``)
comes from a data file anyone can edit, so it is treated as hostile: it is plain JSON data, read
with :func:`json.loads` only — nothing in it is ever executed (no pickle, no ``eval``, no class or
function named by the state is looked up) — and it is checked against the schema below
(:func:`state_problems`) before anything is built from it, so that a state can neither allocate
nor compute without bound. Each violation is one line ``procedure_state: <field>: expected ...,
got <value>`` of an :class:`~appeal.errors.AppealInputError`.

The schema of a state (every field but ``history`` is required; no other field is allowed):

* every kind: ``kind`` (``"psi"``, ``"updown"`` or ``"constant"``); ``levels``, a list of 2 to
  :data:`MAX_LEVELS` finite, strictly increasing numbers (``|x| <=`` :data:`MAX_MAGNITUDE`);
  ``history``, a list of at most :data:`MAX_HISTORY` answers (and at most the procedure's
  trial limit), each ``[level, correct]`` with the level one of ``levels`` and ``correct``
  ``true``/``false`` or ``1``/``0``.
* ``psi``: ``thresholds`` and ``widths`` (widths positive), lists of 1 to :data:`MAX_AXIS`
  increasing numbers, ``lapses`` of 1 to :data:`MAX_LAPSES` increasing numbers in [0, 0.5],
  their grid with the levels at most :data:`MAX_PSI_CELLS` cells (so the tables stay under
  ~100 MB) and the replay of the history at most :data:`MAX_REPLAY` cell updates; ``guess``
  in [0, 1) with ``guess + max(lapses) < 1``; ``family`` one of
  :data:`~appeal.psychophysics.functions.FAMILIES` (``weibull``: positive levels);
  ``max_trials`` (integer 1 to :data:`MAX_HISTORY`, or null), ``max_ci_width`` (positive
  number or null; one of the two given), ``min_trials`` (integer 0 to :data:`MAX_HISTORY`),
  ``ci_level`` and ``pc`` in (0, 1), ``alpha`` in (0, 0.5), ``entropy`` ``"joint"`` or
  ``"threshold"``.
* ``updown``: ``down``, ``up``, ``step`` (integers 1 to :data:`MAX_LEVELS`), ``start`` (one of
  the levels, or null), ``max_trials``, ``max_reversals`` (integers 1 to :data:`MAX_HISTORY`, or
  null; one of the two given).
* ``constant``: ``trials_per_level`` (integer >= 1, at most :data:`MAX_HISTORY` trials over all
  levels), ``seed`` (integer 0 to 2**63 - 1).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from appeal.errors import AppealInputError
from appeal.labels import shown
from appeal.psychophysics.continuum import level_index
from appeal.psychophysics.functions import FAMILIES

__all__ = ["SETTINGS", "state_problems", "describe_value", "MAX_STATE_CHARS", "MAX_LEVELS", "MAX_AXIS", "MAX_LAPSES",
           "MAX_PSI_CELLS", "MAX_HISTORY", "MAX_REPLAY", "MAX_MAGNITUDE"]

#: The settings each kind of procedure keeps in its state (besides ``kind``, ``levels`` and ``history``).
SETTINGS: dict[str, tuple[str, ...]] = {
    "psi": ("thresholds", "widths", "lapses", "guess", "family", "max_trials", "max_ci_width", "min_trials",
            "ci_level", "entropy", "pc", "alpha"),
    "updown": ("down", "up", "step", "start", "max_trials", "max_reversals"),
    "constant": ("trials_per_level", "seed"),
}
#: The longest state text :func:`procedure_from_json` parses (characters).
MAX_STATE_CHARS = 2_000_000
#: The most levels a procedure may have.
MAX_LEVELS = 1001
#: The most points of the psi grid's threshold axis and of its width axis.
MAX_AXIS = 1001
#: The most points of the psi grid's lapse axis.
MAX_LAPSES = 101
#: The most cells of the psi method's (threshold x width x lapse) x level tables (8 MB each).
MAX_PSI_CELLS = 1_000_000
#: The most answers a state's history may hold (and the most trials a plan may have).
MAX_HISTORY = 100_000
#: The most grid-point updates replaying a psi history may take (history length x grid points).
MAX_REPLAY = 200_000_000
#: The largest magnitude of a level or grid value.
MAX_MAGNITUDE = 1e12
_MAX_SEED = 2 ** 63 - 1


def describe_value(value: Any) -> str:
    """``value`` as a message shows it: a scalar quoted (:func:`~appeal.labels.shown`), a container
    by its type and size (never its whole text)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return f"a list of {len(value)} item{'s' if len(value) != 1 else ''}"
    if isinstance(value, Mapping):
        return f"an object of {len(value)} field{'s' if len(value) != 1 else ''}"
    if isinstance(value, int) and value.bit_length() > 100:
        return f"an integer of about {int(value.bit_length() * 0.30103) + 1} digits"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return shown(value)
    return f"a {type(value).__name__}"


def _fmt(x: float) -> str:
    return f"{x:g}"


class _Missing:
    """A field the state lacks."""


_MISSING = _Missing()
_BAD = object()


class _Checker:
    """Collects the schema violations of one state."""

    def __init__(self, state: Mapping[str, Any]):
        self.state = state
        self.problems: list[str] = []

    def bad(self, field: str, expected: str, value: Any) -> Any:
        got = "no such field" if value is _MISSING else describe_value(value)
        self.problems.append(f"procedure_state: {field}: expected {expected}, got {got}")
        return _BAD

    def get(self, field: str, default: Any = _MISSING) -> Any:
        return self.state.get(field, default)

    @staticmethod
    def _finite(value: Any) -> float | None:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return None
        try:
            x = float(value)
        except OverflowError:
            return None
        return x if math.isfinite(x) and abs(x) <= MAX_MAGNITUDE else None

    def number(self, field: str, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
               hi_open: bool = False, nullable: bool = False) -> Any:
        """A finite number within the bounds (or null when ``nullable``)."""
        value = self.get(field)
        if nullable and value is None:
            return None
        x = self._finite(value)
        in_range = x is not None and (lo is None or (x > lo if lo_open else x >= lo)) and (
            hi is None or (x < hi if hi_open else x <= hi))
        if not in_range:
            if lo is not None and hi is not None:
                span = f"a number in {'(' if lo_open else '['}{_fmt(lo)}, {_fmt(hi)}{')' if hi_open else ']'}"
            elif lo is not None:
                span = f"a number {'>' if lo_open else '>='} {_fmt(lo)}"
            else:
                span = "a finite number"
            return self.bad(field, span + (" or null" if nullable else ""), value)
        return x

    def integer(self, field: str, lo: int, hi: int, *, nullable: bool = False) -> Any:
        """An integer (not a boolean, not 3.0) from ``lo`` to ``hi`` (or null when ``nullable``)."""
        value = self.get(field)
        if nullable and value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            return self.bad(field, f"an integer from {lo} to {hi}" + (" or null" if nullable else ""), value)
        return value

    def choice(self, field: str, options: Sequence[str]) -> Any:
        value = self.get(field)
        if not isinstance(value, str) or value not in options:
            return self.bad(field, "one of " + ", ".join(repr(o) for o in options), value)
        return value

    def numbers(self, field: str, min_len: int, max_len: int, *, lo: float | None = None,
                hi: float | None = None, lo_open: bool = False) -> Any:
        """A list of ``min_len`` to ``max_len`` finite, strictly increasing numbers within the bounds."""
        value = self.get(field)
        what = f"a list of {min_len} to {max_len} finite, increasing numbers"
        if lo is not None and hi is not None:
            what += f" in {'(' if lo_open else '['}{_fmt(lo)}, {_fmt(hi)}]"
        elif lo is not None:
            what += f" {'>' if lo_open else '>='} {_fmt(lo)}"
        if not isinstance(value, list) or not min_len <= len(value) <= max_len:
            return self.bad(field, what, value)
        out = []
        for i, item in enumerate(value):
            x = self._finite(item)
            if x is None or (lo is not None and (x <= lo if lo_open else x < lo)) or (hi is not None and x > hi):
                return self.bad(f"{field}[{i}]", what.replace("a list of", "an item of a list of"), item)
            if out and x <= out[-1]:
                return self.bad(f"{field}[{i}]", f"a number above {field}[{i - 1}] = {_fmt(out[-1])} ({what})",
                                item)
            out.append(x)
        return out

    def history(self, levels: Any, limit: int | None) -> Any:
        """The answers: at most ``limit`` ``[level, correct]`` pairs, each level one of ``levels``."""
        value = self.get("history", [])
        most = min(MAX_HISTORY, limit) if limit is not None else MAX_HISTORY
        what = f"a list of at most {most} answers [level, correct]"
        if not isinstance(value, list) or len(value) > most:
            return self.bad("history", what + (" (the procedure's trial limit)" if most < MAX_HISTORY else ""), value)
        if not value:
            return value
        xs = np.empty(len(value))
        for i, entry in enumerate(value):
            if not isinstance(entry, list) or len(entry) != 2:
                return self.bad(f"history[{i}]", "an answer [level, correct]", entry)
            x, correct = entry
            fx = self._finite(x)
            if fx is None:
                return self.bad(f"history[{i}][0]", "a finite number (a level)", x)
            if not (isinstance(correct, bool) or (isinstance(correct, int) and correct in (0, 1))):
                return self.bad(f"history[{i}][1]", "true, false, 1 or 0", correct)
            xs[i] = fx
        if levels is _BAD:
            return _BAD
        lv = np.asarray(levels, float)
        tol = 1e-9 * max(float(lv[-1] - lv[0]), 1.0)
        j = np.clip(np.searchsorted(lv, xs), 1, len(lv) - 1)
        near = np.where(np.abs(xs - lv[j - 1]) <= np.abs(xs - lv[j]), j - 1, j)
        off = np.flatnonzero(np.abs(lv[near] - xs) > tol)
        if len(off):
            i = int(off[0])
            return self.bad(f"history[{i}][0]", f"one of the {len(lv)} levels", value[i][0])
        return value


def _level_of(levels: Any, value: Any) -> bool:
    """Whether ``value`` is one of ``levels`` (as :func:`level_index` finds it)."""
    try:
        level_index(np.asarray(levels, float), value)
    except AppealInputError:
        return False
    return True


def state_problems(state: Any, kind: str | None = None) -> list[str]:
    """Every violation of the state schema (see the module) by ``state``, one line each; empty when it is valid.

    Parameters
    ----------
    state : object
        The state as read (any JSON value, or anything else).
    kind : str, optional
        The kind the state must be (a class's :meth:`from_dict`).

    Returns
    -------
    list of str
        ``procedure_state: <field>: expected ..., got ...`` lines.
    """
    if not isinstance(state, Mapping):
        return [f"procedure_state: expected an object (a procedure's state), got {describe_value(state)}"]
    chk = _Checker(state)
    got_kind = state.get("kind", _MISSING)
    if not isinstance(got_kind, str) or got_kind not in SETTINGS:
        chk.bad("kind", "one of " + ", ".join(repr(k) for k in SETTINGS), got_kind)
        return chk.problems
    if kind is not None and got_kind != kind:
        chk.bad("kind", f"'{kind}'", got_kind)
        return chk.problems
    allowed = {"kind", "levels", "history", *SETTINGS[got_kind]}
    unknown = [k for k in state if k not in allowed]
    for k in unknown[:3]:
        name = shown(k) if isinstance(k, str) else describe_value(k)
        chk.problems.append(f"procedure_state: {name}: expected one of the fields of a '{got_kind}' state "
                            f"({', '.join(sorted(allowed))}), got an unknown field")
    if len(unknown) > 3:
        chk.problems.append(f"procedure_state: expected only the fields of a '{got_kind}' state, got "
                            f"{len(unknown) - 3} more unknown fields")
    levels = chk.numbers("levels", 2, MAX_LEVELS, lo=-MAX_MAGNITUDE, hi=MAX_MAGNITUDE)
    if got_kind == "psi":
        _psi_problems(chk, levels)
    elif got_kind == "updown":
        _updown_problems(chk, levels)
    else:
        _constant_problems(chk, levels)
    return chk.problems


def _psi_problems(chk: _Checker, levels: Any) -> None:
    thresholds = chk.numbers("thresholds", 1, MAX_AXIS, lo=-MAX_MAGNITUDE, hi=MAX_MAGNITUDE)
    widths = chk.numbers("widths", 1, MAX_AXIS, lo=0.0, hi=MAX_MAGNITUDE, lo_open=True)
    lapses = chk.numbers("lapses", 1, MAX_LAPSES, lo=0.0, hi=0.5)
    guess = chk.number("guess", 0.0, 1.0, hi_open=True)
    family = chk.choice("family", FAMILIES)
    max_trials = chk.integer("max_trials", 1, MAX_HISTORY, nullable=True)
    max_ci_width = chk.number("max_ci_width", 0.0, lo_open=True, nullable=True)
    chk.integer("min_trials", 0, MAX_HISTORY)
    chk.number("ci_level", 0.0, 1.0, lo_open=True, hi_open=True)
    chk.choice("entropy", ("joint", "threshold"))
    chk.number("pc", 0.0, 1.0, lo_open=True, hi_open=True)
    chk.number("alpha", 0.0, 0.5, lo_open=True, hi_open=True)
    if max_trials is None and max_ci_width is None:
        chk.bad("max_trials", "an integer when max_ci_width is null (a stopping rule)", None)
    if family == "weibull" and levels is not _BAD and levels[0] <= 0:
        chk.bad("levels[0]", "a positive number (the weibull family works on log levels)", levels[0])
    if guess is not _BAD and lapses is not _BAD and guess + lapses[-1] >= 1:
        chk.bad("guess", f"a number below 1 - max(lapses) = {_fmt(1 - lapses[-1])}", guess)
    grid = 0
    if _BAD not in (thresholds, widths, lapses) and levels is not _BAD:
        grid = len(thresholds) * len(widths) * len(lapses)
        if grid * len(levels) > MAX_PSI_CELLS:
            chk.problems.append(f"procedure_state: thresholds, widths, lapses: expected a grid of at most "
                                f"{MAX_PSI_CELLS} cells with the levels, got {len(thresholds)} x {len(widths)} x "
                                f"{len(lapses)} x {len(levels)} levels = {grid * len(levels)}")
            grid = 0
    history = chk.history(levels, max_trials if isinstance(max_trials, int) else None)
    if grid and isinstance(history, list) and len(history) * grid > MAX_REPLAY:
        chk.bad("history", f"at most {MAX_REPLAY // grid} answers for a grid of {grid} points (replaying it "
                           f"takes history x grid updates, at most {MAX_REPLAY})", history)


def _updown_problems(chk: _Checker, levels: Any) -> None:
    for field in ("down", "up", "step"):
        chk.integer(field, 1, MAX_LEVELS)
    start = chk.get("start")
    if start is not None:
        if chk._finite(start) is None:
            chk.bad("start", "a level or null", start)
        elif levels is not _BAD and not _level_of(levels, start):
            chk.bad("start", f"one of the {len(levels)} levels or null", start)
    max_trials = chk.integer("max_trials", 1, MAX_HISTORY, nullable=True)
    max_reversals = chk.integer("max_reversals", 1, MAX_HISTORY, nullable=True)
    if max_trials is None and max_reversals is None:
        chk.bad("max_trials", "an integer when max_reversals is null (a stopping rule)", None)
    chk.history(levels, max_trials if isinstance(max_trials, int) else None)


def _constant_problems(chk: _Checker, levels: Any) -> None:
    per = chk.integer("trials_per_level", 1, MAX_HISTORY)
    chk.integer("seed", 0, _MAX_SEED)
    plan = None
    if levels is not _BAD and per is not _BAD:
        plan = len(levels) * per
        if plan > MAX_HISTORY:
            chk.bad("trials_per_level", f"at most {MAX_HISTORY // len(levels)} with {len(levels)} levels (a plan "
                                        f"of at most {MAX_HISTORY} trials)", per)
            plan = None
    chk.history(levels, plan)
