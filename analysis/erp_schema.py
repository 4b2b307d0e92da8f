"""The ERP analysis config (``kind: erp``): recordings to N170 / EPN / LPP amplitudes.

Defaults follow Zell's thesis §7.3: 128-channel BioSemi, average reference, causal 0.16 Hz
high-pass and zero-phase 30 Hz low-pass, epochs -100 ... 600 ms with a -100 ... 0 ms
baseline, 120 µV rejection, N170 (150-190 ms) and EPN (250-400 ms) over two
temporo-occipital clusters, LPP (400-600 ms) over a parietal cluster. Example::

    kind: erp
    recordings: data/sub-*_task-faces_eeg.bdf
    montage: biosemi128
    events: {protocol: ../exp3_erp.yaml}
    eog: [EXG1, EXG2, EXG3, EXG4]
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from analysis.covariates_schema import CovariatesSpec
from analysis.mixed_schema import MixedOptions
from appeal.studyfile import InputDir, InputFile, OutputPath, StudyModel

__all__ = [
    "ErpConfig",
    "FilterConfig",
    "EpochsConfig",
    "RejectConfig",
    "BadChannelsConfig",
    "ComponentConfig",
    "SourceConfig",
    "QualityConfig",
    "ProtocolEvents",
    "FiguresConfig",
    "ChannelsConfig",
    "BIOSEMI_LAYOUTS",
    "THESIS_COMPONENTS",
]

Level = str | int | float

# Thesis §7.3 clusters (10-5 names). The right cluster's printed list repeats PO10 and reads
# "TP8hT8"; it is the mirror image of the left one, which is what is used here.
_LEFT = ["I1", "OI1", "O1", "POO3", "PO9", "PO9h", "PO7", "PO7h", "P9", "P9h", "P7", "P7h", "TP9h", "TP7", "TP7h"]
_RIGHT = ["I2", "OI2", "O2", "POO4", "PO10", "PO10h", "PO8", "PO8h", "P10", "P10h", "P8", "P8h", "TP10h", "TP8", "TP8h"]
_PARIETAL = ["CCPz", "CP5", "CP5h", "CP3", "CP1", "CPz", "CP2", "CP4", "CP6", "CPP5h", "CPP3", "CPPz", "CPP4",
             "P3", "P1", "Pz", "P2", "P4", "PPO3", "PPO1", "PPOz", "PPO2", "PPO4", "PO3", "POz", "PO4"]

#: The thesis's windows and clusters (§7.3).
THESIS_COMPONENTS = {
    "N170": {"window_s": [0.150, 0.190], "clusters": {"left": _LEFT, "right": _RIGHT}, "polarity": "negative"},
    "EPN": {"window_s": [0.250, 0.400], "clusters": {"left": _LEFT, "right": _RIGHT}, "polarity": "negative"},
    "LPP": {"window_s": [0.400, 0.600], "clusters": {"parietal": _PARIETAL}, "polarity": "positive"},
}


#: BioSemi cap layouts (MNE montages) whose electrodes a recording may label by position,
#: A1-A32, B1-B32, ... in the order of the montage (``channels: {rename: biosemi16}``).
BIOSEMI_LAYOUTS = ("biosemi16", "biosemi32", "biosemi64", "biosemi128", "biosemi160", "biosemi256")


class ChannelsConfig(StudyModel):
    """Renaming the recording's channels before anything else reads them.

    ``rename`` is a mapping ``{A1: Fp1, A2: Fp2, ...}`` (file label -> new name) or the name
    of a BioSemi layout (``biosemi16`` ... ``biosemi256``): BioSemi's positional labels
    A1-A32, B1-B32, ... become that MNE montage's electrode names in order (for biosemi16:
    A1 -> Fp1, A2 -> Fp2, A3 -> F4, ...). Labels the recording does not have are skipped, so
    one config reads A1-labelled files and files already labelled with the montage's names.
    Every other field (eog, clusters, figure channels, bad channels) uses the new names.
    """

    rename: dict[str, str] | str = Field(default_factory=dict)

    @field_validator("rename")
    @classmethod
    def _rename(cls, v: dict[str, str] | str) -> dict[str, str] | str:
        if isinstance(v, str):
            if v not in BIOSEMI_LAYOUTS:
                import difflib

                close = difflib.get_close_matches(v, BIOSEMI_LAYOUTS, n=1)
                hint = f"did you mean '{close[0]}'?" if close else f"expected one of {', '.join(BIOSEMI_LAYOUTS)}"
                raise ValueError(f"unknown BioSemi layout {v!r} ({hint}), or give a mapping {{A1: Fp1, ...}}")
            return v
        empty = [k for k, n in v.items() if not str(k).strip() or not str(n).strip()]
        if empty:
            raise ValueError(f"expected non-empty channel names (got {empty[0]!r}: {v[empty[0]]!r})")
        targets = list(v.values())
        dup = sorted({n for n in targets if targets.count(n) > 1})
        if dup:
            raise ValueError(f"several channels renamed to {', '.join(dup)} (expected each new name once)")
        return v


class ProtocolEvents(StudyModel):
    """``events: {protocol: FILE}``: read ``triggers.codes`` of a runner protocol."""

    protocol: InputFile


class FilterConfig(StudyModel):
    """Band limits; MNE's default FIR design (firwin, Hamming, automatic lengths)."""

    highpass_hz: float | None = Field(0.16, gt=0)
    lowpass_hz: float | None = Field(30.0, gt=0)
    highpass_causal: bool = True
    method: Literal["fir", "iir"] = "fir"
    notch_hz: list[float] = Field(default_factory=list)

    @model_validator(mode="after")
    def _order(self) -> FilterConfig:
        if self.highpass_hz and self.lowpass_hz and self.highpass_hz >= self.lowpass_hz:
            raise ValueError(f"highpass_hz must be below lowpass_hz (got {self.highpass_hz} >= {self.lowpass_hz})")
        return self


