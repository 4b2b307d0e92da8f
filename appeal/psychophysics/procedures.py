"""Adaptive procedures over a discrete set of stimulus levels (e.g. 41 points of a continuum 0..1).

:class:`PsiProcedure` is the psi method (Kontsevich & Tyler 1999, *Vision Research* 39, 2729–2737;
QUEST+ in its one-stimulus-dimension form): a posterior over a (threshold, width, lapse) grid,
each next level the one that minimises the expected entropy of the posterior after the response.
:class:`UpDownStaircase` is a transformed 1-up-N-down staircase (Levitt 1971) for comparison, and
:class:`ConstantStimuli` the method of constant stimuli (every level equally often, in a seeded
random order). All stop by trial count (and the psi procedure also by the width of the threshold's credible
interval), and all serialise to a plain dict (:meth:`to_dict` / :meth:`from_dict`) that replays
the responses, so that a resumed session continues the same procedure.

A state read back (:func:`procedure_from_json`, :func:`procedure_from_dict`, ``Cls.from_dict``)
comes from a data file anyone can edit, so it is treated as hostile: read with :func:`json.loads`
only (nothing in it is executed) and checked against the schema of
:mod:`appeal.psychophysics.states` before anything is built from it.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from appeal.psychophysics.continuum import level_index
from appeal.psychophysics.intervals import credible_interval
from appeal.psychophysics.functions import check_family, psi
from appeal.psychophysics.observers import SimulatedObserver
from appeal.psychophysics.states import MAX_STATE_CHARS, SETTINGS, describe_value, state_problems
from appeal.errors import AppealInputError

__all__ = ["level_index", "PsiProcedure", "UpDownStaircase", "ConstantStimuli", "procedure_from_dict",
           "procedure_from_json", "run_procedure"]



def _levels(levels: ArrayLike) -> NDArray:
    lv = np.asarray(levels, float).ravel()
    if len(lv) < 2 or not np.all(np.isfinite(lv)) or np.any(np.diff(lv) <= 0):
        raise AppealInputError("an adaptive procedure needs at least 2 finite, increasing levels")
    return lv


def _rebuild(cls: type, state: Any, where: str | None = None) -> Any:
    """A procedure of class ``cls`` from its :meth:`to_dict` state, checked first
    (:func:`state_problems`): its ``levels`` and settings, then every response of its history replayed."""
    head = f"{where}: procedure_state" if where else "procedure_state"
    problems = state_problems(state, cls.kind)
    if problems:
        raise AppealInputError([f"{where}: {p}" if where else p for p in problems])
    try:
        proc = cls(state["levels"], **{k: state[k] for k in cls.settings})
        for x, correct in state.get("history", []):
            proc.update(x, bool(correct))
    except AppealInputError as exc:
        raise AppealInputError([f"{head}: {line}" for line in exc.lines]) from None
    return proc


class PsiProcedure:
    """The psi method over a discrete set of levels.

    Parameters
    ----------
    levels : array_like
        The increasing stimulus levels the procedure may show (the psychometric function is
        assumed to rise with the level).
    thresholds, widths, lapses : array_like, optional
        The parameter grid. Defaults: 41 thresholds over the levels' range, 12 widths spaced
        logarithmically from twice the level spacing to the range, lapses 0, 0.01, 0.02, 0.04.
    guess : float
        Guess rate (0.5 for 2AFC).
    family : str
        ``"logistic"``, ``"norm"`` or ``"weibull"``.
    max_trials : int, optional
        Stop after this many trials.
    max_ci_width : float, optional
        Stop once the threshold's credible interval is at most this wide (after ``min_trials``).
    min_trials : int
        Trials before the width rule may stop the procedure.
    ci_level : float
        Credible level of the intervals.
    entropy : {"joint", "threshold"}
        Minimise the expected entropy of the joint posterior (Kontsevich & Tyler) or of the
        threshold's marginal only (Prins' psi-marginal).
    pc, alpha : float
        Threshold and width definitions, as in :mod:`appeal.psychophysics.functions`.

    Raises
    ------
    AppealInputError
        When there is no stopping rule, or the grid or levels are bad.
    """

    kind = "psi"
    settings = SETTINGS["psi"]

    def __init__(self, levels: ArrayLike, thresholds: ArrayLike | None = None, widths: ArrayLike | None = None,
                 lapses: ArrayLike | None = None, guess: float = 0.5, family: str = "logistic",
                 max_trials: int | None = None, max_ci_width: float | None = None, min_trials: int = 0,
                 ci_level: float = 0.95, entropy: str = "joint", pc: float = 0.5, alpha: float = 0.05) -> None:
        if max_trials is None and max_ci_width is None:
            raise AppealInputError("the psi procedure needs a stopping rule: max_trials or max_ci_width")
        if max_trials is not None and max_trials < 1:
            raise AppealInputError(f"max_trials must be at least 1 (got {max_trials})")
        if max_ci_width is not None and not max_ci_width > 0:
            raise AppealInputError(f"max_ci_width must be positive (got {max_ci_width})")
        if entropy not in ("joint", "threshold"):
            raise AppealInputError(f"entropy must be 'joint' or 'threshold' (got '{entropy}')")
        check_family(family)
        self.levels = _levels(levels)
        lo, hi = self.levels[0], self.levels[-1]
        step = float(np.min(np.diff(self.levels)))
        self.thresholds = np.linspace(lo, hi, 41) if thresholds is None else np.asarray(thresholds, float)
        self.widths = (np.geomspace(2 * step, hi - lo, 12) if widths is None else np.asarray(widths, float))
        self.lapses = np.array([0.0, 0.01, 0.02, 0.04]) if lapses is None else np.asarray(lapses, float)
        self.guess, self.family, self.pc, self.alpha = float(guess), family, pc, alpha
        self.max_trials, self.max_ci_width, self.min_trials = max_trials, max_ci_width, int(min_trials)
        self.ci_level, self.entropy = ci_level, entropy
        m, w, lam = np.meshgrid(self.thresholds, self.widths, self.lapses, indexing="ij")
        self._shape = m.shape
        # P × X table of P(correct | parameters, level)
        self._pc = psi(self.levels[None, :], m.reshape(-1, 1), w.reshape(-1, 1), self.guess, lam.reshape(-1, 1),
                       family, pc, alpha)
        self._pc = np.clip(self._pc, 1e-12, 1 - 1e-12)
        self._log_pc, self._log_pi = np.log(self._pc), np.log1p(-self._pc)
        self._logpost = np.zeros(self._pc.shape[0])
        self.history: list[tuple[float, bool]] = []

    # -- posterior ---------------------------------------------------------------------------
    def posterior(self) -> NDArray:
        """The normalised posterior over the grid, shape (thresholds, widths, lapses)."""
        p = np.exp(self._logpost - self._logpost.max())
        return (p / p.sum()).reshape(self._shape)

    def _entropy(self, post: NDArray) -> NDArray:
        """Entropy of posteriors stored along axis 0 (P × X)."""
        if self.entropy == "threshold":
            post = post.reshape(self._shape[0], -1, post.shape[-1]).sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return -np.nansum(np.where(post > 0, post * np.log(post), 0.0), axis=0)

    def next_level(self) -> float:
        """The level whose response is expected to leave the least posterior entropy."""
        post = self.posterior().ravel()
        p1 = post @ self._pc  # P(correct) at each level
        post1 = post[:, None] * self._pc / p1
        post0 = post[:, None] * (1 - self._pc) / (1 - p1)
        expected = p1 * self._entropy(post1) + (1 - p1) * self._entropy(post0)
        return float(self.levels[int(np.argmin(expected))])

    def update(self, level: float, correct: bool) -> None:
        """Add one response at ``level`` (one of :attr:`levels`)."""
        i = level_index(self.levels, level)
        self._logpost = self._logpost + (self._log_pc[:, i] if correct else self._log_pi[:, i])
        self.history.append((float(self.levels[i]), bool(correct)))

    # -- estimates ---------------------------------------------------------------------------
    def estimate(self) -> dict[str, float]:
        """Posterior means and equal-tailed credible intervals of threshold, width and lapse.

        Returns
        -------
        dict
            ``threshold``, ``threshold_lo``, ``threshold_hi``, ``width``, ..., ``lapse_hi``,
            ``n_trials``.
        """
        post = self.posterior()
        out: dict[str, float] = {}
        for ax, (name, grid) in enumerate((("threshold", self.thresholds), ("width", self.widths),
                                           ("lapse", self.lapses))):
            mg = post.sum(axis=tuple(i for i in range(3) if i != ax))
            out[name] = float(mg @ grid)
            out[f"{name}_lo"], out[f"{name}_hi"] = credible_interval(grid, mg, self.ci_level)
        out["n_trials"] = len(self.history)
        return out

    @property
    def n_trials(self) -> int:
        """Trials so far."""
        return len(self.history)

    @property
    def finished(self) -> bool:
        """Whether a stopping rule is met."""
        if self.max_trials is not None and self.n_trials >= self.max_trials:
            return True
        if self.max_ci_width is not None and self.n_trials >= self.min_trials:
            e = self.estimate()
            return e["threshold_hi"] - e["threshold_lo"] <= self.max_ci_width
        return False

    # -- state ---------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The procedure's state as plain data (JSON-ready): its settings and every response."""
        return {"kind": self.kind, "levels": self.levels.tolist(), "thresholds": self.thresholds.tolist(),
                "widths": self.widths.tolist(), "lapses": self.lapses.tolist(), "guess": self.guess,
                "family": self.family, "max_trials": self.max_trials, "max_ci_width": self.max_ci_width,
                "min_trials": self.min_trials, "ci_level": self.ci_level, "entropy": self.entropy,
                "pc": self.pc, "alpha": self.alpha, "history": [[x, c] for x, c in self.history]}

    @classmethod
    def from_dict(cls, state: Mapping[str, Any], where: str | None = None) -> PsiProcedure:
        """Rebuild a procedure from :meth:`to_dict`'s output (checked first: see the module), replaying its
        responses; ``where`` (the file and row) starts each error line."""
        return _rebuild(cls, state, where)


