"""Window measures, bad-channel scores and the BDF writer on small arrays with exact answers."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.erp.measures import cluster_waveform, measure_cells, window_mask, window_measures
from analysis.erp.preprocessing import robust_bad_channels


def test_window_mask_snaps_like_mne_crop():
    from mne.utils.numerics import _time_mask

    for sf in (100.0, 256.0, 512.0, 2048.0):
        times = np.arange(-int(0.1 * sf), int(0.6 * sf) + 1) / sf
        for win in [(0.150, 0.190), (0.250, 0.400), (0.4, 0.6)]:
            assert np.array_equal(window_mask(times, win), _time_mask(times, *win, sfreq=sf))
    with pytest.raises(ValueError, match="holds no sample"):
        window_mask(np.arange(10) / 10, (2.0, 3.0))


def test_window_measures_exact():
    times = np.arange(-2, 9) / 10  # -0.2 ... 0.8 s at 10 Hz
    wave = np.array([0, 0, 0, 1, -3, -5, 2, 4, 1, 0, 0]) * 1e-6
    m = window_measures(wave, times, (0.2, 0.4), "negative").iloc[0]  # samples 0.2, 0.3, 0.4: -3, -5, 2
    assert m.mean_uV == pytest.approx((-3 - 5 + 2) / 3)
    assert (m.peak_uV, m.peak_latency_ms) == (pytest.approx(-5.0), pytest.approx(300.0))
    # 50% of the -5 peak first reached at 0.2 s (-3); negative area: trapezoids 0.4 then 0.25 (of 0.65),
    # half of it passed at 0.3 s
    assert (m.frac_peak_latency_ms, m.frac_area_latency_ms) == (pytest.approx(200.0), pytest.approx(300.0))
    m = window_measures(wave, times, (0.4, 0.6), "positive").iloc[0]  # 2, 4, 1
    assert (m.mean_uV, m.peak_uV, m.peak_latency_ms) == (pytest.approx(7 / 3), pytest.approx(4.0), pytest.approx(500.0))
    # 50% of 4 reached at 0.4 s already; area 0.3 of 0.55 by 0.5 s
    assert (m.frac_peak_latency_ms, m.frac_area_latency_ms) == (pytest.approx(400.0), pytest.approx(500.0))
    # a fraction of 0.8: 3.2 first reached at the 4; area 0.8 x 0.55 = 0.44 only reached at 0.6 s
    m = window_measures(wave, times, (0.4, 0.6), "positive", peak_fraction=0.8, area_fraction=0.8).iloc[0]
    assert (m.frac_peak_latency_ms, m.frac_area_latency_ms) == (pytest.approx(500.0), pytest.approx(600.0))


def test_measure_cells_table():
    times = np.arange(0, 5) / 10
    data = np.array([[1, 1, 1, 1, 1], [3, 3, 3, 3, 3], [0, -2, -4, 0, 0]], float) * 1e-6
    comps = {"N": {"window_s": (0.1, 0.2), "polarity": "negative", "clusters": {"a": [0, 1], "b": [2]}}}
    df = measure_cells({(0, "x"): data}, {(0, "x"): 7}, times, ["s", "e"], comps)
    assert list(df.columns) == ["s", "e", "component", "cluster", "mean_uV", "peak_uV", "peak_latency_ms",
                                "frac_peak_latency_ms", "frac_area_latency_ms", "n_trials"]
    assert df[["s", "e"]].values.tolist() == [[0, "x"], [0, "x"]]
    assert df["mean_uV"].tolist() == pytest.approx([2.0, -3.0])
    assert df["peak_uV"].tolist() == pytest.approx([2.0, -4.0])
    # cluster a is all positive: no negative peak or area, so no fractional latency
    assert np.isnan(df["frac_peak_latency_ms"].iloc[0]) and df["frac_peak_latency_ms"].iloc[1] == pytest.approx(100.0)
    assert df["n_trials"].tolist() == [7, 7]
    assert cluster_waveform(data, [0, 1]) == pytest.approx(np.full(5, 2e-6))
    trials = np.stack([data, 3 * data])  # single trials: the channel axis is the second last
    assert cluster_waveform(trials, [0, 2]) == pytest.approx(np.stack([data[[0, 2]].mean(0), 3 * data[[0, 2]].mean(0)]))


def test_robust_bad_channels():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((20, 2000)) * (1 + 0.1 * rng.standard_normal((20, 1)))
    x[3] *= 12  # noisy
    x[7] = 0.0  # flat
    assert robust_bad_channels(x, 5.0, flat=1e-9).tolist() == [3, 7]
    # a channel 1.5x the others is not bad (spread floor)
    y = rng.standard_normal((20, 2000))
    y[5] *= 1.5
    assert robust_bad_channels(y, 5.0).tolist() == []


def test_bdf_writer_round_trip(tmp_path):
    import mne

    from analysis.erp.bdf import write_bdf

    rng = np.random.default_rng(0)
    data = rng.normal(0, 80, (3, 3 * 512))
    status = np.zeros(3 * 512, int) | 0x100000
    status[100:110] |= 11
    status[900:905] |= 63
    path = write_bdf(tmp_path / "x.bdf", data, ["A1", "B2", "EXG1"], 512, status)
    raw = mne.io.read_raw_bdf(path, preload=True, verbose="error")
    assert raw.ch_names == ["A1", "B2", "EXG1", "Status"] and raw.info["sfreq"] == 512
    assert np.abs(raw.get_data()[:3] * 1e6 - data).max() <= 1 / 64 + 1e-9  # half of BioSemi's 1/32 µV step
    ev = mne.find_events(raw, shortest_event=1, verbose="error")
    assert ev[:, [0, 2]].tolist() == [[100, 11], [900, 63]]
