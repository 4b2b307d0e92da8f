"""What the ERP pipeline gives back: one subject's result and the whole study's.

Made by :mod:`analysis.erp.pipeline`, written out by :mod:`analysis.erp.report`; both import
these types from here, so neither module names the other for them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from analysis.erp.config import EventMap

__all__ = ["ErpResult", "SubjectResult"]


@dataclass
class SubjectResult:
    """What one subject gives back: QC numbers, measures, single-trial measures and their SME, cell
    averages and source maps (small tables and arrays: never the epochs)."""

    subject: str
    path: str
    qc: dict
    amplitudes: pd.DataFrame
    evokeds: dict  # cell -> ndarray (n_channels, n_times), volts
    n_trials: dict  # cell -> int
    info: object  # mne.Info of the EEG channels
    times: np.ndarray
    source_maps: dict = field(default_factory=dict)  # (component, level) -> ndarray (n_vox,)
    single_trials: pd.DataFrame = field(default_factory=pd.DataFrame)  # analysis.erp.single_trials
    sme: pd.DataFrame = field(default_factory=pd.DataFrame)  # analysis.erp.quality.sme_table


@dataclass
class ErpResult:
    """All subjects: tables ready for statistics and figures."""

    subjects: list[SubjectResult]
    failures: list  # appeal.parallel.ItemFailure
    emap: EventMap
    head: object = None

    def _stacked(self, table: str) -> pd.DataFrame:
        """One table of every subject's ``table``, with ``subject`` as its first column."""
        if not self.subjects:
            return pd.DataFrame()
        parts = [getattr(s, table).assign(subject=s.subject) for s in self.subjects]
        return pd.concat(parts, ignore_index=True)[["subject", *getattr(self.subjects[0], table).columns]]

    @property
    def amplitudes(self) -> pd.DataFrame:
        """``amplitudes.csv``: subject, factor columns, component, cluster, measures, n_trials."""
        return self._stacked("amplitudes")

    @property
    def single_trials(self) -> pd.DataFrame:
        """``single_trials.csv``: subject, then one row per kept trial x component x cluster."""
        return self._stacked("single_trials")

    @property
    def sme(self) -> pd.DataFrame:
        """SME per subject x cell x component x cluster (``sme.csv`` adds ``flagged``)."""
        return self._stacked("sme")

    @property
    def qc(self) -> pd.DataFrame:
        """One row per subject: channels interpolated, trials rejected, trials per cell."""
        return pd.DataFrame([{"subject": s.subject, **s.qc} for s in self.subjects])