class EpochsConfig(StudyModel):
    """Epoch limits and baseline in seconds relative to the trigger."""

    tmin_s: float = -0.1
    tmax_s: float = 0.6
    baseline_s: tuple[float, float] | None = (-0.1, 0.0)

    @model_validator(mode="after")
    def _order(self) -> EpochsConfig:
        if self.tmin_s >= self.tmax_s:
            raise ValueError(f"tmin_s must be below tmax_s (got {self.tmin_s} >= {self.tmax_s})")
        if self.baseline_s is not None:
            a, b = self.baseline_s
            if not (self.tmin_s - 1e-9 <= a < b <= self.tmax_s + 1e-9):
                raise ValueError(f"baseline_s must be an interval inside [tmin_s, tmax_s] (got {list(self.baseline_s)})")
        return self


class RejectConfig(StudyModel):
    """Trial rejection: absolute threshold (thesis: 120 µV) or peak-to-peak (MNE ``reject``)."""

    absolute_uV: float | None = Field(None, gt=0)
    peak_to_peak_uV: float | None = Field(None, gt=0)

    @model_validator(mode="after")
    def _one(self) -> RejectConfig:
        if self.absolute_uV is not None and self.peak_to_peak_uV is not None:
            raise ValueError("give absolute_uV or peak_to_peak_uV, not both")
        return self


class BadChannelsConfig(StudyModel):
    """Bad-channel detection (robust z-score of the channel's log SD, flat channels)."""

    detect: bool = True
    z_threshold: float = Field(5.0, gt=0)
    flat_uV: float = Field(0.5, ge=0)
    mark: list[str] = Field(default_factory=list)
    interpolate: bool = True


