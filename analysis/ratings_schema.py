"""The ``kind: ratings`` study file: what ``appeal analyze ratings STUDY.yaml --out DIR`` analyses.

Example (protocols/analysis/exp2_ratings.yaml)::

    kind: ratings
    title: "Experiment 2: shape and material"
    data: ../../data/sub-*/ses-*/beh/*_task-exp2_beh.tsv   # a glob, or one CSV/TSV/Parquet file
    within: [character, shape, material, expression]
    scales: [realism, appeal]              # default: every response_* column
    model: both                            # anova | mixed | ordinal | both (anova + mixed) | all
    mixed: {random: maximal, ddf: satterthwaite}
    covariates: {audit: ../../stimuli/exp2/audit/audit.csv, measures: [face_L_mean]}   # optional
    figures:
      interactions: [{x: material, trace: shape}]
      realism_vs_appeal: {x_scale: realism, y_scale: appeal, line: shape, point: material}
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import AfterValidator, Field, ValidationInfo, model_validator

from analysis.covariates_schema import CovariatesSpec
from analysis.mixed_schema import MixedOptions
from appeal.studyfile import StudyModel

__all__ = ["RatingsAnalysis", "CovariatesSpec", "MixedOptions", "OrdinalOptions", "PosthocOptions", "ContrastSpec", "InteractionFigure", "ScatterFigure", "Figures"]


def _data_path(value: str, info: ValidationInfo) -> str:
    ctx = info.context or {}
    p = Path(value).expanduser()
    if not p.is_absolute():
        p = Path(ctx.get("base_dir", ".")) / p
    text = str(p)
    # a glob names where runner output will be (checked when the analysis runs); a plain
    # path must exist
    if ctx.get("check_paths", True) and not any(ch in value for ch in "*?[") and not p.is_file():
        raise ValueError(f"file not found: {text}")
    return text


#: A data file or a glob of files; relative paths resolve against the study file's folder.
DataPath = Annotated[str, AfterValidator(_data_path)]


class PosthocOptions(StudyModel):
    """Post-hoc comparisons of significant effects."""

    adjust: Literal["tukey", "holm", "bonferroni", "none"] = "tukey"
    max_order: int = Field(2, ge=1, description="Highest interaction order that gets post-hocs.")
    max_cells: int = Field(60, ge=2, description="Skip effects with more cells than this.")


class ContrastSpec(StudyModel):
    """Polynomial contrasts of an ordered within factor."""

    factor: str
    max_degree: int | None = Field(None, ge=1)


class InteractionFigure(StudyModel):
    """Mean rating vs ``x`` with one line per level of ``trace`` (thesis Fig. 6.4/6.12)."""

    x: str
    trace: str | None = None


class ScatterFigure(StudyModel):
    """Realism-vs-appeal diagram (thesis Fig. 6.16)."""

    x_scale: str = "realism"
    y_scale: str = "appeal"
    line: str
    point: str


class ReferenceSpec(StudyModel):
    """Ratings of a reference (e.g. photographs of the real actors, thesis §6.4) compared with
    the matched stylisation levels: ``rows`` selects the reference ratings (the runner's
    end-of-session items: ``{phase: [end]}``), ``matched`` the within factors whose levels pair
    by position (``[shape, material]``: s0/m0 ... s4/m4)."""

    name: str = Field("photograph", min_length=1)
    rows: dict[str, list[str | int | float]] = Field(min_length=1)
    matched: list[str] = Field(min_length=1)


class Figures(StudyModel):
    """Which figures to draw for every scale."""

    interactions: list[InteractionFigure] = Field(default_factory=list)
    bars: list[str] = Field(default_factory=list, description="Factors to draw as bar charts.")
    realism_vs_appeal: ScatterFigure | None = None


class OrdinalOptions(StudyModel):
    """The cumulative-link mixed model of the ratings as ordered categories (``model: ordinal`` or ``all``)."""

    link: Literal["logit", "probit"] = "logit"


class RatingsAnalysis(StudyModel):
    """A rating study to analyse: data, design, scales and what to report."""

    kind: Literal["ratings"]
    title: str = "Rating study"
    data: DataPath
    subject: str = "participant_id"
    within: list[str] = Field(min_length=1)
    between: list[str] = Field(default_factory=list)
    scales: list[str] | None = Field(None, min_length=1)
    scale_range: tuple[float, float] | None = (1, 7)
    levels: dict[str, list[str | int | float]] = Field(default_factory=dict)
    rows: dict[str, list[str | int | float]] = Field(
        default_factory=lambda: {"phase": ["main"]},
        description="Keep only rows whose column holds one of these values; a column the data lack is "
                    "ignored. The default keeps the runner's main trials (drops anchors, practice and "
                    "end-of-session items).")
    aggregate: Literal["mean"] | None = "mean"
    incomplete: Literal["error", "drop", "mixed"] = "mixed"
    stimulus: str | None = "stimulus"
    alpha: float = Field(0.05, gt=0, lt=1)
    model: Literal["anova", "mixed", "ordinal", "both", "all"] = Field(
        "anova", description="anova: rm-ANOVA on cell means (the thesis); mixed: linear mixed model on the trials with "
                             "participants and stimuli as crossed random factors; ordinal: cumulative-link mixed "
                             "model; both: anova + mixed; all: anova + mixed + ordinal.")
    mixed: MixedOptions = Field(default_factory=MixedOptions)
    covariates: CovariatesSpec | None = Field(
        None, description="Stimulus audit measures as covariates, e.g. {audit: ../../stimuli/exp2/audit/audit.csv, "
                          "measures: [face_L_mean], by: stimulus}: centred fixed effects of the mixed models, an "
                          "ANCOVA-style adjustment of the trials before the rm-ANOVA's cell means (the stimuli of a "
                          "cell must differ: leave character out of within).")
    ordinal: OrdinalOptions = Field(default_factory=OrdinalOptions)
    posthoc: PosthocOptions = Field(default_factory=PosthocOptions)
    contrasts: list[ContrastSpec] = Field(default_factory=list)
    reliability: list[list[str]] = Field(default_factory=list)
    reference: ReferenceSpec | None = None
    figures: Figures = Field(default_factory=Figures)

    @model_validator(mode="after")
    def _consistent(self) -> RatingsAnalysis:
        factors = self.within + self.between
        dup = sorted({f for f in factors if factors.count(f) > 1})
        if dup:
            raise ValueError(f"factors named twice in within/between: {', '.join(dup)}")
        unknown = [k for k in self.levels if k not in factors]
        if unknown:
            raise ValueError(f"levels: {', '.join(unknown)} is not a within or between factor (expected one of: {', '.join(factors)})")
        if self.scale_range is not None and not self.scale_range[0] < self.scale_range[1]:
            raise ValueError(f"scale_range: expected [low, high] with low < high (got {list(self.scale_range)})")
        for c in self.contrasts:
            if c.factor not in self.within:
                raise ValueError(f"contrasts: '{c.factor}' is not a within factor (expected one of: {', '.join(self.within)})")
        for f in self.figures.interactions:
            for name in (f.x, f.trace):
                if name is not None and name not in factors:
                    raise ValueError(f"figures.interactions: '{name}' is not a factor (expected one of: {', '.join(factors)})")
        for b in self.figures.bars:
            if b not in factors:
                raise ValueError(f"figures.bars: '{b}' is not a factor (expected one of: {', '.join(factors)})")
        sc = self.figures.realism_vs_appeal
        if sc is not None:
            for name in (sc.line, sc.point):
                if name not in factors:
                    raise ValueError(f"figures.realism_vs_appeal: '{name}' is not a factor (expected one of: {', '.join(factors)})")
        if self.reference is not None:
            bad = [f for f in self.reference.matched if f not in self.within]
            if bad:
                raise ValueError(f"reference.matched: '{bad[0]}' is not a within factor (expected some of: {', '.join(self.within)})")
        if self.covariates is not None:
            roles = {*factors, self.subject}
            clash = [m for m in self.covariates.measures if m in roles]
            if clash:
                raise ValueError(f"covariates.measures: '{clash[0]}' is also a factor or the subject column "
                                 "(expected audit measures such as face_L_mean)")
        for group in self.reliability:
            if len(group) < 2:
                raise ValueError(f"reliability: each group needs at least 2 scales (got {group})")
        return self
