"""A generative grammar of dynamic facial expressions for reverse correlation (Jack et al. 2012).

Each trial of the paradigm shows a face animated with a random combination of facial action units
(AUs), each with a random time course; the participant names the emotion and its intensity, and
the AUs that predict an answer are that participant's model of the expression (Jack, Garrod, Yu,
Caldara & Schyns 2012, PNAS 109:7241; Jack & Schyns 2015). This module is the grammar's maths,
shared by the stimulus engine (which poses the rig with it), the runtime and the analysis.

AUs
    :data:`ACTION_UNITS` are the FACS AUs the project's rigs carry (the ARKit/ICT blendshapes
    grouped per AU in ``stimulus_engine/data/facs_recipes.yaml``; AU23 shares AU24's lip-press
    shapes and is left out so that no two AUs move the same shapes). Left and right move together;
    ``lateralised=True`` draws each side as its own AU (``AU12_L``, ``AU12_R``) where the AU has two
    sides.
A trial
    :func:`draw_trial`: the number of AUs is ``1 + Binomial(5, 0.4)`` by default — at least 1, at
    most 6, median 3, as Jack et al. report for their grammar — drawn without replacement; each AU
    gets the grammar's six temporal parameters (:class:`AuMotion`), each uniform over its range
    (:data:`PARAMETER_RANGES`, configurable).
A time course
    :func:`au_curve`: 0 before the onset, a rise to the peak amplitude at the peak latency, a fall
    back to 0 at the offset, each a cubic Hermite segment between the level ends: zero slope at the
    peak, the start slope ``3 x acceleration`` on the rise and the end slope ``-3 x deceleration``
    on the fall (in amplitude per segment length). 0 starts (or ends) at rest, a smoothstep; 1
    starts at three times the segment's mean slope, ``1 - (1 - s)^3``; slopes up to 3 keep a segment
    monotone (Fritsch & Carlson). Times are fractions of the clip.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from appeal.errors import AppealInputError

__all__ = ["ACTION_UNITS", "BILATERAL", "PARAMETER_RANGES", "AuMotion", "Trial", "action_units", "draw_count",
           "draw_trial", "draw_trials", "au_curve", "trial_curves", "presence_matrix"]

#: The AUs the rigs carry, in FACS order (AU11 is ARKit's upper-lip raiser, AU24 the lip press).
ACTION_UNITS: tuple[str, ...] = ("AU1", "AU2", "AU4", "AU5", "AU6", "AU7", "AU9", "AU11", "AU12", "AU14", "AU15",
                                 "AU16", "AU20", "AU24", "AU26", "AU45")
#: AUs with a left and a right blendshape (AU26, the jaw, has one).
BILATERAL: frozenset[str] = frozenset(set(ACTION_UNITS) - {"AU26"})
#: The six temporal parameters and their default ranges (fractions of the clip; amplitude of the AU).
PARAMETER_RANGES: dict[str, tuple[float, float]] = {
    "onset": (0.0, 0.25), "acceleration": (0.0, 1.0), "peak_latency": (0.25, 0.6), "peak_amplitude": (0.2, 1.0),
    "deceleration": (0.0, 1.0), "offset": (0.6, 1.0)}


def action_units(lateralised: bool = False) -> tuple[str, ...]:
    """The grammar's AUs: :data:`ACTION_UNITS`, or with ``lateralised`` each bilateral AU as ``_L`` and ``_R``.

    Examples
    --------
    >>> len(action_units()), action_units(lateralised=True)[:3]
    (16, ('AU1_L', 'AU1_R', 'AU2_L'))
    """
    if not lateralised:
        return ACTION_UNITS
    return tuple(n for au in ACTION_UNITS for n in ((f"{au}_L", f"{au}_R") if au in BILATERAL else (au,)))


@dataclass(frozen=True)
class AuMotion:
    """One AU's movement on a trial: the grammar's six parameters (times as fractions of the clip)."""

    au: str
    onset: float
    acceleration: float
    peak_latency: float
    peak_amplitude: float
    deceleration: float
    offset: float

    def as_dict(self) -> dict[str, float | str]:
        return asdict(self)


@dataclass(frozen=True)
class Trial:
    """A trial's AUs and their motions, with the seed that drew it."""

    index: int
    seed: int
    motions: tuple[AuMotion, ...]

    @property
    def aus(self) -> tuple[str, ...]:
        return tuple(m.au for m in self.motions)