class ComponentConfig(StudyModel):
    """One ERP component: its window, channel clusters and the direction of its peak."""

    window_s: tuple[float, float]
    clusters: dict[str, list[str]]
    polarity: Literal["negative", "positive"] = "negative"
    peak_fraction: float = Field(
        0.5, gt=0, le=1, description="fractional-peak latency (amplitudes.csv frac_peak_latency_ms): the first "
                                     "sample of the window reaching this fraction of the peak (onset side)")
    area_fraction: float = Field(
        0.5, gt=0, le=1, description="fractional-area latency (amplitudes.csv frac_area_latency_ms): the sample "
                                     "where the area of the component's sign reaches this fraction (0.5: ERP "
                                     "CORE's 50% area latency)")

    @field_validator("window_s")
    @classmethod
    def _window(cls, v: tuple[float, float]) -> tuple[float, float]:
        if v[0] >= v[1]:
            raise ValueError(f"window_s must be [start, end] with start < end (got {list(v)})")
        return v

    @field_validator("clusters")
    @classmethod
    def _clusters(cls, v: dict[str, list[str]]) -> dict[str, list[str]]:
        if not v:
            raise ValueError("at least one cluster is needed")
        for name, chans in v.items():
            if not chans:
                raise ValueError(f"cluster {name!r} has no channels")
        return v


class SourceConfig(StudyModel):
    """Source-space summaries: forward, inverse, window maps and voxel-wise contrasts."""

    enabled: bool = True
    method: Literal["dSPM", "sLORETA", "MNE", "eLORETA", "LCMV"] = "sLORETA"
    snr: float = Field(3.0, gt=0)
    spacing_mm: float = Field(7.0, ge=2, le=20)
    subjects_dir: InputDir | None = None
    subject: str = "fsaverage"
    bem: Literal["fsaverage"] | InputFile | None = Field(
        None, description="'fsaverage' (a realistic three-layer template from the fsaverage surfaces MNE ships, "
                          "MNI space), a BEM solution file (with trans), or none (a three-shell sphere)")
    trans: InputFile | None = None
    factor: str | None = None
    contrasts: list[tuple[Level, Level]] | None = None
    components: list[str] | None = None
    p_threshold: float = Field(0.005, gt=0, lt=1)
    min_cluster_voxels: int = Field(25, ge=1)
    min_cluster_mm3: float | None = Field(
        None, gt=0, description="smallest cluster as a volume, on any grid (the thesis's 25 voxels of 2 mm = 200 mm³); "
                                "replaces min_cluster_voxels")
    smoothing_fwhm_mm: float = Field(0.0, ge=0, description="Gaussian smoothing of each subject's map before the "
                                                             "voxel-wise test (SPM: 8 mm FWHM; 0 = none)")
    n_permutations: int = Field(1000, ge=10)

    @model_validator(mode="after")
    def _bem(self) -> SourceConfig:
        if self.bem is not None and self.bem != "fsaverage" and self.trans is None:
            raise ValueError("a bem needs trans (the head<->MRI transform of the template)")
        return self


class QualityConfig(StudyModel):
    """Data quality: the standardized measurement error (SME) of the mean amplitudes.

    ``sme_threshold_uV`` flags every subject x cell x component x cluster whose SME is above
    it (``sme.csv`` column ``flagged``, named in the report). The default None only reports the
    SMEs: they grow with the window's noise and shrink with the trials per cell, so no single
    cut-off fits every design (Luck et al. 2021 compare a subject's SME with the others').
    """

    sme_threshold_uV: float | None = Field(None, gt=0)


class ErpMixedConfig(MixedOptions):
    """Linear mixed models of the single-trial window means (``single_trials.csv``), one per
    component x cluster: ``mean_uV ~ factors`` with subjects (and stimuli, when ``beh`` names the
    runner's files) as crossed random factors; the random part and dfs as for ratings."""

    enabled: bool = False


class FiguresConfig(StudyModel):
    """Figures: waveform channels (10-5 names or labels; thesis Fig. 7.5-7.7: PO8, CPPz)."""

    channels: list[str] = Field(default_factory=lambda: ["PO8", "CPPz"])
    topomap_factor: str | None = None


