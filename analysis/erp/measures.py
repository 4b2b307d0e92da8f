"""Window measures on waveforms: mean amplitude, peak amplitude and latency, fractional latencies.

Pure functions on arrays (volts in, microvolts and milliseconds out). The mean is a plain
window mean; the peak and the fractional latencies are MNE's (:mod:`mne.stats.erp`), given the
waveforms as an :class:`mne.EvokedArray` with one channel per waveform. Every measure reads
the same samples, those of :func:`window_mask` (both ends included, as ``Evoked.crop``), which
is also the window of ``mne.stats.erp.compute_peak`` / ``compute_frac_*`` (they select samples
with the same ``_time_mask``). :func:`measure_cells` applies them to every condition cell,
component and cluster of one subject.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

__all__ = ["window_mask", "cluster_waveform", "window_means", "window_peaks", "fractional_latencies",
           "window_measures", "measure_cells", "AMPLITUDE_COLUMNS", "MEASURE_COLUMNS"]

#: Measures of one waveform in a window (:func:`window_measures`).
MEASURE_COLUMNS = ["mean_uV", "peak_uV", "peak_latency_ms", "frac_peak_latency_ms", "frac_area_latency_ms"]

#: Measure columns of ``amplitudes.csv`` (after the factor columns).
AMPLITUDE_COLUMNS = ["component", "cluster", *MEASURE_COLUMNS, "n_trials"]


def _sfreq(times: np.ndarray) -> float:
    return 1.0 / float(np.median(np.diff(times))) if len(times) > 1 else 1.0


def window_mask(times: np.ndarray, window: Sequence[float]) -> np.ndarray:
    """Samples inside ``window``, both ends snapped to the nearest sample and included.

    The same rule as MNE's ``Evoked.crop(tmin, tmax)`` and as the windows of
    ``mne.stats.erp.compute_peak``, ``compute_frac_peak_latency`` and ``compute_frac_area_latency``,
    so window means equal a plain MNE script's (note that ``Evoked.get_data(tmin=, tmax=)``, and so
    ``mne.stats.erp.compute_sme``, leaves out the ``tmax`` sample; :mod:`analysis.erp.quality`
    keeps this rule for the SME).

    Raises
    ------
    ValueError
        When the window holds no sample.
    """
    times = np.asarray(times, float)
    sfreq = _sfreq(times)
    lo = round(window[0] * sfreq) / sfreq - 0.5 / sfreq
    hi = round(window[1] * sfreq) / sfreq + 0.5 / sfreq
    mask = (times >= lo) & (times <= hi)
    if not mask.any():
        raise ValueError(f"window {list(window)} s holds no sample of the epoch ({times[0]:.3f} ... {times[-1]:.3f} s)")
    return mask


def cluster_waveform(data: np.ndarray, picks: Sequence[int]) -> np.ndarray:
    """Mean over the cluster's channels (the channel axis is the second last).

    Parameters
    ----------
    data : ndarray, shape (n_channels, n_times) or (n_trials, n_channels, n_times)
        An average or single trials.
    picks : sequence of int
        The cluster's channel indices.

    Returns
    -------
    ndarray, shape (n_times,) or (n_trials, n_times)
        ``data[..., picks, :].mean(axis=-2)``, computed as a weighted sum so that single trials
        are not copied channel by channel.
    """
    data = np.asarray(data)
    weights = np.zeros(data.shape[-2])
    np.add.at(weights, list(picks), 1.0 / len(picks))
    return weights @ data


def _as_evoked(waves: np.ndarray, times: np.ndarray):
    """The waveforms (n_waves, n_times) as an EvokedArray with one ``misc`` channel each."""
    import mne

    info = mne.create_info([f"w{i}" for i in range(len(waves))], _sfreq(times), "misc")
    return mne.EvokedArray(waves, info, tmin=float(times[0]), verbose="error")


def _mode(polarity: str) -> str:
    if polarity not in ("negative", "positive"):
        raise ValueError(f"polarity must be 'negative' or 'positive' (got {polarity!r})")
    return "neg" if polarity == "negative" else "pos"


def window_means(waves: np.ndarray, times: np.ndarray, window: Sequence[float]) -> np.ndarray:
    """Window mean (µV) of each waveform.

    Parameters
    ----------
    waves : ndarray, shape (n_waves, n_times) or (n_times,)
        Waveforms in volts.
    times : ndarray, shape (n_times,)
        Sample times in seconds.
    window : (start, end)
        Window in seconds, both ends included (:func:`window_mask`).

    Returns
    -------
    ndarray, shape (n_waves,)
    """
    return np.atleast_2d(np.asarray(waves, float))[:, window_mask(times, window)].mean(axis=1) * 1e6


def window_peaks(waves: np.ndarray, times: np.ndarray, window: Sequence[float],
                 polarity: str = "negative") -> tuple[np.ndarray, np.ndarray]:
    """Peak amplitude (µV) and latency (ms) of each waveform: ``mne.stats.erp.compute_peak``.

    The peak is the window's minimum (``negative``, MNE mode ``neg``) or maximum (``positive``,
    ``pos``), the first such sample on ties; with ``strict=False`` a window without a value of the
    component's sign still has its extremum (MNE's strict mode would raise).

    Parameters
    ----------
    waves : ndarray, shape (n_waves, n_times) or (n_times,)
        Waveforms in volts.
    times : ndarray, shape (n_times,)
        Sample times in seconds.
    window : (start, end)
        Window in seconds, both ends included.
    polarity : {"negative", "positive"}
        The direction of the peak.

    Returns
    -------
    peak_uV, latency_ms : ndarray, shape (n_waves,)
    """
    from mne.stats.erp import compute_peak

    waves = np.atleast_2d(np.asarray(waves, float))
    window_mask(times, window)  # the one-line error for an empty window
    peak = compute_peak(_as_evoked(waves, times), window[0], window[1], mode=_mode(polarity), strict=False)
    return peak["amplitude"].to_numpy() * 1e6, peak["latency"].to_numpy() * 1e3


def fractional_latencies(waves: np.ndarray, times: np.ndarray, window: Sequence[float], polarity: str = "negative",
                         peak_fraction: float = 0.5, area_fraction: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Fractional-peak (onset side) and fractional-area latencies (ms): ``mne.stats.erp``.

    * ``compute_frac_peak_latency``: the first sample of the window where the waveform, signed
      by the polarity, reaches ``peak_fraction`` of the window's peak. MNE searches forward from
      the window's start, not backward from the peak as ERPLAB does: where an earlier deflection
      already reaches the fraction, the latency is that deflection's. Sample resolution, no
      interpolation between samples.
    * ``compute_frac_area_latency``: the first sample where the running area (trapezoid rule)
      of the waveform's part of the polarity's sign (MNE mode ``neg``/``pos``: the other sign
      counts as zero) reaches ``area_fraction`` of that part's area over the window (ERP CORE's
      50 % area latency). Sample resolution.

    Both are NaN for a waveform without any value of the polarity's sign in the window (no
    peak or area of that sign, where MNE would raise or return NaN). MNE's warnings about the
    peak's offset side (not used here) and about empty areas are silenced.

    Parameters
    ----------
    waves, times, window, polarity
        As :func:`window_peaks` (volts, seconds, both window ends included, the component's sign).
    peak_fraction, area_fraction : float
        Fractions in (0, 1].

    Returns
    -------
    frac_peak_latency_ms, frac_area_latency_ms : ndarray, shape (n_waves,)
    """
    import mne
    from mne.stats.erp import compute_frac_area_latency, compute_frac_peak_latency

    waves = np.atleast_2d(np.asarray(waves, float))
    seg = waves[:, window_mask(times, window)]
    mode = _mode(polarity)
    signed = (seg < 0 if mode == "neg" else seg > 0).any(axis=1)
    ev = _as_evoked(waves, times)
    with warnings.catch_warnings(), mne.utils.use_log_level("error"):
        warnings.simplefilter("ignore")
        onset = compute_frac_peak_latency(ev, peak_fraction, window[0], window[1], mode=mode, strict=False)
        area = compute_frac_area_latency(ev, area_fraction, window[0], window[1], mode=mode)
    nan = np.full(len(waves), np.nan)
    return (np.where(signed, onset["fractional_peak_onset"].to_numpy() * 1e3, nan),
            np.where(signed, area["fractional_area_latency"].to_numpy() * 1e3, nan))