def _check_ranges(ranges: Mapping[str, tuple[float, float]] | None) -> dict[str, tuple[float, float]]:
    out = dict(PARAMETER_RANGES)
    for key, value in (ranges or {}).items():
        if key not in PARAMETER_RANGES:
            raise AppealInputError(f"revcorr: temporal parameter '{key}': unknown (expected one of: "
                                   f"{', '.join(PARAMETER_RANGES)})")
        try:
            lo, hi = (float(v) for v in value)
        except (TypeError, ValueError):
            raise AppealInputError(f"revcorr: {key}: expected [low, high], got {value!r}") from None
        if not 0.0 <= lo <= hi <= 1.0:
            raise AppealInputError(f"revcorr: {key}: expected 0 <= low <= high <= 1, got [{lo}, {hi}]")
        out[key] = (lo, hi)
    if out["onset"][1] > out["peak_latency"][0] or out["peak_latency"][1] > out["offset"][0]:
        raise AppealInputError("revcorr: the ranges must keep onset <= peak_latency <= offset (onset's high <= "
                               "peak_latency's low, peak_latency's high <= offset's low)")
    return out


def draw_count(rng: np.random.Generator, n_max: int = 6, p: float = 0.4) -> int:
    """How many AUs a trial moves: ``1 + Binomial(n_max - 1, p)`` (default 1-6, median 3)."""
    return 1 + int(rng.binomial(n_max - 1, p))


def draw_trial(seed: int, index: int = 0, *, aus: Sequence[str] = ACTION_UNITS, n_max: int = 6, p: float = 0.4,
               ranges: Mapping[str, tuple[float, float]] | None = None) -> Trial:
    """One trial drawn from its own seed (the same seed and index give the same trial anywhere).

    Parameters
    ----------
    seed : int
        The participant's (or the pool's) seed.
    index : int
        The trial's number; trial ``index`` is drawn from ``SeedSequence([seed, index])``.
    aus : sequence of str
        The AUs to draw from (:func:`action_units`).
    n_max, p : int, float
        The count distribution ``1 + Binomial(n_max - 1, p)`` (:func:`draw_count`).
    ranges : mapping, optional
        Replacement ranges of the temporal parameters (:data:`PARAMETER_RANGES`).

    Returns
    -------
    Trial
    """
    r = _check_ranges(ranges)
    if not 1 <= n_max <= len(aus):
        raise AppealInputError(f"revcorr: n_max {n_max}: expected 1 to the {len(aus)} AUs")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), int(index)]))
    k = draw_count(rng, n_max, p)
    chosen = sorted(rng.choice(len(aus), size=k, replace=False))
    motions = []
    for i in chosen:
        v = {name: float(rng.uniform(*r[name])) for name in PARAMETER_RANGES}
        motions.append(AuMotion(aus[i], **v))
    return Trial(int(index), int(seed), tuple(motions))


def draw_trials(seed: int, n: int, **kwargs) -> list[Trial]:
    """Trials ``0 .. n - 1`` of :func:`draw_trial`."""
    return [draw_trial(seed, i, **kwargs) for i in range(n)]


def _hermite(s: NDArray, m0: float, m1: float) -> NDArray:
    """The cubic Hermite segment from 0 to 1 on ``s`` in [0, 1] with end slopes ``m0``, ``m1``."""
    return (3 * s ** 2 - 2 * s ** 3) + m0 * (s ** 3 - 2 * s ** 2 + s) + m1 * (s ** 3 - s ** 2)


def au_curve(motion: AuMotion, t: NDArray) -> NDArray:
    """The AU's amplitude at times ``t`` (fractions of the clip, 0..1).

    Examples
    --------
    >>> m = AuMotion("AU12", 0.1, 1.0, 0.5, 0.8, 1.0, 0.9)
    >>> [round(float(v), 3) for v in au_curve(m, np.array([0.0, 0.1, 0.3, 0.5, 0.7, 0.9, 1.0]))]
    [0.0, 0.0, 0.7, 0.8, 0.7, 0.0, 0.0]
    """
    t = np.asarray(t, float)
    a, t0, tp, t1 = motion.peak_amplitude, motion.onset, motion.peak_latency, motion.offset
    out = np.zeros_like(t)
    rise = (t > t0) & (t <= tp)
    if tp > t0:
        out[rise] = a * _hermite((t[rise] - t0) / (tp - t0), 3 * motion.acceleration, 0.0)
    fall = (t > tp) & (t < t1)
    if t1 > tp:
        out[fall] = a * (1 - _hermite((t[fall] - tp) / (t1 - tp), 0.0, 3 * motion.deceleration))
    out[t == tp] = a
    return np.clip(out, 0.0, a)


def trial_curves(trial: Trial, n_frames: int) -> dict[str, NDArray]:
    """Every AU's amplitude over a clip of ``n_frames`` frames (frame ``k`` at ``t = k / (n_frames - 1)``)."""
    t = np.linspace(0.0, 1.0, n_frames)
    return {m.au: au_curve(m, t) for m in trial.motions}


def presence_matrix(trials: Sequence[Trial], aus: Sequence[str] = ACTION_UNITS) -> NDArray:
    """``(n_trials, n_aus)`` 0/1: which AUs each trial moved."""
    col = {au: j for j, au in enumerate(aus)}
    out = np.zeros((len(trials), len(aus)), np.int8)
    for i, tr in enumerate(trials):
        for au in tr.aus:
            out[i, col[au]] = 1
    return out
