"""Simulated observers with a known psychometric function, for tests and for planning."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from appeal.psychophysics.functions import check_family, psi

__all__ = ["SimulatedObserver", "constant_stimuli"]


@dataclass
class SimulatedObserver:
    """An observer whose probability of a correct answer at ``level`` is a known psychometric function.

    Parameters
    ----------
    threshold, width : float
        ``m`` and ``w`` of the sigmoid (psignifit's parameterisation).
    lapse : float
        Lapse rate ``lambda``.
    guess : float
        Guess rate ``gamma`` (0.5 for 2AFC).
    family : str
        ``"logistic"``, ``"norm"`` or ``"weibull"``.
    seed : int or numpy.random.Generator
        Seed of the observer's own generator; the same seed gives the same answers.
    """

    threshold: float
    width: float
    lapse: float = 0.0
    guess: float = 0.5
    family: str = "logistic"
    seed: int | np.random.Generator | None = 0
    pc: float = 0.5
    alpha: float = 0.05
    rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        check_family(self.family)
        self.rng = np.random.default_rng(self.seed)

    def p_correct(self, level: ArrayLike) -> NDArray:
        """Probability of a correct response at ``level``."""
        return psi(level, self.threshold, self.width, self.guess, self.lapse, self.family, self.pc, self.alpha)

    def respond(self, level: float) -> bool:
        """One trial at ``level``: ``True`` when correct."""
        return bool(self.rng.random() < float(self.p_correct(level)))

    def respond_many(self, level: ArrayLike, n: int = 1) -> NDArray:
        """Numbers correct out of ``n`` trials at each of ``level``."""
        return self.rng.binomial(n, self.p_correct(level))


def constant_stimuli(observer: SimulatedObserver, levels: ArrayLike, trials_per_level: int) -> NDArray:
    """Run the method of constant stimuli: rows ``(level, n_correct, n_trials)`` ready for a fit."""
    lv = np.asarray(levels, float)
    k = observer.respond_many(lv, trials_per_level)
    return np.column_stack([lv, k, np.full(len(lv), trials_per_level)]).astype(float)