class UpDownStaircase:
    """A transformed up–down staircase (1-up-N-down by default 1-up-2-down, converging on ~70.7 %).

    Parameters
    ----------
    levels : array_like
        Increasing levels; a higher level is easier.
    down : int
        Consecutive correct answers before a step down (harder).
    up : int
        Consecutive wrong answers before a step up (easier).
    step : int
        Step size in level indices.
    start : float, optional
        First level (default the easiest, the last level).
    max_trials, max_reversals : int, optional
        Stopping rules; at least one is needed.
    """

    kind = "updown"
    settings = SETTINGS["updown"]

    def __init__(self, levels: ArrayLike, down: int = 2, up: int = 1, step: int = 1, start: float | None = None,
                 max_trials: int | None = None, max_reversals: int | None = None) -> None:
        if max_trials is None and max_reversals is None:
            raise AppealInputError("the staircase needs a stopping rule: max_trials or max_reversals")
        if down < 1 or up < 1 or step < 1:
            raise AppealInputError(f"staircase up, down and step must be >= 1 (got {up}, {down}, {step})")
        self.levels = _levels(levels)
        self.down, self.up, self.step = int(down), int(up), int(step)
        self.start = float(self.levels[-1] if start is None else self.levels[level_index(self.levels, start)])
        self.max_trials, self.max_reversals = max_trials, max_reversals
        self._i = level_index(self.levels, self.start)
        self._run, self._direction = 0, 0
        self.reversals: list[float] = []
        self.history: list[tuple[float, bool]] = []

    def next_level(self) -> float:
        """The level of the next trial."""
        return float(self.levels[self._i])

    def update(self, level: float, correct: bool) -> None:
        """Add the response to the trial at ``level`` (the staircase moves from its own current level)."""
        x = self.levels[level_index(self.levels, level)]
        self.history.append((float(x), bool(correct)))
        if correct:
            self._run = self._run + 1 if self._run > 0 else 1
            move = -1 if self._run >= self.down else 0
        else:
            self._run = self._run - 1 if self._run < 0 else -1
            move = 1 if -self._run >= self.up else 0
        if move:
            self._run = 0
            if self._direction and move != self._direction:
                self.reversals.append(float(self.levels[self._i]))
            self._direction = move
            self._i = int(np.clip(self._i + move * self.step, 0, len(self.levels) - 1))

    @property
    def n_trials(self) -> int:
        """Trials so far."""
        return len(self.history)

    @property
    def finished(self) -> bool:
        """Whether a stopping rule is met."""
        return ((self.max_trials is not None and self.n_trials >= self.max_trials)
                or (self.max_reversals is not None and len(self.reversals) >= self.max_reversals))

    def estimate(self, last: int = 6) -> dict[str, float]:
        """Threshold as the mean level of the last ``last`` reversals (NaN before any)."""
        r = self.reversals[-last:]
        return {"threshold": float(np.mean(r)) if r else float("nan"), "n_reversals": len(self.reversals),
                "n_trials": self.n_trials}

    def to_dict(self) -> dict[str, Any]:
        """The staircase's settings and responses as plain data."""
        return {"kind": self.kind, "levels": self.levels.tolist(), "down": self.down, "up": self.up,
                "step": self.step, "start": self.start, "max_trials": self.max_trials,
                "max_reversals": self.max_reversals, "history": [[x, c] for x, c in self.history]}

    @classmethod
    def from_dict(cls, state: Mapping[str, Any], where: str | None = None) -> UpDownStaircase:
        """Rebuild a staircase from :meth:`to_dict`'s output (checked first), replaying its responses."""
        return _rebuild(cls, state, where)


