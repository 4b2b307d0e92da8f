"""Window measures on averaged waveforms: mean amplitude, peak amplitude and latency.

Pure functions on arrays (volts in, microvolts out); :func:`measure_cells` applies them to
every condition cell, component and cluster of one subject.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

__all__ = ["window_mask", "cluster_waveform", "window_measures", "measure_cells", "AMPLITUDE_COLUMNS"]

#: Measure columns of ``amplitudes.csv`` (after the factor columns).
AMPLITUDE_COLUMNS = ["component", "cluster", "mean_uV", "peak_uV", "peak_latency_ms", "n_trials"]


def window_mask(times: np.ndarray, window: Sequence[float]) -> np.ndarray:
    """Samples inside ``window``, both ends snapped to the nearest sample and included.

    The same rule as MNE's ``Evoked.crop(tmin, tmax)``, so window means equal a plain MNE
    script's (note that ``Evoked.get_data(tmin=, tmax=)`` leaves out the ``tmax`` sample).

    Raises
    ------
    ValueError
        When the window holds no sample.
    """
    times = np.asarray(times, float)
    sfreq = 1.0 / np.median(np.diff(times)) if len(times) > 1 else 1.0
    lo = round(window[0] * sfreq) / sfreq - 0.5 / sfreq
    hi = round(window[1] * sfreq) / sfreq + 0.5 / sfreq
    mask = (times >= lo) & (times <= hi)
    if not mask.any():
        raise ValueError(f"window {list(window)} s holds no sample of the epoch ({times[0]:.3f} ... {times[-1]:.3f} s)")
    return mask


def cluster_waveform(data: np.ndarray, picks: Sequence[int]) -> np.ndarray:
    """Mean over the cluster's channels: ``data[picks].mean(axis=0)``."""
    return np.asarray(data)[list(picks)].mean(axis=0)


def window_measures(wave: np.ndarray, times: np.ndarray, window: Sequence[float], polarity: str = "negative") -> tuple[float, float, float]:
    """Mean amplitude, peak amplitude (µV) and peak latency (ms) of a waveform in a window.

    Parameters
    ----------
    wave : ndarray, shape (n_times,)
        The waveform in volts.
    times : ndarray, shape (n_times,)
        Sample times in seconds.
    window : (start, end)
        Window in seconds, both ends included.
    polarity : {"negative", "positive"}
        The peak is the minimum (negative) or maximum (positive) in the window.

    Returns
    -------
    mean_uV, peak_uV, peak_latency_ms : float
    """
    mask = window_mask(times, window)
    seg = np.asarray(wave)[mask] * 1e6
    i = int(np.argmin(seg) if polarity == "negative" else np.argmax(seg))
    return float(seg.mean()), float(seg[i]), float(np.asarray(times)[mask][i] * 1e3)


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
        name -> ``{"window_s": (a, b), "polarity": str, "clusters": {name: channel indices}}``.

    Returns
    -------
    pandas.DataFrame
        One row per cell, component and cluster: factor columns + :data:`AMPLITUDE_COLUMNS`.
    """
    rows = []
    for cell, data in evoked_data.items():
        for comp, spec in components.items():
            for cname, picks in spec["clusters"].items():
                mean, peak, lat = window_measures(cluster_waveform(data, picks), times, spec["window_s"], spec["polarity"])
                rows.append((*cell, comp, cname, mean, peak, lat, int(n_trials[cell])))
    return pd.DataFrame(rows, columns=[*factors, *AMPLITUDE_COLUMNS])