def window_measures(waves: np.ndarray, times: np.ndarray, window: Sequence[float], polarity: str = "negative",
                    peak_fraction: float = 0.5, area_fraction: float = 0.5) -> pd.DataFrame:
    """All window measures of each waveform: :data:`MEASURE_COLUMNS`.

    Parameters
    ----------
    waves, times, window, polarity
        As :func:`window_peaks`.
    peak_fraction, area_fraction : float
        Fractions of :func:`fractional_latencies`.

    Returns
    -------
    pandas.DataFrame
        One row per waveform: mean_uV, peak_uV, peak_latency_ms, frac_peak_latency_ms,
        frac_area_latency_ms.
    """
    peak, lat = window_peaks(waves, times, window, polarity)
    fpeak, farea = fractional_latencies(waves, times, window, polarity, peak_fraction, area_fraction)
    values = [window_means(waves, times, window), peak, lat, fpeak, farea]
    return pd.DataFrame(dict(zip(MEASURE_COLUMNS, values)))


def measure_cells(
    evoked_data: Mapping[tuple, np.ndarray],
    n_trials: Mapping[tuple, int],
    times: np.ndarray,
    factors: Sequence[str],
    components: Mapping[str, dict],
) -> pd.DataFrame:
    """Measures of every cell x component x cluster.

    Parameters
    ----------
    evoked_data : mapping
        cell (tuple of levels) -> averaged data (n_channels, n_times) in volts.
    n_trials : mapping
        cell -> number of averaged trials.
    times : ndarray
        Sample times in seconds.
    factors : sequence of str
        Factor names (the cell tuples' order).
    components : mapping
        name -> ``{"window_s": (a, b), "polarity": str, "clusters": {name: channel indices}}``
        and optionally ``peak_fraction`` / ``area_fraction`` (default 0.5).

    Returns
    -------
    pandas.DataFrame
        One row per cell, component and cluster: factor columns + :data:`AMPLITUDE_COLUMNS`.
    """
    cells = list(evoked_data)
    cols = [*factors, *AMPLITUDE_COLUMNS]
    if not cells:
        return pd.DataFrame(columns=cols)
    parts = []
    for comp, spec in components.items():  # one MNE call per component: every cell's clusters at once
        names = list(spec["clusters"])
        waves = np.array([cluster_waveform(evoked_data[cell], spec["clusters"][c]) for cell in cells for c in names])
        m = window_measures(waves, times, spec["window_s"], spec["polarity"], spec.get("peak_fraction", 0.5),
                            spec.get("area_fraction", 0.5))
        keys = pd.DataFrame([(*cell, comp, c, int(n_trials[cell])) for cell in cells for c in names],
                            columns=[*factors, "component", "cluster", "n_trials"])
        parts.append(pd.concat([keys, m], axis=1).assign(_cell=np.repeat(np.arange(len(cells)), len(names))))
    out = pd.concat(parts, ignore_index=True).sort_values("_cell", kind="stable")  # rows by cell, then component
    return out[cols].reset_index(drop=True)