class ConstantStimuli:
    """The method of constant stimuli: every level ``trials_per_level`` times, in a seeded random order.

    Parameters
    ----------
    levels : array_like
        Increasing levels.
    trials_per_level : int
        Presentations of each level (the stopping rule: it ends after ``len(levels) * trials_per_level``).
    seed : int
        Seed of the order.
    """

    kind = "constant"
    settings = SETTINGS["constant"]

    def __init__(self, levels: ArrayLike, trials_per_level: int, seed: int = 0) -> None:
        if trials_per_level < 1:
            raise AppealInputError(f"the method of constant stimuli needs trials_per_level >= 1 (got {trials_per_level})")
        self.levels = _levels(levels)
        self.trials_per_level, self.seed = int(trials_per_level), int(seed)
        order = np.repeat(np.arange(len(self.levels)), self.trials_per_level)
        self._order = np.random.default_rng(self.seed).permutation(order)
        self.history: list[tuple[float, bool]] = []

    def next_level(self) -> float:
        """The level of the next trial (the last one again once the plan is done)."""
        return float(self.levels[self._order[min(self.n_trials, len(self._order) - 1)]])

    def update(self, level: float, correct: bool) -> None:
        """Add the response to the trial at ``level``."""
        x = self.levels[level_index(self.levels, level)]
        self.history.append((float(x), bool(correct)))

    @property
    def n_trials(self) -> int:
        """Trials so far."""
        return len(self.history)

    @property
    def finished(self) -> bool:
        """Whether every planned trial has been answered."""
        return self.n_trials >= len(self._order)

    def estimate(self) -> dict[str, float]:
        """Proportion correct so far and the trial count (the fit comes after the session)."""
        pc = float(np.mean([c for _, c in self.history])) if self.history else float("nan")
        return {"proportion_correct": pc, "n_trials": self.n_trials}

    def to_dict(self) -> dict[str, Any]:
        """The plan's settings and responses as plain data."""
        return {"kind": self.kind, "levels": self.levels.tolist(), "trials_per_level": self.trials_per_level,
                "seed": self.seed, "history": [[x, c] for x, c in self.history]}

    @classmethod
    def from_dict(cls, state: Mapping[str, Any], where: str | None = None) -> ConstantStimuli:
        """Rebuild the plan from :meth:`to_dict`'s output (checked first), replaying its responses."""
        return _rebuild(cls, state, where)


