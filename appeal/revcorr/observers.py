"""Simulated participants of a reverse-correlation study with a known model of each expression.

:class:`TemplateObserver` holds a template per emotion (the AUs that carry it). On a trial it
weighs, for every emotion, the peak amplitudes of the template's AUs that moved (their mean over the
template), less ``antagonism`` times the amplitude of the moving AUs outside the template (their
sum over the template's size), plus Gaussian noise of SD ``noise``; it names the emotion with the
most evidence, or "don't know" when that evidence is below ``criterion``; with probability
``lapse`` it answers at random among the emotions and "don't know". The intensity (1-5) follows
how strongly the named emotion's AUs moved: ``1 + round(4 x clip((a - 0.2) / 0.8 + e, 0, 1))`` with
``a`` the mean peak amplitude of its template's AUs that moved (0 when none did) and ``e`` Gaussian
noise of SD ``noise``. The analysis must recover the templates from its answers
(:mod:`analysis.revcorr`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from appeal.errors import AppealInputError
from appeal.revcorr.grammar import ACTION_UNITS, Trial

__all__ = ["EMOTIONS", "DONT_KNOW", "PROTOTYPES", "TemplateObserver", "amplitude_matrix"]

#: The six basic emotions the participant chooses among (plus :data:`DONT_KNOW`).
EMOTIONS: tuple[str, ...] = ("happy", "surprise", "fear", "disgust", "anger", "sad")
DONT_KNOW = "dont_know"
#: EMFACS prototypes (Ekman, Friesen & Hager 2002) in the grammar's AUs: the default templates.
PROTOTYPES: dict[str, tuple[str, ...]] = {
    "happy": ("AU6", "AU12"),
    "surprise": ("AU1", "AU2", "AU5", "AU26"),
    "fear": ("AU1", "AU2", "AU4", "AU5", "AU20", "AU26"),
    "disgust": ("AU9", "AU11", "AU15", "AU16"),
    "anger": ("AU4", "AU5", "AU7", "AU24"),
    "sad": ("AU1", "AU4", "AU15"),
}


def amplitude_matrix(trials: Sequence[Trial], aus: Sequence[str] = ACTION_UNITS) -> NDArray:
    """``(n_trials, n_aus)``: each AU's peak amplitude on each trial (0 where it did not move)."""
    col = {au: j for j, au in enumerate(aus)}
    out = np.zeros((len(trials), len(aus)))
    for i, tr in enumerate(trials):
        for m in tr.motions:
            out[i, col[m.au]] = m.peak_amplitude
    return out


@dataclass
class TemplateObserver:
    """A simulated participant whose model of each emotion is a known set of AUs.

    Parameters
    ----------
    templates : mapping
        ``{emotion: AUs}``; default :data:`PROTOTYPES`.
    noise, criterion, antagonism, lapse : float
        See the module docstring.
    seed : int
        The participant's own generator.
    aus : sequence of str
        The grammar's AUs (the columns of :func:`amplitude_matrix`).
    """

    templates: Mapping[str, Sequence[str]] = field(default_factory=lambda: dict(PROTOTYPES))
    noise: float = 0.1
    criterion: float = 0.25
    antagonism: float = 0.3
    lapse: float = 0.02
    seed: int = 0
    aus: Sequence[str] = ACTION_UNITS
    rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        unknown = sorted({au for t in self.templates.values() for au in t} - set(self.aus))
        if unknown:
            raise AppealInputError(f"revcorr observer: template AU '{unknown[0]}' is not one of the grammar's AUs")
        if not self.templates:
            raise AppealInputError("revcorr observer: no templates")
        self.rng = np.random.default_rng(self.seed)

    @property
    def emotions(self) -> tuple[str, ...]:
        return tuple(self.templates)

    def template_matrix(self) -> NDArray:
        """``(n_aus, n_emotions)`` 0/1: which AUs each template holds."""
        out = np.zeros((len(self.aus), len(self.templates)))
        for j, aus in enumerate(self.templates.values()):
            for au in aus:
                out[list(self.aus).index(au), j] = 1
        return out

    def evidence(self, amplitudes: NDArray) -> NDArray:
        """Noise-free evidence ``(n_trials, n_emotions)`` for each emotion."""
        return self._evidence(np.asarray(amplitudes, float), self.template_matrix())

    def _evidence(self, a: NDArray, t: NDArray) -> NDArray:
        return (a @ t - self.antagonism * a @ (1 - t)) / t.sum(axis=0)

    def respond(self, amplitudes: NDArray) -> tuple[NDArray, NDArray]:
        """Answers (emotion names or :data:`DONT_KNOW`) and intensities (1-5; 0 for "don't know")
        to trials with these AU amplitudes (:func:`amplitude_matrix`)."""
        a = np.atleast_2d(np.asarray(amplitudes, float))
        t = self.template_matrix()
        ev = self._evidence(a, t) + self.rng.normal(0.0, self.noise, (len(a), len(self.templates)))
        best = ev.argmax(axis=1)
        top = ev[np.arange(len(a)), best]
        names = np.array([*self.emotions, DONT_KNOW], dtype=object)
        choice = np.where(top >= self.criterion, best, len(self.emotions))
        lapses = self.rng.random(len(a)) < self.lapse
        choice = np.where(lapses, self.rng.integers(0, len(self.emotions) + 1, len(a)), choice)
        named = t[:, np.minimum(choice, len(self.emotions) - 1)].T  # (n_trials, n_aus): the named template
        moved = (a > 0) * named
        mean_amp = np.where(moved.sum(axis=1) > 0, (a * moved).sum(axis=1) / np.maximum(moved.sum(axis=1), 1), 0.2)
        strength = (mean_amp - 0.2) / 0.8 + self.rng.normal(0.0, self.noise, len(a))
        intensity = 1 + np.rint(4 * np.clip(strength, 0.0, 1.0)).astype(int)
        intensity = np.where(choice == len(self.emotions), 0, intensity)
        return names[choice], intensity
