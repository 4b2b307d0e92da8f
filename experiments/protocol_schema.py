"""The runner protocol (``kind: protocol``): a validated description of one study session.

A protocol names its stimuli (a grid ``manifest.csv`` or a folder of images plus a factor
table), the screen and timing (seconds, converted to frames from the refresh rate), the
trial ordering constraints, instruction pages, anchor/practice trials, end-of-session items,
breaks, the responses (Likert scales, classification with an intensity follow-up, or none)
and the EEG trigger codes. ``appeal validate`` checks it with :class:`Protocol`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from appeal.levels import level_key
from appeal.studyfile import InputFile, OutputPath, StudyModel
from appeal.triggers import trigger_table

__all__ = [
    "Protocol", "StimulusSource", "Selection", "ScreenSpec", "TimingSpec", "OrderSpec", "BreakSpec",
    "LikertSpec", "ClassificationSpec", "ChoiceSpec", "ExtraTrialsSpec", "TriggerSpec",
    "DemographicItem", "PsychophysicsSpec", "ProcedureSpec", "PAIR_CHOICES", "RevcorrSpec", "REVCORR_COLUMNS",
]

Name = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$", max_length=40)]
Level = str | int | float | bool
Seconds = Annotated[float, Field(ge=0, le=3600)]


class Selection(StudyModel):
    """Which stimuli a part of the session uses: factor levels to keep, factors that must match."""

    where: dict[Name, Level | list[Level]] = Field(default_factory=dict,
                                                   description="factor -> level or list of levels to keep")
    exclude: dict[Name, Level | list[Level]] = Field(default_factory=dict,
                                                     description="factor -> level or list of levels to drop")
    match: list[Name] = Field(default_factory=list,
                              description="factors whose levels must be equal (e.g. [shape, material] = baseline)")

    @field_validator("match")
    @classmethod
    def _match_two(cls, v: list[str]) -> list[str]:
        if len(v) == 1:
            raise ValueError("expected at least two factors whose levels must match (got one)")
        return v


class StimulusSource(StudyModel):
    """Where the images come from.

    Exactly one of ``manifest`` (a grid ``manifest.csv``: ``file`` + one column per factor) or
    ``folder`` + ``table`` (any images plus a CSV with a ``file`` column and factor columns).
    Paths are resolved against the protocol's folder; they are checked when the session
    starts (the stimuli may not be rendered yet when the protocol is validated). A table with
    a ``frames`` column holds clips (animated stimuli): each such row names a folder of PNG
    frames (``frame_00000.png`` ...) and its ``fps`` (see :mod:`experiments.clips`).
    """

    manifest: OutputPath | None = None
    folder: OutputPath | None = None
    table: OutputPath | None = None
    grid: OutputPath | None = Field(None, description="grid file that renders these stimuli (shown in errors)")
    factors: list[Name] = Field(min_length=1, description="the factor columns, in analysis order")
    levels: dict[Name, list[Level]] = Field(
        default_factory=dict, description="factor -> its levels in order (most stylised first); used by "
        "select.match (levels at the same position match) and by simulated participants")
    select: Selection = Field(default_factory=Selection)

    @model_validator(mode="after")
    def _one_source(self) -> StimulusSource:
        if (self.manifest is None) == (self.folder is None):
            raise ValueError("expected exactly one of 'manifest' (a grid manifest.csv) or 'folder' (+ 'table')")
        if self.folder is not None and self.table is None:
            raise ValueError("'folder' needs 'table': a CSV with a 'file' column and one column per factor")
        if self.manifest is not None and self.table is not None:
            raise ValueError("'table' goes with 'folder', not with 'manifest'")
        if len(set(self.factors)) != len(self.factors):
            raise ValueError(f"factors must be unique (got {self.factors})")
        unknown = [f for f in self.levels if f not in self.factors]
        if unknown:
            raise ValueError(f"levels: unknown factor(s) {unknown} (factors: {self.factors})")
        return self


class ScreenSpec(StudyModel):
    """The display: background, stimulus size, refresh rate, window size."""

    background: float = Field(0.5, ge=0, le=1, description="grey level 0 (black) .. 1 (white); 0.5 = 50% grey")
    stimulus_height: float = Field(0.8, gt=0, le=1, description="image height as a fraction of the screen height")
    response_stimulus_height: float = Field(0.45, gt=0, le=1)
    refresh_hz: float | None = Field(None, gt=20, le=500,
                                     description="nominal refresh; default: measured (falls back to 60)")
    window_size: tuple[Annotated[int, Field(ge=64)], Annotated[int, Field(ge=64)]] = (1280, 1024)
    text_color: float = Field(1.0, ge=0, le=1)


class TimingSpec(StudyModel):
    """Durations in seconds (converted to whole frames at the refresh rate)."""

    stimulus_s: Seconds = Field(gt=0)
    fixation_s: Seconds | tuple[Seconds, Seconds] | None = Field(
        None, description="fixed, or [min, max] drawn uniformly per trial (in whole frames)")
    fixation_position: Literal["before", "after"] = Field(
        "before", description="fixation before each stimulus, or after it (ERP: face, then jittered cross)")
    iti_s: Seconds = 0.0
    response_deadline_s: Seconds | None = Field(None, gt=0)
    stimulus_visible_during_response: bool = Field(
        False, description="keep a thumbnail of the face on the response screens; the thesis (and the default) "
                           "shows the face for stimulus_s, then asks without it, so every face is seen equally long")
    clip_end: Literal["hold", "end"] = Field(
        "hold", description="clips (animated stimuli): after the last frame, hold it until stimulus_s has passed "
                            "since frame 0 (a longer clip is shown whole), or end the stimulus screen at once")
    clip_trigger: Literal["first_frame", "onset_frame"] = Field(
        "first_frame", description="clips: send the trigger on the flip that shows frame 0, or the manifest's "
                                   "onset_frame (the expression's onset); both flip times are logged")
    on_dropped_frames: Literal["log", "flag", "repeat"] = Field(
        "log", description="a trial whose stimulus had a late flip or a clip frame not shown for its flips: "
                           "log the counts only, also flag it (dropped_flag = 1), or flag it and repeat it at "
                           "the end of its block")
    max_repeats: int = Field(1, ge=1, le=10, description="on_dropped_frames: repeat: repeats of one planned trial")

    @field_validator("fixation_s")
    @classmethod
    def _range(cls, v: Any) -> Any:
        if isinstance(v, tuple) and v[0] > v[1]:
            raise ValueError(f"expected [min, max] with min <= max (got {list(v)})")
        return v

    @model_validator(mode="after")
    def _repeats(self) -> TimingSpec:
        if "max_repeats" in self.model_fields_set and self.on_dropped_frames != "repeat":
            raise ValueError(f"max_repeats is only used with on_dropped_frames: repeat "
                             f"(got on_dropped_frames: {self.on_dropped_frames})")
        return self


class OrderSpec(StudyModel):
    """Trial order: repetitions, randomisation and constraints."""

    repetitions: int = Field(1, ge=1, le=1000)
    order: Literal["random", "blocked", "fixed"] = "random"
    shuffle: Literal["whole", "per_repetition"] = Field(
        "whole", description="whole: one random order of all trials; per_repetition: a new order per pass")
    block_by: list[Name] = Field(default_factory=list, description="factors defining blocks (order: blocked)")
    block_order: Literal["random", "fixed"] = "random"
    no_immediate_repeat: bool = False
    max_run: dict[Name, Annotated[int, Field(ge=1)]] = Field(
        default_factory=dict, description="factor -> most consecutive trials with the same level")

    @model_validator(mode="after")
    def _blocked(self) -> OrderSpec:
        if self.order == "blocked" and not self.block_by:
            raise ValueError("order 'blocked' needs block_by: the factor(s) whose levels form the blocks")
        if self.order != "blocked" and self.block_by:
            raise ValueError(f"block_by is only used with order: blocked (got order: {self.order})")
        return self


class BreakSpec(StudyModel):
    """A pause every N main trials."""

    every: int = Field(ge=1)
    text: str = "Pause. Press SPACE to continue."
    min_s: Seconds = 0.0


class LikertSpec(StudyModel):
    """A rating scale 1..points with labelled ends."""

    type: Literal["likert"] = "likert"
    name: Name
    points: int = Field(7, ge=2, le=11)
    low: str = Field(min_length=1)
    high: str = Field(min_length=1)
    description: str = ""
    keys: bool = Field(True, description="number keys 1..points answer too (points <= 9)")


class ChoiceSpec(StudyModel):
    """One option of a classification."""

    label: str = Field(min_length=1)
    value: Level
    key: str | None = Field(None, min_length=1)


class ClassificationSpec(StudyModel):
    """Choose one of several options (keys or mouse), optionally followed by an intensity scale."""

    type: Literal["classification"] = "classification"
    name: Name
    prompt: str = ""
    choices: list[ChoiceSpec] = Field(min_length=2)
    factor: Name | None = Field(None, description="the stimulus factor the correct answer is read from")
    intensity: LikertSpec | None = None
    skip_intensity_for: list[Level] = Field(default_factory=list,
                                            description="choices after which no intensity is asked")
    skip_value: int | None = Field(None, description="intensity recorded when skipped (thesis: the lowest value)")

    @model_validator(mode="after")
    def _check(self) -> ClassificationSpec:
        values = [level_key(c.value) for c in self.choices]
        if len(set(values)) != len(values):
            raise ValueError(f"choice values must be unique (got {values})")
        keys = [c.key for c in self.choices if c.key is not None]
        if len(set(keys)) != len(keys):
            raise ValueError(f"choice keys must be unique (got {keys})")
        unknown = [s for s in self.skip_intensity_for if level_key(s) not in values]
        if unknown:
            raise ValueError(f"skip_intensity_for names no choice value (got {unknown}; choices: {values})")
        if self.skip_intensity_for and self.intensity is None:
            raise ValueError("skip_intensity_for needs an intensity scale")
        if self.skip_value is not None and self.intensity is not None and not 1 <= self.skip_value <= self.intensity.points:
            raise ValueError(f"skip_value must lie on the intensity scale 1..{self.intensity.points} (got {self.skip_value})")
        return self


Response = Annotated[LikertSpec | ClassificationSpec, Field(discriminator="type")]


class ExtraTrialsSpec(StudyModel):
    """Anchor, practice or end-of-session trials (selected from the stimuli or listed files)."""

    select: Selection | None = None
    files: list[OutputPath] = Field(default_factory=list, description="extra images (relative to the protocol)")
    factors: dict[Name, Level] = Field(default_factory=dict, description="factor levels recorded for 'files'")
    n: int | None = Field(None, ge=1, description="take this many (randomly) of the selection")
    respond: bool = True
    title: str = ""
    stimulus_s: Seconds | None = Field(None, gt=0)
    order: Literal["random", "fixed"] = "fixed"
    if_missing: Literal["error", "skip"] = Field(
        "error", description="what to do when the selection matches no stimulus")

    @model_validator(mode="after")
    def _some(self) -> ExtraTrialsSpec:
        if self.select is None and not self.files:
            raise ValueError("expected 'select' (stimuli from the set) or 'files' (extra images)")
        return self


class TriggerSpec(StudyModel):
    """EEG triggers sent on the stimulus onset flip and reset after ``pulse_ms``."""

    backend: Literal["parallel", "serial", "lsl", "file"] = "file"
    address: str | None = Field(None, description="parallel: port address (0x0378); serial: device (/dev/ttyUSB0)")
    baudrate: int = Field(115200, gt=0)
    stream_name: str = "AppealLabMarkers"
    pulse_ms: float = Field(10.0, gt=0, le=1000)
    codes: list[dict[Name, Level]] = Field(min_length=1, description="list of {code: 1-255, factor: level, ...}")

    @field_validator("codes")
    @classmethod
    def _codes(cls, v: list[dict[str, Any]]) -> list[dict[str, Any]]:
        trigger_table(v)  # the rules the ERP analysis reads the table by (appeal.triggers)
        return v

    @model_validator(mode="after")
    def _addr(self) -> TriggerSpec:
        if self.backend in ("parallel", "serial") and not self.address:
            raise ValueError(f"backend '{self.backend}' needs 'address' (e.g. 0x0378 or /dev/ttyUSB0)")
        return self


class DemographicItem(StudyModel):
    """One question of the participant-information dialog (stored apart from the ratings)."""

    name: Name
    label: str = ""
    type: Literal["int", "text", "choice"] = "text"
    choices: list[str] = Field(default_factory=list)
    required: bool = Field(False, description="OK is refused until this field is answered")
    prefer_not_to_say: str | None = Field(
        None, description="text of an extra, explicit choice after the others (e.g. 'prefer not to say'), "
                          "recorded as written; choice fields only")

    @model_validator(mode="after")
    def _choices(self) -> DemographicItem:
        if self.type == "choice" and len(self.choices) < 2:
            raise ValueError("type 'choice' needs at least two choices")
        if self.type != "choice" and (self.choices or self.prefer_not_to_say is not None):
            raise ValueError(f"'choices' and 'prefer_not_to_say' need type 'choice' (got type '{self.type}')")
        if self.prefer_not_to_say is not None and self.prefer_not_to_say in self.choices:
            raise ValueError(f"prefer_not_to_say '{self.prefer_not_to_say}' is already one of the choices")
        if any(not c.strip() for c in self.choices) or self.prefer_not_to_say == "":
            raise ValueError("choices must not be empty (an unanswered field is recorded as n/a)")
        return self

    @property
    def options(self) -> list[str]:
        """The choices offered, the explicit 'prefer not to say' one last."""
        return [*self.choices, *([self.prefer_not_to_say] if self.prefer_not_to_say is not None else [])]


#: The choice values a psychophysics protocol's one classification must offer, by task and layout.
PAIR_CHOICES: dict[tuple[str, str], tuple[str, str]] = {
    ("2afc", "side_by_side"): ("left", "right"), ("2afc", "sequence"): ("first", "second"),
    ("same_different", "side_by_side"): ("same", "different"), ("same_different", "sequence"): ("same", "different"),
}


class ProcedureSpec(StudyModel):
    """How each track of a psychophysics protocol picks its levels and when it stops.

    ``psi`` (Bayesian adaptive, Kontsevich & Tyler 1999) stops after ``max_trials`` or once the
    threshold's credible interval is at most ``max_ci_width`` wide; ``staircase`` (transformed
    ``up``-up-``down``-down) after ``max_trials`` or ``max_reversals``; ``constant`` (method of
    constant stimuli) after ``trials_per_level`` answers at every level.
    """

    method: Literal["psi", "staircase", "constant"] = "psi"
    max_trials: int | None = Field(None, ge=1, le=5000, description="stop a track after this many trials")
    max_ci_width: float | None = Field(None, gt=0, description="psi: stop once the threshold's 95 % interval is this "
                                                               "narrow (in continuum units)")
    min_trials: int = Field(0, ge=0, description="psi: trials before max_ci_width may stop a track")
    family: Literal["logistic", "norm", "weibull"] = Field("logistic", description="psi: the function it assumes")
    guess: float | None = Field(None, ge=0, lt=1, description="psi: guess rate (default 0.5 for 2afc, 0 for "
                                                              "same_different's 'different' answers)")
    down: int = Field(2, ge=1, le=5, description="staircase: consecutive correct answers before a harder level")
    up: int = Field(1, ge=1, le=5, description="staircase: consecutive errors before an easier level")
    step: int = Field(1, ge=1, description="staircase: step in levels of the continuum")
    max_reversals: int | None = Field(None, ge=1, description="staircase: stop after this many reversals")
    trials_per_level: int | None = Field(None, ge=1, le=500, description="constant: answers per level")

    @model_validator(mode="after")
    def _stops(self) -> ProcedureSpec:
        rules = {"psi": ("max_trials", "max_ci_width"), "staircase": ("max_trials", "max_reversals"),
                 "constant": ("trials_per_level",)}[self.method]
        if all(getattr(self, r) is None for r in rules):
            raise ValueError(f"method '{self.method}' needs a stopping rule: {' or '.join(rules)} (got none)")
        own = {"psi": {"max_ci_width", "min_trials", "family", "guess"}, "staircase": {"down", "up", "step",
                                                                                        "max_reversals"},
               "constant": {"trials_per_level"}}
        foreign = sorted(self.model_fields_set - {"method", "max_trials"} - own[self.method])
        if foreign:
            raise ValueError(f"{', '.join(foreign)}: not used by method '{self.method}'")
        if self.method == "constant" and self.max_trials is not None:
            raise ValueError("method 'constant' stops after trials_per_level at every level (max_trials is not used)")
        return self


class PsychophysicsSpec(StudyModel):
    """A psychophysical procedure along a continuum factor (2AFC or same–different pairs).

    Every trial shows a reference face (the continuum's ``reference`` level) and a comparison
    face of the same item (the ``items`` factors' levels drawn per trial) at a level the
    track's procedure picks, in a random, balanced order (left/right or first/second); the one
    classification of ``responses`` is the answer. One track per level combination of
    ``conditions`` (times ``interleave``), tracks interleaved at random until all have stopped.
    """

    task: Literal["2afc", "same_different"] = "2afc"
    presentation: Literal["side_by_side", "sequence"] = "side_by_side"
    continuum: Name = Field(description="the numeric factor the levels lie on (e.g. shape: 0 realistic .. 1 cartoon)")
    reference: float = Field(description="the level every comparison is judged against (e.g. 0.0, the realistic end)")
    levels: list[float] = Field(default_factory=list, description="the comparison levels the procedure may show "
                                                                  "(values of the continuum); default: all but the "
                                                                  "reference")
    conditions: list[Name] = Field(default_factory=list, description="one track per level combination of these")
    with_continuum: list[Name] = Field(default_factory=list, description="factors whose level changes with the "
                                                                         "continuum's (e.g. a paired material)")
    items: list[Name] | None = Field(None, description="factors drawn per trial, shared by both faces (default: "
                                                       "every other factor)")
    interleave: int = Field(1, ge=1, le=8, description="tracks per condition")
    procedure: ProcedureSpec
    isi_s: Seconds = Field(0.5, description="sequence: blank between the two faces")
    same_proportion: float = Field(0.5, gt=0, lt=1, description="same_different: share of 'same' pairs")
    practice_trials: int = Field(0, ge=0, le=50, description="easy pairs before the tracks start (not scored)")

    @model_validator(mode="after")
    def _check(self) -> PsychophysicsSpec:
        named = [self.continuum, *self.conditions, *self.with_continuum, *(self.items or [])]
        dup = sorted({n for n in named if named.count(n) > 1})
        if dup:
            raise ValueError(f"{', '.join(dup)}: a factor may be the continuum, a condition, with_continuum or an item, "
                             "not two of them")
        if len(set(self.levels)) != len(self.levels) or self.reference in self.levels:
            raise ValueError("levels: expected distinct comparison levels without the reference "
                             f"{self.reference:g} (got {self.levels})")
        return self

    def choice_values(self) -> tuple[str, str]:
        """The two answers its classification must offer (e.g. left/right)."""
        return PAIR_CHOICES[(self.task, self.presentation)]


#: The pool columns a ``revcorr:`` protocol records with every trial (added to ``stimuli.factors``).
REVCORR_COLUMNS: tuple[str, ...] = ("revcorr_seed", "revcorr_trial", "revcorr_lateralised")


class RevcorrSpec(StudyModel):
    """``revcorr:``: a reverse-correlation session (Jack et al. 2012; docs/revcorr.md).

    The stimuli are a pool of clips of random action units, rendered by a grid with
    ``animation.revcorr`` (its manifest names each clip's ``revcorr_seed``, ``revcorr_trial`` and
    ``revcorr_lateralised``); those columns are recorded with every trial (the protocol adds them
    to ``stimuli.factors``), so ``appeal analyze revcorr`` draws every trial's AUs again from the
    data file alone. The one response is a classification among the six basic emotions and "don't
    know" (values ``happy``, ``surprise``, ``fear``, ``disgust``, ``anger``, ``sad``,
    ``dont_know``) with a 5-point intensity scale. ``trials``: how many of the pool's trials each
    participant sees at every level combination of the other factors, drawn by the participant's
    seed (the same trials at every level: a participant's models on two levels answer the same
    movements); default every trial of the pool.
    """

    trials: int | None = Field(None, ge=1, le=100_000,
                               description="pool trials per participant at every level combination (default: all)")


class Instructions(StudyModel):
    """Instruction pages shown before the first trial (Markdown-ish text, any language)."""

    pages: list[str] = Field(default_factory=list)
    files: list[InputFile] = Field(default_factory=list, description="Markdown files, one page each")
    continue_text: str = "Press SPACE to continue."
    end_text: str = "Thank you! The session is complete."


class Protocol(StudyModel):
    """A runner protocol: stimuli, screen, timing, order, responses, triggers (``kind: protocol``)."""

    kind: Literal["protocol"]
    name: Name
    title: str = ""
    task: Annotated[str, Field(pattern=r"^[A-Za-z0-9]+$")] = Field(description="BIDS task label (letters and digits)")
    stimuli: StimulusSource
    screen: ScreenSpec = Field(default_factory=ScreenSpec)
    timing: TimingSpec
    order: OrderSpec = Field(default_factory=OrderSpec)
    instructions: Instructions = Field(default_factory=Instructions)
    anchors: ExtraTrialsSpec | None = None
    practice: ExtraTrialsSpec | None = None
    end_of_session: ExtraTrialsSpec | None = None
    breaks: BreakSpec | None = None
    responses: list[Response] = Field(default_factory=list, description="empty = passive viewing")
    triggers: TriggerSpec | None = None
    demographics: list[DemographicItem] = Field(default_factory=list)
    psychophysics: PsychophysicsSpec | None = Field(
        None, description="run a psychophysical procedure along a continuum (2AFC or same-different pairs)")
    revcorr: RevcorrSpec | None = Field(
        None, description="a reverse-correlation session on a pool of random action-unit clips (docs/revcorr.md)")

    @model_validator(mode="after")
    def _cross(self) -> Protocol:
        if self.revcorr is not None:  # the pool's trial columns are recorded with every trial
            self.stimuli.factors = [*self.stimuli.factors, *(c for c in REVCORR_COLUMNS if c not in self.stimuli.factors)]
        factors = set(self.stimuli.factors)
        problems = []

        def check(where: str, names: Any) -> None:
            for n in names:
                if n not in factors:
                    problems.append(f"{where}: unknown factor '{n}' (stimuli.factors: {', '.join(self.stimuli.factors)})")

        check("order.block_by", self.order.block_by)
        check("order.max_run", self.order.max_run)
        check("stimuli.select", [*self.stimuli.select.where, *self.stimuli.select.exclude, *self.stimuli.select.match])
        for part in ("anchors", "practice", "end_of_session"):
            spec = getattr(self, part)
            if spec is not None and spec.select is not None:
                check(f"{part}.select", [*spec.select.where, *spec.select.exclude, *spec.select.match])
        names: list[str] = []
        for r in self.responses:
            names.append(r.name)
            if isinstance(r, ClassificationSpec):
                if r.factor is not None:
                    check(f"responses.{r.name}.factor", [r.factor])
                if r.intensity is not None:
                    names.append(r.intensity.name)
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            problems.append(f"responses: names must be unique (repeated: {', '.join(dup)})")
        if self.triggers is not None:
            for i, entry in enumerate(self.triggers.codes):
                check(f"triggers.codes[{i}]", [k for k in entry if k != "code"])
        if self.psychophysics is not None:
            problems += self._psychophysics_problems(self.psychophysics)
            psy = self.psychophysics
            check("psychophysics", [psy.continuum, *psy.conditions, *psy.with_continuum, *(psy.items or [])])
        if self.revcorr is not None:
            problems += self._revcorr_problems()
        if problems:
            raise ValueError("; ".join(problems))
        return self

    def _revcorr_problems(self) -> list[str]:
        """What a revcorr protocol cannot have: anything but one emotion classification with a 1-5 intensity."""
        from appeal.revcorr.observers import DONT_KNOW, EMOTIONS

        want = sorted([*EMOTIONS, DONT_KNOW])
        resp = self.responses
        if len(resp) != 1 or not isinstance(resp[0], ClassificationSpec):
            return [f"revcorr: expected exactly one classification response with the values {', '.join(want)} and a "
                    f"5-point intensity (got {len(resp)} response(s))"]
        spec, problems = resp[0], []
        values = sorted(level_key(c.value) for c in spec.choices)
        if values != want:
            problems.append(f"responses.{spec.name}.choices: revcorr expects the values {', '.join(want)} (got "
                            f"{', '.join(values)})")
        if spec.intensity is None or spec.intensity.points != 5:
            problems.append(f"responses.{spec.name}.intensity: revcorr expects a 5-point intensity scale (got "
                            f"{'none' if spec.intensity is None else f'{spec.intensity.points} points'})")
        if spec.factor is not None:
            problems.append(f"responses.{spec.name}.factor: a revcorr answer has no correct value (expected no 'factor')")
        if self.psychophysics is not None:
            problems.append("revcorr: not used with psychophysics")
        return problems

    def _psychophysics_problems(self, psy: PsychophysicsSpec) -> list[str]:
        """What a psychophysics protocol cannot have: one classification answering the pair, no more."""
        want = psy.choice_values()
        resp = self.responses
        if len(resp) != 1 or not isinstance(resp[0], ClassificationSpec):
            return [f"psychophysics: expected exactly one classification response answering the pair with the choice "
                    f"values {' and '.join(want)} (got {len(resp)} response(s))"]
        spec = resp[0]
        problems = []
        values = sorted(level_key(c.value) for c in spec.choices)
        if values != sorted(want):
            problems.append(f"responses.{spec.name}.choices: psychophysics ({psy.task}, {psy.presentation}) expects "
                            f"the values {' and '.join(want)} (got {', '.join(values)})")
        if spec.factor is not None or spec.intensity is not None:
            problems.append(f"responses.{spec.name}: a pair's answer is scored by the procedure (expected no 'factor' "
                            "and no 'intensity')")
        for part in ("anchors", "practice", "end_of_session", "triggers"):
            if getattr(self, part) is not None:
                problems.append(f"{part}: not used with psychophysics (practice: psychophysics.practice_trials)")
        if self.timing.on_dropped_frames == "repeat":
            problems.append("timing.on_dropped_frames: repeat: a procedure's next level depends on each answer "
                            "(expected log or flag)")
        return problems

    @property
    def response_names(self) -> list[str]:
        """Every response column stem (``response_<name>``), follow-up scales included."""
        out = []
        for r in self.responses:
            out.append(r.name)
            if isinstance(r, ClassificationSpec) and r.intensity is not None:
                out.append(r.intensity.name)
        return out


def protocol_base_dir(path: str | Path) -> Path:
    """The folder relative paths of a protocol file resolve against."""
    return Path(path).resolve().parent
