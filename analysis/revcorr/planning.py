"""How many trials a reverse-correlation participant needs: recovery of known models.

:func:`simulate_participant` runs a :class:`~appeal.revcorr.observers.TemplateObserver` through a
participant's seeded trials; :func:`expected_models` is the MI map of the same observer over a very
long run (the map its templates imply); :func:`recovery_table` fits :func:`~analysis.revcorr.models.au_models`
to simulated participants at several trial counts and says how much of the templates comes back.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from analysis.revcorr.models import au_models, model_recovery
from appeal.progress import progress
from appeal.revcorr.grammar import Trial, draw_trials, presence_matrix
from appeal.revcorr.observers import TemplateObserver, amplitude_matrix

__all__ = ["SimulatedSession", "simulate_participant", "expected_models", "map_correlation", "recovery_table"]


@dataclass(frozen=True)
class SimulatedSession:
    """A simulated participant's trials, the AUs' presence and amplitudes, answers and intensities."""

    trials: list[Trial]
    presence: NDArray
    amplitudes: NDArray
    answers: NDArray
    intensity: NDArray


def simulate_participant(observer: TemplateObserver, n_trials: int, seed: int) -> SimulatedSession:
    """``n_trials`` trials drawn from ``seed`` (:func:`~appeal.revcorr.grammar.draw_trials`) answered by ``observer``."""
    trials = draw_trials(seed, n_trials, aus=observer.aus)
    amps = amplitude_matrix(trials, observer.aus)
    answers, intensity = observer.respond(amps)
    return SimulatedSession(trials, presence_matrix(trials, observer.aus), amps, answers, intensity)


def expected_models(observer: TemplateObserver, n_trials: int = 40000, seed: int = 10_000) -> pd.DataFrame:
    """The MI map (:func:`~analysis.revcorr.models.au_models` without permutations) of ``n_trials`` of
    the same observer (a copy with its own generator): what a participant's map tends to."""
    s = simulate_participant(replace(observer, seed=seed), n_trials, seed)
    return au_models(s.presence, s.answers, observer.aus, observer.emotions, n_permutations=0)


def map_correlation(models: pd.DataFrame, expected: pd.DataFrame) -> float:
    """The correlation of two MI maps (every emotion x AU)."""
    key = ["emotion", "au"]
    both = models[[*key, "mi"]].merge(expected[[*key, "mi"]], on=key, suffixes=("", "_expected"))
    return float(np.corrcoef(both["mi"], both["mi_expected"])[0, 1])


def recovery_table(observer: TemplateObserver, trial_counts: Sequence[int] = (300, 600, 1200, 2400),
                   n_participants: int = 5, n_permutations: int = 1000, seed: int = 0) -> pd.DataFrame:
    """Recovery of ``observer``'s templates by simulated participants: a row per trial count with
    the share of template AUs found (``hit_rate``), false AUs per emotion (``false_aus``), the MI map's
    correlation with :func:`expected_models` (``map_corr``) and the worst participant's hit rate."""
    expected = expected_models(observer)
    rows = []
    jobs = [(n, p) for n in trial_counts for p in range(n_participants)]
    per = []
    for n, p in progress(jobs, total=len(jobs), desc="revcorr recovery", unit="participant"):
        obs = replace(observer, seed=seed + 7919 * p + n)
        s = simulate_participant(obs, n, seed + 104_729 * p + n)
        models = au_models(s.presence, s.answers, observer.aus, observer.emotions, n_permutations=n_permutations,
                           seed=seed + p)
        rec = model_recovery(models, dict(observer.templates))
        per.append({"n_trials": n, "participant": p, "hit_rate": rec["hits"].sum() / rec["template_size"].sum(),
                    "false_aus": rec["false_aus"].mean(), "map_corr": map_correlation(models, expected)})
    table = pd.DataFrame(per)
    for n, sub in table.groupby("n_trials"):
        rows.append({"n_trials": int(n), "participants": len(sub), "hit_rate": sub["hit_rate"].mean(),
                     "worst_hit_rate": sub["hit_rate"].min(), "false_aus": sub["false_aus"].mean(),
                     "map_corr": sub["map_corr"].mean(), "worst_map_corr": sub["map_corr"].min()})
    return pd.DataFrame(rows)
