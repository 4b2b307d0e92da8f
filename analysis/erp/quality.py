"""Data quality of the mean-amplitude measure: the standardized measurement error (SME).

The analytic SME of a mean amplitude (Luck, Stewart, Simmons & Rhemtulla 2021; ERP CORE) is the
standard deviation of the single-trial window means divided by the square root of the number
of trials: the standard error of the subject's averaged score. It is computed per subject x
condition cell x component x cluster from the single-trial window means of
:mod:`analysis.erp.single_trials` by ``mne.stats.erp.compute_sme`` (population SD, ``ddof=0``;
ERPLAB's MATLAB ``std`` divides by n - 1, a factor sqrt(n / (n - 1)) larger: 1.7 % at 30 trials).
Across subjects, ERP CORE summarises a cell by the root mean square of the SMEs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

__all__ = ["SME_COLUMNS", "sme", "sme_table", "flag_sme", "sme_rms"]

#: Columns of ``sme.csv`` after ``subject`` and the factor columns.
SME_COLUMNS = ["component", "cluster", "sme_uV", "n_trials", "flagged"]


def sme(values: np.ndarray) -> np.ndarray:
    """SME of each column of single-trial scores: ``mne.stats.erp.compute_sme``.

    ``compute_sme`` averages each epoch over ``Epochs.get_data(tmin, tmax)``, which leaves out
    the ``tmax`` sample and truncates ``tmin`` to a sample, unlike the window of
    :func:`analysis.erp.measures.window_mask` (both ends included). So the window means are
    taken first, by that rule, and ``compute_sme`` gets them as epochs of one sample each at
    1 Hz, followed by a copy that ``get_data`` leaves out: the result is exactly
    ``values.std(axis=0) / sqrt(n)``.

    Parameters
    ----------
    values : ndarray, shape (n_trials, n_scores)
        Single-trial window means (any unit; the SME has the same unit).

    Returns
    -------
    ndarray, shape (n_scores,)
        NaN where fewer than two trials (one trial has no spread to measure).
    """
    import mne
    from mne.stats.erp import compute_sme

    values = np.asarray(values, float)
    if values.ndim != 2:
        raise ValueError(f"expected single-trial scores of shape (n_trials, n_scores) (got {values.shape})")
    if len(values) < 2:
        return np.full(values.shape[1], np.nan)
    info = mne.create_info([f"s{i}" for i in range(values.shape[1])], 1.0, "misc")
    epochs = mne.EpochsArray(np.repeat(values[:, :, None], 2, axis=2), info, tmin=0.0, baseline=None, verbose="error")
    return compute_sme(epochs)


def sme_table(single_trials: pd.DataFrame, factors: Sequence[str], cells: Sequence[tuple] | None = None,
              value: str = "mean_uV") -> pd.DataFrame:
    """SME per condition cell x component x cluster of one subject's single trials.

    Parameters
    ----------
    single_trials : pandas.DataFrame
        :func:`analysis.erp.single_trials.single_trial_table`'s rows: ``trial``, the factor
        columns, ``component``, ``cluster`` and ``value``.
    factors : sequence of str
        The condition factors.
    cells : sequence of tuple | None
        The order of the cells (levels in ``factors`` order; the event map's); cells without
        trials are left out. None: the order of first appearance.
    value : str
        The single-trial score (µV).

    Returns
    -------
    pandas.DataFrame
        Factor columns, component, cluster, sme_uV, n_trials.
    """
    cols = [*factors, "component", "cluster", "sme_uV", "n_trials"]
    if single_trials.empty:
        return pd.DataFrame(columns=cols)
    order = list(dict.fromkeys(zip(single_trials["component"], single_trials["cluster"])))  # as measured
    wide = single_trials.pivot(index="trial", columns=["component", "cluster"], values=value)[order]
    per_trial = single_trials.drop_duplicates("trial").set_index("trial").loc[wide.index, list(factors)]
    positions = per_trial.groupby(list(factors), sort=False, observed=True).indices
    groups = {(k if isinstance(k, tuple) else (k,)): v for k, v in positions.items()}
    values = wide.to_numpy()
    parts = []
    for cell in (groups if cells is None else [c for c in cells if c in groups]):
        idx = groups[cell]
        out = pd.DataFrame(list(wide.columns), columns=["component", "cluster"])
        out["sme_uV"] = sme(values[idx])
        out["n_trials"] = len(idx)
        for f, level in zip(factors, cell):
            out[f] = [level] * len(out)
        parts.append(out[cols])
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=cols)


def flag_sme(table: pd.DataFrame, threshold_uV: float | None) -> pd.DataFrame:
    """``table`` with ``flagged``: the SME is above ``threshold_uV`` (all False without one)."""
    flagged = table["sme_uV"] > threshold_uV if threshold_uV is not None else pd.Series(False, index=table.index)
    return table.assign(flagged=flagged.astype(bool))


def sme_rms(table: pd.DataFrame, factors: Sequence[str]) -> pd.DataFrame:
    """Root mean square of the SME across subjects per cell x component x cluster (ERP CORE).

    Returns
    -------
    pandas.DataFrame
        Factor columns, component, cluster, rms_sme_uV, n_subjects (subjects with an SME).
    """
    keys = [*factors, "component", "cluster"]
    g = table.dropna(subset=["sme_uV"]).groupby(keys, sort=False, observed=True)["sme_uV"]
    out = g.agg(rms_sme_uV=lambda s: float(np.sqrt(np.mean(np.square(s)))), n_subjects="count").reset_index()
    return out[[*keys, "rms_sme_uV", "n_subjects"]]