Procedure = PsiProcedure | UpDownStaircase | ConstantStimuli
_KINDS: dict[str, type] = {c.kind: c for c in (PsiProcedure, UpDownStaircase, ConstantStimuli)}


def procedure_from_dict(state: Mapping[str, Any], where: str | None = None) -> Procedure:
    """Any procedure from its :meth:`to_dict` state (the ``kind`` field says which), checked against
    the module's schema before anything is built; ``where`` (the file and row) starts each error line.

    Raises
    ------
    AppealInputError
        One line per violation of the schema, or why the procedure cannot be built.
    """
    kind = state.get("kind") if isinstance(state, Mapping) else None
    if isinstance(kind, str) and kind in _KINDS:
        return _KINDS[kind].from_dict(state, where)
    problems = state_problems(state)
    raise AppealInputError([f"{where}: {p}" if where else p for p in problems])


class _Constant(ValueError):
    """A NaN or Infinity literal in state text."""


def _no_constant(name: str) -> Any:
    raise _Constant(name)


def procedure_from_json(text: str | bytes, where: str | None = None) -> Procedure:
    """A procedure from the JSON text of its state (a data row's ``procedure_state``).

    The text is read by :func:`json.loads` only — plain data; nothing in it is executed — after its
    size is checked (at most :data:`MAX_STATE_CHARS` characters); it must be one JSON object without
    ``NaN``/``Infinity`` literals, nested as a state is, and is then checked and built by
    :func:`procedure_from_dict`.

    Parameters
    ----------
    text : str or bytes
        The JSON text (bytes: UTF-8).
    where : str, optional
        The file and row it came from, put first in each error line.

    Returns
    -------
    PsiProcedure, UpDownStaircase or ConstantStimuli
        The procedure with its history replayed.

    Raises
    ------
    AppealInputError
        One line per problem (``procedure_state: ...: expected ..., got ...``).
    """
    head = f"{where}: procedure_state" if where else "procedure_state"
    if isinstance(text, (bytes, bytearray)):
        if len(text) > MAX_STATE_CHARS:
            raise AppealInputError(f"{head}: expected at most {MAX_STATE_CHARS} characters of JSON, "
                                   f"got {len(text)} bytes")
        try:
            text = bytes(text).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise AppealInputError(f"{head}: expected UTF-8 text, got a byte {text[exc.start]:#04x} at {exc.start} "
                                   "that is not") from None
    if not isinstance(text, str):
        raise AppealInputError(f"{head}: expected JSON text, got {describe_value(text)}")
    if len(text) > MAX_STATE_CHARS:
        raise AppealInputError(f"{head}: expected at most {MAX_STATE_CHARS} characters of JSON, got {len(text)}")
    try:
        state = json.loads(text, parse_constant=_no_constant)
    except _Constant as exc:
        raise AppealInputError(f"{head}: expected finite numbers, got {exc}") from None
    except RecursionError:
        raise AppealInputError(f"{head}: expected a JSON object nested as a state is (3 levels), got JSON nested "
                               "too deep to read") from None
    except ValueError as exc:  # json.JSONDecodeError, an integer of more than 4300 digits
        msg = (f"{exc.msg} at line {exc.lineno} column {exc.colno}" if isinstance(exc, json.JSONDecodeError)
               else str(exc).split(";")[0])
        raise AppealInputError(f"{head}: expected JSON, got text that is not ({msg})") from None
    if not isinstance(state, dict):
        raise AppealInputError(f"{head}: expected a JSON object, got {describe_value(state)}")
    return procedure_from_dict(state, where)


def run_procedure(procedure: Procedure, observer: SimulatedObserver,
                  max_trials: int = 100000) -> Sequence[tuple[float, bool]]:
    """Run ``procedure`` with a simulated ``observer`` until it stops; return its (level, correct) history."""
    while not procedure.finished and procedure.n_trials < max_trials:
        x = procedure.next_level()
        procedure.update(x, observer.respond(x))
    return procedure.history
