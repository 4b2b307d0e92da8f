"""The ``kind: psychometric`` analysis file: what ``appeal analyze psychometric STUDY.yaml`` fits.

Example (protocols/analysis/realism_threshold.yaml)::

    kind: psychometric
    title: "Realism discrimination threshold per expression"
    data: ../../data/sub-*/ses-*/beh/*_task-realism2afc_beh.tsv   # glob(s), relative to this file
    x: difference              # the psychometric function's stimulus variable
    correct: correct           # 1 = correct, 0 = not, n/a = no answer (dropped)
    conditions: [expression]   # one fit per participant x these columns
    fit: {family: logistic, method: bayes, nafc: 2, threshold_pc: 0.75, min_trials: 20}
    continuum: {reference: 0.0, direction: 1}   # x on the continuum: reference + direction * x
    compare: [expression]      # rm-ANOVA of the per-participant thresholds across these
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from analysis.psychometric.fit import MIN_TRIALS, PARAMS
from analysis.ratings_schema import DataPath, PosthocOptions
from appeal.studyfile import StudyModel

__all__ = ["FitOptions", "ContinuumOptions", "PsychometricAnalysis"]


class FitOptions(StudyModel):
    """How each psychometric function is fitted (:mod:`analysis.psychometric.fit`)."""

    family: Literal["logistic", "norm", "weibull"] = Field(
        "logistic", description="Sigmoid family: logistic, norm (cumulative Gaussian) or weibull (x > 0; "
                                "threshold and width in natural-log units).")
    method: Literal["bayes", "ml"] = Field(
        "bayes", description="bayes: psignifit-4-style grid posterior (beta-binomial, MAP, credible intervals); "
                             "ml: binomial maximum likelihood (fast, no intervals).")
    nafc: int | None = Field(2, ge=2, description="Alternatives of the forced choice (guess rate 1/nafc); "
                                                   "null for yes/no (the guess rate is fitted).")
    threshold_pc: float = Field(0.75, gt=0, lt=1, description="Proportion correct at which x_at_pc is read "
                                                               "off the fitted function (e.g. 0.75 in 2AFC).")
    sigmoid_pc: float = Field(0.5, gt=0, lt=1, description="psignifit's threshold definition: the value of the "
                                                            "sigmoid part at the threshold parameter.")
    width_alpha: float = Field(0.05, gt=0, lt=0.5, description="psignifit's width definition: the width spans "
                                                                "the sigmoid from width_alpha to 1 - width_alpha.")
    min_trials: int = Field(MIN_TRIALS, ge=MIN_TRIALS, description="Fewest answered trials a fit needs (over at "
                                                                   "least 3 levels of x).")
    too_few: Literal["error", "skip"] = Field(
        "error", description="A participant x condition below min_trials: stop with an error, or skip it "
                             "(listed in the report).")
    ci_level: float = Field(0.95, gt=0, lt=1, description="Credible level of the intervals (bayes).")
    grid: dict[str, int] = Field(default_factory=dict, description="Grid points per parameter of the Bayesian "
                                 "fit (threshold, width, lambda, gamma, eta); fewer is faster and coarser.")

    @field_validator("grid")
    @classmethod
    def _known_params(cls, value: dict[str, int]) -> dict[str, int]:
        unknown = [k for k in value if k not in PARAMS]
        if unknown:
            raise ValueError(f"unknown parameter '{unknown[0]}' (expected some of: {', '.join(PARAMS)})")
        small = [k for k, v in value.items() if v < 3]
        if small:
            raise ValueError(f"{small[0]}: at least 3 grid points expected (got {value[small[0]]})")
        return value

    @model_validator(mode="after")
    def _pc_above_guess(self) -> FitOptions:
        if self.nafc is not None and not self.threshold_pc > 1 / self.nafc:
            raise ValueError(f"threshold_pc must exceed the guess rate 1/nafc = {1 / self.nafc:g} "
                             f"(got {self.threshold_pc:g})")
        return self


class ContinuumOptions(StudyModel):
    """Where x lies on the stimulus continuum: ``point = reference + direction * x``."""

    reference: float = Field(0.0, description="The reference (e.g. realistic) face's level on the continuum.")
    direction: Literal[-1, 1] = Field(1, description="1 when the comparison faces lie above the reference, "
                                                      "-1 when below.")


class PsychometricAnalysis(StudyModel):
    """Psychometric functions fitted to psychophysics data: per participant and condition, pooled, compared."""

    kind: Literal["psychometric"]
    title: str = "Psychometric fits"
    data: DataPath | list[DataPath] = Field(
        description="The runner's BIDS *_beh.tsv files: a glob or a list of globs, relative to this file.")
    subject: str = Field("participant_id", description="Participant id column.")
    x: str = Field("difference", description="Column of the stimulus variable (|level - reference| by default).")
    correct: str = Field("correct", description="Column of the answers: 1 correct, 0 not, n/a no answer.")
    conditions: list[str] = Field(default_factory=list, description="Fit one function per participant x these "
                                                                    "columns (empty: one per participant).")
    rows: dict[str, list[str | int | float]] = Field(
        default_factory=lambda: {"phase": ["main"], "pair_type": ["different"]},
        description="Keep only rows whose column holds one of these values (a column the data lack is ignored); "
                    "the default drops practice trials and the 'same' pairs of a same-different task (their "
                    "answers are correct rejections, not points of the function).")
    levels: dict[str, list[str | int | float]] = Field(default_factory=dict,
                                                       description="Level order of condition columns.")
    fit: FitOptions = Field(default_factory=FitOptions)
    continuum: ContinuumOptions | None = Field(None, description="Report thresholds as points on the continuum.")
    compare: list[str] = Field(default_factory=list, description="Within factors (among conditions) across which "
                                                                 "the per-participant thresholds are compared "
                                                                 "(rm-ANOVA and post-hocs).")
    compare_measure: Literal["x_at_pc", "threshold", "width"] = Field(
        "x_at_pc", description="The per-participant estimate that is compared.")
    alpha: float = Field(0.05, gt=0, lt=1, description="Significance level of the comparison.")
    posthoc: PosthocOptions = Field(default_factory=PosthocOptions)

    @model_validator(mode="after")
    def _consistent(self) -> PsychometricAnalysis:
        roles = [self.subject, self.x, self.correct, *self.conditions]
        dup = sorted({r for r in roles if roles.count(r) > 1})
        if dup:
            raise ValueError(f"each column may have one role only (subject, x, correct, conditions; used twice: "
                             f"{', '.join(dup)})")
        bad = [c for c in self.compare if c not in self.conditions]
        if bad:
            raise ValueError(f"compare: '{bad[0]}' is not one of the conditions "
                             f"(expected some of: {', '.join(self.conditions) or 'none given'})")
        unknown = [k for k in self.levels if k not in self.conditions]
        if unknown:
            raise ValueError(f"levels: '{unknown[0]}' is not one of the conditions "
                             f"(expected some of: {', '.join(self.conditions) or 'none given'})")
        return self

    @property
    def patterns(self) -> list[str]:
        """The data globs, resolved against the study file's folder."""
        return [self.data] if isinstance(self.data, str) else list(self.data)
