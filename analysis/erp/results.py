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
    """What one subject gives back: QC numbers, measures, cell averages and source maps."""

    subject: str
    path: str
    qc: dict
    amplitudes: pd.DataFrame
    evokeds: dict  # cell -> ndarray (n_channels, n_times), volts
    n_trials: dict  # cell -> int
    info: object  # mne.Info of the EEG channels
    times: np.ndarray
    source_maps: dict = field(default_factory=dict)  # (component, level) -> ndarray (n_vox,)


@dataclass
class ErpResult:
    """All subjects: tables ready for statistics and figures."""

    subjects: list[SubjectResult]
    failures: list  # appeal.parallel.ItemFailure
    emap: EventMap
    head: object = None

    @property
    def amplitudes(self) -> pd.DataFrame:
        """``amplitudes.csv``: subject, factor columns, component, cluster, measures, n_trials."""
        if not self.subjects:
            return pd.DataFrame()
        return pd.concat([s.amplitudes.assign(subject=s.subject) for s in self.subjects], ignore_index=True)[
            ["subject", *self.subjects[0].amplitudes.columns]]

    @property
    def qc(self) -> pd.DataFrame:
        """One row per subject: channels interpolated, trials rejected, trials per cell."""
        return pd.DataFrame([{"subject": s.subject, **s.qc} for s in self.subjects])
