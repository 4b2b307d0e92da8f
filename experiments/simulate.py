"""Simulated participants: ratings = f(factor levels) + noise, classification from a confusion
matrix, log-normal response times — seeded, so whole studies run headless and reproducibly.

A model is ``default`` (built in, thesis-like: realism rises with stylisation level, appeal is
an inverted U) or a YAML file::

    kind: participant_model
    participant_sd: 0.5            # random intercept per participant
    rt: {median_s: 1.4, sigma: 0.35, min_s: 0.25}
    ratings:
      realism:
        intercept: 4.0
        noise_sd: 0.8
        slopes: {shape: [1.2, 0.0]}           # linear, quadratic in level rank scaled to [-1, 1]
        effects: {character: {c1: 0.2, c2: -0.2}}   # per-level offsets
    classification:
      expression:
        p_correct: 0.85                          # where no confusion row is given
        confusion: {neutral: {neutral: 0.6, surprise: 0.3, sad: 0.1}}
    revcorr:                       # reverse-correlation trials (revcorr: protocols)
      templates: {happy: [AU6, AU12], ...}   # default: the EMFACS prototypes
      by: {shape: {"1": {happy: [AU6, AU12, AU26]}}}   # templates replaced at a level
    psychometric:                  # pair trials (psychophysics): P(correct) along the difference
      threshold: 0.3               # psignifit's threshold (75 % correct in 2AFC without lapses)
      width: 0.4                   # 5 % -> 95 % of the sigmoid
      lapse: 0.02
      by: {expression: {happiness: {threshold: 0.25}}}   # per-level changes
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field

from appeal.errors import AppealInputError
from appeal.levels import level_key
from appeal.psychophysics.functions import psi
from appeal.studyfile import StudyModel, load_study_file
from experiments.protocol_schema import ChoiceSpec, ClassificationSpec, LikertSpec

__all__ = ["ParticipantModel", "RevcorrModel", "SimulatedParticipant", "load_participant_model", "DEFAULT_MODEL"]


class ScaleModel(StudyModel):
    """How one rating scale depends on the factors."""

    intercept: float | None = Field(None, description="default: the scale's midpoint")
    noise_sd: float = Field(0.8, ge=0)
    slopes: dict[str, tuple[float, float]] = Field(default_factory=dict)
    effects: dict[str, dict[str, float]] = Field(default_factory=dict)


class ClassModel(StudyModel):
    """How one classification is answered."""

    p_correct: float = Field(0.85, ge=0, le=1)
    confusion: dict[str, dict[str, float]] = Field(default_factory=dict)


class RtModel(StudyModel):
    """Log-normal response times."""

    median_s: float = Field(1.4, gt=0)
    sigma: float = Field(0.35, ge=0)
    min_s: float = Field(0.2, ge=0)


class ObserverChange(StudyModel):
    """A change of the psychometric function for one level of a factor."""

    threshold: float | None = Field(None, gt=0)
    width: float | None = Field(None, gt=0)


class PsychometricModel(StudyModel):
    """How pair trials are answered: P(correct) at a difference is a psychometric function.

    2AFC: ``guess + (1 - guess - lapse) * S(difference)`` with the task's guess rate 0.5;
    same–different: P("different") with ``false_alarm`` as its floor ('same' pairs: the floor).
    ``threshold`` and ``width`` are psignifit's (:mod:`appeal.psychophysics.functions`).
    """

    threshold: float = Field(0.3, gt=0)
    width: float = Field(0.4, gt=0)
    lapse: float = Field(0.02, ge=0, lt=0.5)
    family: Literal["logistic", "norm", "weibull"] = "logistic"
    false_alarm: float = Field(0.1, ge=0, lt=1)
    participant_sd: float = Field(0.0, ge=0, description="SD of a participant's threshold around 'threshold'")
    by: dict[str, dict[str, ObserverChange]] = Field(default_factory=dict)


class RevcorrModel(StudyModel):
    """How reverse-correlation trials are answered (``revcorr:`` protocols): a
    :class:`~appeal.revcorr.observers.TemplateObserver` per participant, its template of AUs per
    emotion (default: the EMFACS prototypes), replaced at the levels ``by`` names
    (``{factor: {level: {emotion: [AUs]}}}``)."""

    templates: dict[str, list[str]] | None = Field(None, description="emotion -> AUs (default: the EMFACS prototypes)")
    noise: float = Field(0.1, ge=0)
    criterion: float = Field(0.25, description="evidence below which the answer is dont_know")
    antagonism: float = Field(0.3, ge=0)
    lapse: float = Field(0.02, ge=0, lt=1)
    by: dict[str, dict[str, dict[str, list[str]]]] = Field(default_factory=dict)


class ParticipantModel(StudyModel):
    """A simulated participant (``--simulate FILE.yaml``)."""

    kind: Literal["participant_model"] = "participant_model"
    participant_sd: float = Field(0.5, ge=0)
    rt: RtModel = Field(default_factory=RtModel)
    ratings: dict[str, ScaleModel] = Field(default_factory=dict)
    classification: dict[str, ClassModel] = Field(default_factory=dict)
    psychometric: PsychometricModel = Field(default_factory=PsychometricModel)
    revcorr: RevcorrModel = Field(default_factory=RevcorrModel)


_APPEAL_LIKE = {"shape": (0.2, -0.9), "material": (-0.4, -0.5), "stylisation": (-0.2, -1.0)}
DEFAULT_MODEL = ParticipantModel(
    ratings={
        "realism": ScaleModel(noise_sd=0.7, slopes={"shape": (1.3, 0.0), "material": (0.8, 0.0),
                                                    "stylisation": (2.0, 0.0), "lighting": (0.15, 0.0)}),
        "appeal": ScaleModel(slopes=_APPEAL_LIKE),
        "reassurance": ScaleModel(slopes=_APPEAL_LIKE),
        "attractiveness": ScaleModel(slopes=_APPEAL_LIKE),
        "familiarity": ScaleModel(noise_sd=1.0, slopes={"material": (0.3, 0.0)}),
        "intensity": ScaleModel(intercept=4.5, slopes={"shape": (-0.9, 0.0), "stylisation": (-0.8, 0.0)}),
    },
    classification={"expression": ClassModel(confusion={
        "neutral": {"neutral": 0.6, "surprise": 0.2, "sad": 0.2},
    })},
    # realism discrimination (2AFC, realistic vs a stylised level): happy faces' stylisation
    # noticed sooner, angry ones' later (a plausible pattern for the demo and tests, not a finding)
    psychometric=PsychometricModel(threshold=0.3, width=0.4, lapse=0.02, participant_sd=0.04, by={
        "expression": {"happiness": ObserverChange(threshold=0.22), "anger": ObserverChange(threshold=0.38)},
        "emotion": {"happiness": ObserverChange(threshold=0.22), "anger": ObserverChange(threshold=0.38)}}),
    # reverse correlation: at the most stylised shape the dropped jaw (AU26) joins happiness and leaves
    # surprise (a made-up change for the demo and tests to find, not a finding)
    revcorr=RevcorrModel(by={"shape": {"1": {"happy": ["AU6", "AU12", "AU26"], "surprise": ["AU1", "AU2", "AU5"]}}}),
)


def load_participant_model(spec: str | Path) -> ParticipantModel:
    """``default`` or a YAML file -> :class:`ParticipantModel` (one-line errors for bad files)."""
    if str(spec) == "default":
        return DEFAULT_MODEL
    path = Path(spec)
    if not path.is_file():
        raise AppealInputError(f"{path}: --simulate: expected 'default' or a participant-model YAML file (file not found)")
    return load_study_file(path, ParticipantModel)


class SimulatedParticipant:
    """Answers the runner's questions from a :class:`ParticipantModel`.

    Parameters
    ----------
    model : ParticipantModel
        The model.
    levels : mapping of str to list of str
        Every factor's levels in natural order (ranks for the slopes).
    seed : int
        The participant's randomness (ratings noise, choices, RTs).
    """

    def __init__(self, model: ParticipantModel, levels: Mapping[str, Sequence[str]], seed: int):
        self.model = model
        self.levels = {f: [str(v) for v in vs] for f, vs in levels.items()}
        self.rng = np.random.default_rng(seed)
        self.offset = float(self.rng.normal(0.0, model.participant_sd))
        self.threshold_offset = float(np.random.default_rng([seed, 31]).normal(0.0, model.psychometric.participant_sd))
        self._seed = int(seed)
        self._observers: dict[tuple, Any] = {}
        self._revcorr: tuple[tuple, str, int] | None = None

    def revcorr_answer(self, factors: Mapping[str, str]) -> tuple[str, int] | None:
        """The answer and intensity (1-5) to a reverse-correlation trial (``factors`` with its
        ``revcorr_seed``, ``revcorr_trial``, ``revcorr_lateralised``), or None for any other
        stimulus; the same trial asked again (its intensity after its classification) gets the same."""
        if "revcorr_trial" not in factors:
            return None
        key = tuple(sorted(factors.items()))
        if self._revcorr is None or self._revcorr[0] != key:
            from appeal.revcorr.grammar import action_units, draw_trial
            from appeal.revcorr.observers import PROTOTYPES, TemplateObserver, amplitude_matrix

            rm = self.model.revcorr
            templates = {e: tuple(a) for e, a in (rm.templates or PROTOTYPES).items()}
            for factor, changes in rm.by.items():
                changed = {level_key(k): v for k, v in changes.items()}.get(level_key(factors.get(factor, "")), {})
                templates.update({e: tuple(a) for e, a in changed.items()})
            aus = action_units(lateralised=factors.get("revcorr_lateralised", "0") == "1")
            okey = (tuple(sorted(templates.items())), aus)
            if okey not in self._observers:
                self._observers[okey] = TemplateObserver(templates=templates, noise=rm.noise, criterion=rm.criterion,
                                                         antagonism=rm.antagonism, lapse=rm.lapse, aus=aus,
                                                         seed=self._seed * 7919 + len(self._observers))
            trial = draw_trial(int(factors["revcorr_seed"]), int(factors["revcorr_trial"]), aus=aus)
            answer, intensity = self._observers[okey].respond(amplitude_matrix([trial], aus))
            self._revcorr = (key, str(answer[0]), max(1, int(intensity[0])))
        return self._revcorr[1], self._revcorr[2]

    def _x(self, factor: str, level: str) -> float:
        levels = self.levels.get(factor, [])
        if level not in levels or len(levels) < 2:
            return 0.0
        return -1.0 + 2.0 * levels.index(level) / (len(levels) - 1)

    def expected_rating(self, scale: LikertSpec, factors: Mapping[str, str]) -> float:
        """The noise-free rating of ``scale`` for a stimulus with ``factors``."""
        sm = self.model.ratings.get(scale.name, ScaleModel())
        mid = (1 + scale.points) / 2
        value = (sm.intercept if sm.intercept is not None else mid) + self.offset
        for factor, level in factors.items():
            if factor in sm.effects and level in sm.effects[factor]:
                value += sm.effects[factor][level]
            elif factor in sm.slopes:
                lin, quad = sm.slopes[factor]
                x = self._x(factor, level)
                value += lin * x * (scale.points - 1) / 4 + quad * (x * x - 0.5) * (scale.points - 1) / 4
        return value

    def rate(self, scale: LikertSpec, factors: Mapping[str, str]) -> int:
        """A rating 1..points (a reverse-correlation trial's: its intensity, :meth:`revcorr_answer`)."""
        answer = self.revcorr_answer(factors)
        if answer is not None:
            return min(answer[1], scale.points)
        sm = self.model.ratings.get(scale.name, ScaleModel())
        value = self.expected_rating(scale, factors) + self.rng.normal(0.0, sm.noise_sd)
        return int(np.clip(np.rint(value), 1, scale.points))

    def classify(self, name: str, choices: Sequence[ChoiceSpec], true_level: str | None,
                 factors: Mapping[str, str] | None = None) -> str:
        """The chosen value (as a level string) for a stimulus whose correct answer is ``true_level``
        (a reverse-correlation trial, ``factors`` naming its pool trial: :meth:`revcorr_answer`)."""
        answer = self.revcorr_answer(factors or {})
        if answer is not None:
            return answer[0]
        values = [level_key(c.value) for c in choices]
        cm = self.model.classification.get(name, ClassModel())
        row = cm.confusion.get(true_level or "", None)
        if row:
            p = np.array([row.get(v, 0.0) for v in values], dtype=float)
        elif true_level in values:
            rest = (1 - cm.p_correct) / (len(values) - 1)
            p = np.array([cm.p_correct if v == true_level else rest for v in values])
        else:
            p = np.ones(len(values))
        if p.sum() <= 0:
            p = np.ones(len(values))
        return values[int(self.rng.choice(len(values), p=p / p.sum()))]

    def observer(self, factors: Mapping[str, str]) -> tuple[float, float]:
        """The (threshold, width) of this participant's psychometric function for ``factors``."""
        pm = self.model.psychometric
        threshold, width = pm.threshold, pm.width
        for factor, changes in pm.by.items():
            change = changes.get(factors.get(factor, ""))
            if change is not None:
                threshold = change.threshold if change.threshold is not None else threshold
                width = change.width if change.width is not None else width
        return max(threshold + self.threshold_offset, 1e-6), width

    def discriminate(self, spec: ClassificationSpec, psy: Mapping[str, Any], factors: Mapping[str, str]) -> str:
        """The answer to a pair trial (``psy``: its difference, pair type and the reference's position).

        2AFC: the reference's position with the psychometric function's probability, else the
        other one; same–different: 'different' with P("different" | difference).
        """
        pm = self.model.psychometric
        threshold, width = self.observer(factors)
        d = float(psy["difference"])
        values = [level_key(c.value) for c in spec.choices]
        if "same" in values:
            p = pm.false_alarm if psy["pair_type"] == "same" else float(
                psi(d, threshold, width, pm.false_alarm, pm.lapse, pm.family))
            return "different" if self.rng.random() < p else "same"
        p = float(psi(d, threshold, width, 0.5, pm.lapse, pm.family))
        other = next(v for v in values if v != psy["reference_side"])
        return psy["reference_side"] if self.rng.random() < p else other

    def rt(self) -> float:
        """A log-normal response time in seconds."""
        m = self.model.rt
        return max(m.min_s, float(m.median_s * np.exp(self.rng.normal(0.0, m.sigma))))

    def demographics(self, items: Sequence[Any]) -> dict[str, Any]:
        """Plausible answers to the demographic questions (age 19-30, a random choice)."""
        out: dict[str, Any] = {}
        for item in items:
            if item.type == "int":
                out[item.name] = int(self.rng.integers(19, 31))
            elif item.type == "choice":
                out[item.name] = item.options[int(self.rng.integers(len(item.options)))]
            else:
                out[item.name] = "simulated"
        return out