class ErpConfig(StudyModel):
    """An ERP analysis (``kind: erp``); see docs/erp.md for every key."""

    kind: Literal["erp"]
    recordings: OutputPath | list[OutputPath]
    subject_pattern: str = r"sub-([A-Za-z0-9]+)"
    montage: str = "biosemi128"
    channels: ChannelsConfig = Field(default_factory=ChannelsConfig)
    events: dict[int, dict[str, Level]] | ProtocolEvents
    factors: list[str] | None = None
    levels: dict[str, list[Level]] = Field(default_factory=dict)
    ignore_codes: list[int] = Field(default_factory=list)
    unknown_codes: Literal["error", "ignore"] = "error"
    stim_channel: str = "auto"
    trigger_mask: int = Field(0xFFFF, ge=1)
    reference: Literal["average", "none"] | list[str] = "average"
    filter: FilterConfig = Field(default_factory=FilterConfig)
    resample_hz: float | None = Field(None, gt=0)
    epochs: EpochsConfig = Field(default_factory=EpochsConfig)
    eog: list[str] = Field(default_factory=list)
    eog_method: Literal["regression", "ica"] = "regression"
    bad_channels: BadChannelsConfig = Field(default_factory=BadChannelsConfig)
    reject: RejectConfig = Field(default_factory=lambda: RejectConfig(absolute_uV=120.0))
    components: dict[str, ComponentConfig] = Field(
        default_factory=lambda: {k: ComponentConfig(**v) for k, v in THESIS_COMPONENTS.items()})
    figures: FiguresConfig = Field(default_factory=FiguresConfig)
    quality: QualityConfig = Field(default_factory=QualityConfig)
    mixed: ErpMixedConfig = Field(default_factory=ErpMixedConfig)
    covariates: CovariatesSpec | None = Field(
        None, description="Stimulus audit measures as centred fixed covariates of the single-trial mixed models, "
                          "e.g. {audit: stimuli/erp/audit/audit.csv, measures: [face_L_mean]}; needs mixed: "
                          "{enabled: true} and beh (each trial's stimulus). The rm-ANOVA of amplitudes.csv "
                          "(per subject x condition) is not adjusted.")
    beh: OutputPath | list[OutputPath] | None = Field(
        None, description="the runner's *_beh.tsv files (globs), one per recording (same subject id): "
                          "single_trials.csv takes each trial's stimulus from them")
    source: SourceConfig = Field(default_factory=SourceConfig)
    n_jobs: int | None = Field(None, ge=1)

    @field_validator("events", mode="before")
    @classmethod
    def _events(cls, v):
        if isinstance(v, dict) and "protocol" not in v:
            for code, levels in v.items():
                try:
                    int(code)
                except (TypeError, ValueError):
                    raise ValueError(f"event codes must be integers (got {code!r})") from None
                if not isinstance(levels, dict) or not levels:
                    raise ValueError(f"code {code}: expected a mapping of factor to level, "
                                     f"e.g. {{stylisation: 0, emotion: angry}} (got {levels!r})")
        return v

    @model_validator(mode="after")
    def _covariates(self) -> ErpConfig:
        if self.covariates is None:
            return self
        if not self.mixed.enabled:
            raise ValueError("covariates: the single-trial mixed models use them: set mixed: {enabled: true}")
        if self.beh is None:
            raise ValueError("covariates: need beh (the runner's *_beh.tsv files give each trial's stimulus)")
        if self.covariates.by != "stimulus":
            raise ValueError(f"covariates.by: single_trials.csv names each trial's image in 'stimulus' (got {self.covariates.by!r})")
        return self

    @field_validator("montage")
    @classmethod
    def _montage(cls, v: str) -> str:
        if v.lower() == "none":
            return "none"
        import mne

        builtin = mne.channels.get_builtin_montages() + ["standard_1005", "standard_1020"]
        if v not in builtin:
            import difflib

            close = difflib.get_close_matches(v, builtin, n=1)
            hint = f"did you mean '{close[0]}'?" if close else "expected an MNE montage name or none"
            raise ValueError(f"unknown montage {v!r} ({hint})")
        return v
