"""ERP measures through ``mne.stats.erp``, the SME and the single-trial table: hand-computed answers
on small arrays, then the pipeline on simulated BDF recordings with runner-style ``_beh.tsv`` files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from analysis.erp.measures import (cluster_waveform, fractional_latencies, measure_cells, window_mask, window_measures,
                                   window_peaks)
from analysis.erp.quality import flag_sme, sme, sme_rms, sme_table
from analysis.erp.single_trials import match_stimuli, read_beh_trials, single_trial_table, trial_table
from analysis.erp_schema import QualityConfig
from appeal.errors import AppealInputError

SF = 1000.0
TIMES = np.arange(-100, 601) / SF  # -0.1 ... 0.6 s, 1 ms steps


def _triangle(peak_ms: float, half_width_ms: float, amp_uV: float) -> np.ndarray:
    t = TIMES * 1e3
    return amp_uV * 1e-6 * np.clip(1 - np.abs(t - peak_ms) / half_width_ms, 0, None)


# --------------------------------------------------------------------------- measures through MNE
def test_fractional_latencies_of_a_triangle():
    """A -10 µV triangle 150-190 ms (peak 170 ms). |x| >= 30 % of 10 µV from 156 ms on; the area up to t
    is (t - 150)² / 4 µV·ms of 200, a quarter (50) at t = 164.14 ms, so the first sample is 165 ms
    (the trapezoid rule is exact on a waveform that is linear between samples)."""
    wave = _triangle(170, 20, -10)
    fp, fa = fractional_latencies(wave, TIMES, (0.1, 0.3), "negative", peak_fraction=0.3, area_fraction=0.25)
    assert (fp[0], fa[0]) == (pytest.approx(156.0), pytest.approx(165.0))
    # the same shape upwards with polarity positive: the same latencies
    fp, fa = fractional_latencies(-wave, TIMES, (0.1, 0.3), "positive", peak_fraction=0.3, area_fraction=0.25)
    assert (fp[0], fa[0]) == (pytest.approx(156.0), pytest.approx(165.0))
    # the other sign only: no peak or area of the component's sign, so NaN (the peak is still the extremum)
    fp, fa = fractional_latencies(-wave, TIMES, (0.1, 0.3), "negative")
    assert np.isnan(fp[0]) and np.isnan(fa[0])


def test_fractional_peak_of_a_gaussian_and_mne_forward_search():
    """50 % of a Gaussian (sd 10 ms) peak is reached 10·sqrt(2 ln 2) = 11.77 ms before it: first sample
    159 ms. MNE searches forward from the window's start: an earlier deflection of 60 % of the peak
    (at 120 ms) gives its own onset (ERPLAB would search backward from the peak and stay at 159)."""
    t = TIMES * 1e3
    wave = -8e-6 * np.exp(-((t - 170) ** 2) / (2 * 10 ** 2))
    peak, lat = window_peaks(wave, TIMES, (0.1, 0.3), "negative")
    assert (peak[0], lat[0]) == (pytest.approx(-8.0), pytest.approx(170.0))
    assert fractional_latencies(wave, TIMES, (0.1, 0.3), "negative")[0][0] == pytest.approx(159.0)
    bump = wave + _triangle(120, 5, -4.8)
    assert fractional_latencies(bump, TIMES, (0.1, 0.3), "negative")[0][0] == pytest.approx(120.0)  # 4.8 >= 4 µV


def test_peak_through_mne_equals_the_hand_written_peak():
    """compute_peak (mode neg/pos, first sample on ties) == argmin/argmax over window_mask, the old rule."""
    rng = np.random.default_rng(4)
    for sf in (128.0, 256.0, 512.0, 1000.0, 2048.0):
        times = np.arange(-int(0.1 * sf), int(0.6 * sf) + 1) / sf
        waves = rng.normal(0, 5e-6, (40, len(times)))
        waves[0] = 0.0  # ties everywhere: the first sample
        waves[1] = np.abs(waves[1])  # no negative value: the minimum all the same
        for win in [(0.150, 0.190), (0.250, 0.400), (0.4, 0.6)]:
            m = window_mask(times, win)
            for pol, arg in (("negative", np.argmin), ("positive", np.argmax)):
                i = arg(waves[:, m], axis=1)
                peak, lat = window_peaks(waves, times, win, pol)
                assert np.array_equal(peak, waves[:, m][np.arange(40), i] * 1e6)
                assert np.allclose(lat, times[m][i] * 1e3, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- SME
def test_sme_is_sd_over_sqrt_n_and_keeps_the_window():
    """Synthetic epochs (binary-exact times at 128 Hz): SME == std of the single-trial window means /
    sqrt(n), written out with numpy index slicing; and == MNE's compute_sme on the raw epochs when its
    stop is one sample past the window (compute_sme leaves the stop sample out)."""
    import mne
    from mne.stats.erp import compute_sme

    rng = np.random.default_rng(7)
    sf, n = 128.0, 25
    times = np.arange(-16, 81) / sf  # -0.125 ... 0.625 s
    data = rng.normal(0, 4e-6, (n, 3, len(times)))
    a, b = 20, 24  # window samples 20/128 ... 24/128 s, i.e. indices 36 ... 40 inclusive
    comps = {"C": {"window_s": (a / sf, b / sf), "polarity": "negative", "clusters": {"one": [1], "pair": [0, 2]}}}
    trials = pd.DataFrame({"trial": np.arange(1, n + 1), "f": "x"})
    single = single_trial_table(data, times, comps, trials)
    got = sme_table(single, ["f"]).set_index("cluster")["sme_uV"]
    one = data[:, 1, 36:41].mean(axis=1) * 1e6
    pair = (data[:, 0, 36:41] + data[:, 2, 36:41]).mean(axis=1) / 2 * 1e6
    assert got["one"] == pytest.approx(one.std() / np.sqrt(n), rel=1e-12)
    assert got["pair"] == pytest.approx(pair.std() / np.sqrt(n), rel=1e-12)
    epochs = mne.EpochsArray(data * 1e6, mne.create_info(3, sf, "misc"), tmin=times[0], baseline=None, verbose="error")
    assert got["one"] == pytest.approx(compute_sme(epochs, a / sf, (b + 1) / sf)[1], rel=1e-12)
    assert got["one"] != pytest.approx(compute_sme(epochs, a / sf, b / sf)[1], rel=1e-6)  # the last sample left out
    # direct: one column per score; one trial has no spread
    vals = rng.normal(0, 1, (9, 2))
    assert sme(vals) == pytest.approx(vals.std(axis=0) / 3, rel=1e-12)
    assert np.isnan(sme(vals[:1])).all()


def test_flags_and_rms():
    table = pd.DataFrame({"subject": ["a", "b", "c", "a", "b", "c"], "f": [1, 1, 1, 2, 2, 2], "component": "N",
                          "cluster": "l", "sme_uV": [3.0, 4.0, np.nan, 1.0, 1.0, 7.0], "n_trials": 9})
    assert flag_sme(table, 3.5)["flagged"].tolist() == [False, True, False, False, False, True]
    assert not flag_sme(table, None)["flagged"].any()
    rms = sme_rms(table, ["f"])
    assert rms["rms_sme_uV"].tolist() == pytest.approx([np.sqrt(12.5), np.sqrt(17.0)])
    assert rms["n_subjects"].tolist() == [2, 3]


# --------------------------------------------------------------------------- single trials
def test_single_trial_means_average_to_the_cell_means():
    """Averaging is linear: each cell's mean of single-trial window means == the window mean of its average."""
    rng = np.random.default_rng(3)
    times = np.arange(-13, 77) / 128
    codes = np.array([1, 2, 1, 1, 2, 2, 2, 1, 1])
    data = rng.normal(0, 5e-6, (len(codes), 4, len(times))) + codes[:, None, None] * 1e-6
    comps = {"N": {"window_s": (0.15, 0.19), "polarity": "negative", "clusters": {"l": [0, 1], "r": [3]}},
             "P": {"window_s": (0.4, 0.6), "polarity": "positive", "clusters": {"c": [1, 2, 3]}}}
    events = np.c_[np.arange(len(codes)) * 100, np.zeros(len(codes), int), codes]
    selection = np.array([0, 1, 2, 4, 5, 6, 7, 9, 10])  # trials 4 and 9 were rejected
    trials = trial_table(selection, events, {1: ("a",), 2: ("b",)}, ["cond"])
    single = single_trial_table(data, times, comps, trials)
    assert len(single) == 3 * len(codes) and single["trial"].tolist()[:6] == [1, 1, 1, 2, 2, 2]
    assert single["stimulus"].isna().all() and single["beh_trial"].isna().all()
    cells = {("a",): data[codes == 1].mean(axis=0), ("b",): data[codes == 2].mean(axis=0)}
    amps = measure_cells(cells, {c: 1 for c in cells}, times, ["cond"], comps)
    means = single.groupby(["cond", "component", "cluster"])["mean_uV"].mean()
    for r in amps.itertuples():
        assert abs(means[(r.cond, r.component, r.cluster)] - r.mean_uV) < 1e-9
    # the peak of a trial is the peak of its own cluster waveform
    wave = cluster_waveform(data[3], [0, 1])
    first = single[(single.trial == 5) & (single.cluster == "l")].iloc[0]
    assert first.peak_uV == pytest.approx(window_measures(wave, times, (0.15, 0.19)).peak_uV.iloc[0], rel=1e-12)


def _beh_file(path: Path, codes: list[int], extra_rows: bool = True) -> list[str]:
    """A runner-like _beh.tsv: one row per code (stimulus varies within a code), plus rows without a
    trigger and with a code outside the event map, which the pairing must skip."""
    rows, stims, k = [], [], 1
    if extra_rows:
        rows.append({"trial": k, "phase": "practice", "stimulus": "practice.png", "trigger": "n/a"})
        k += 1
    for i, c in enumerate(codes):
        stim = f"face_{c}_{'ab'[i % 2]}.png"
        rows.append({"trial": k, "phase": "main", "stimulus": stim, "trigger": str(c)})
        stims.append(stim)
        k += 1
        if extra_rows and i == 3:
            rows.append({"trial": k, "phase": "main", "stimulus": "odd.png", "trigger": "250"})
            k += 1
    pd.DataFrame(rows).to_csv(path, sep="\t", index=False)
    return stims


def test_beh_pairing_rules(tmp_path):
    codes = [11, 12, 11, 13, 12]
    path = tmp_path / "sub-01_beh.tsv"
    stims = _beh_file(path, codes)
    beh = read_beh_trials(path, [11, 12, 13])
    assert beh["code"].tolist() == codes and beh["beh_trial"].tolist() == [2, 3, 4, 5, 7]
    kept = np.array([0, 2, 3, 4])  # the second event was rejected
    got = match_stimuli(beh, kept, np.array(codes)[kept], 5, path, "rec.bdf")
    assert got["stimulus"].tolist() == [stims[i] for i in kept] and got["beh_trial"].tolist() == [2, 4, 5, 7]
    with pytest.raises(AppealInputError, match=r"sub-01_beh.tsv: trigger: 5 trials .* rec.bdf has 6"):
        match_stimuli(beh, kept, np.array(codes)[kept], 6, path, "rec.bdf")
    wrong = np.array(codes)[kept]
    wrong[2] = 11
    with pytest.raises(AppealInputError, match=r"trigger: trial 5 sent code 13, but event 4 of rec.bdf has code 11"):
        match_stimuli(beh, kept, wrong, 5, path, "rec.bdf")
    pd.DataFrame({"trial": [1], "stimulus": ["x"]}).to_csv(tmp_path / "b.tsv", sep="\t", index=False)
    with pytest.raises(AppealInputError, match=r"b.tsv: trigger: no such column"):
        read_beh_trials(tmp_path / "b.tsv", [11])
    pd.DataFrame({"trial": [1], "stimulus": ["x"], "trigger": ["x1"]}).to_csv(tmp_path / "c.tsv", sep="\t", index=False)
    with pytest.raises(AppealInputError, match=r"c.tsv: trigger: row 1 holds 'x1'"):
        read_beh_trials(tmp_path / "c.tsv", [11])


# --------------------------------------------------------------------------- the pipeline on simulated BDF
@pytest.fixture(scope="module")
def study(tmp_path_factory):
    import mne

    from analysis.erp.simulate import SimulationDesign, simulate_study

    d = tmp_path_factory.mktemp("erp_quality")
    design = SimulationDesign(n_subjects=2, trials_per_cell=3, sfreq=128, spacing_mm=15.0, seed=5)
    sim = simulate_study(d / "data", design)
    stims = {}
    for k, f in enumerate(sim["files"], start=1):
        ev = mne.find_events(mne.io.read_raw_bdf(f, verbose="error"), shortest_event=1, verbose="error")
        beh = d / "data" / f"sub-{k:02d}" / "beh" / f"sub-{k:02d}_ses-1_task-faces_beh.tsv"
        beh.parent.mkdir(parents=True)
        stims[f"{k:02d}"] = _beh_file(beh, ev[:, 2].tolist())
    cfg = {"kind": "erp", "recordings": "data/sub-*_task-faces_eeg.bdf",
           "events": {int(c): lv for c, lv in design.events.items()}, "factors": ["stylisation", "emotion"],
           "eog": list(design.eog), "source": {"enabled": False}, "beh": "data/sub-*/beh/*_beh.tsv"}
    (d / "erp.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    return {"dir": d, "sim": sim, "design": design, "stims": stims, "cfg": cfg}


def _load(study, **changes):
    from analysis.erp.config import load_erp_config

    cfg = load_erp_config(study["dir"] / "erp.yaml")
    return cfg.model_copy(update=changes)


def test_subject_single_trials_average_to_amplitudes(study):
    """In memory (no CSV rounding): every cell's single-trial means average to its mean_uV to 1e-9 µV;
    the stimulus of each trial is its beh row's; the SME is the numpy SD / sqrt(n) of those values."""
    from analysis.erp.config import event_map
    from analysis.erp.pipeline import process_subject

    cfg = _load(study)
    beh = next((study["dir"] / "data" / "sub-01" / "beh").glob("*_beh.tsv"))
    res = process_subject(study["sim"]["files"][0], cfg, event_map(cfg), beh=beh)
    st, amps = res.single_trials, res.amplitudes
    assert len(st) == 5 * res.qc["n_epochs"]
    means = st.groupby(["stylisation", "emotion", "component", "cluster"])["mean_uV"].mean()
    diffs = [abs(means[(r.stylisation, r.emotion, r.component, r.cluster)] - r.mean_uV) for r in amps.itertuples()]
    assert len(diffs) == 18 * 5 and max(diffs) < 1e-9
    first = st.drop_duplicates("trial")
    assert first["stimulus"].tolist() == [study["stims"]["01"][t - 1] for t in first["trial"]]
    assert (first["code"].astype(str) == first["stimulus"].str.split("_").str[1]).all()
    for (s, e, comp, cl), g in st.groupby(["stylisation", "emotion", "component", "cluster"]):
        row = res.sme[(res.sme.stylisation == s) & (res.sme.emotion == e) & (res.sme.component == comp)
                      & (res.sme.cluster == cl)].iloc[0]
        assert row.sme_uV == pytest.approx(g["mean_uV"].std(ddof=0) / np.sqrt(len(g)), rel=1e-12)
        assert row.n_trials == len(g)


def test_pipeline_writes_sme_and_single_trials(study, tmp_path):
    from analysis.erp.pipeline import run_erp

    result, outputs = run_erp(_load(study), tmp_path / "a", source=study["dir"] / "erp.yaml", n_jobs=1)
    out = tmp_path / "a"
    sme_csv = pd.read_csv(out / "sme.csv")
    assert list(sme_csv.columns) == ["subject", "stylisation", "emotion", "component", "cluster", "sme_uV", "n_trials",
                                     "flagged"]
    assert len(sme_csv) == 2 * 18 * 5 and not sme_csv["flagged"].any() and (sme_csv["sme_uV"] > 0).all()
    single = pd.read_csv(out / "single_trials.csv")
    assert list(single.columns) == ["subject", "trial", "sample", "code", "stylisation", "emotion", "stimulus",
                                    "beh_trial", "component", "cluster", "mean_uV", "peak_uV", "peak_latency_ms"]
    qc = pd.read_csv(out / "qc.csv")
    assert len(single) == 5 * qc["n_epochs"].sum()
    keys = ["subject", "stylisation", "emotion", "component", "cluster"]
    assert single.groupby(keys).size().sort_index().tolist() == sme_csv.set_index(keys)["n_trials"].sort_index().tolist()
    assert (single["stimulus"].str.startswith("face_")).all()
    rms = pd.read_csv(out / "sme_rms.csv")
    assert len(rms) == 18 * 5 and (rms["n_subjects"] == 2).all()
    report = (out / "report.md").read_text()
    assert "## Data quality (SME)" in report and "nothing flagged" in report
    assert (out / "figures" / "sme.png").is_file() and outputs.sme == out / "sme.csv"
    # a threshold between the smallest and the largest SME flags exactly the values above it
    thr = float(np.round(sme_csv["sme_uV"].quantile(0.9), 3))
    run_erp(_load(study, quality=QualityConfig(sme_threshold_uV=thr)), tmp_path / "b", source=study["dir"] / "erp.yaml", n_jobs=1)
    flagged = pd.read_csv(tmp_path / "b" / "sme.csv")
    assert flagged["flagged"].tolist() == (flagged["sme_uV"] > thr).tolist() and 0 < flagged["flagged"].sum() < len(flagged)
    report = (tmp_path / "b" / "report.md").read_text()
    assert f"Threshold {thr:g} µV: {int(flagged['flagged'].sum())} of {len(flagged)} values above it" in report
    for subj in flagged.loc[flagged["flagged"], "subject"].unique():
        assert f"- **{subj:02d}** (" in report


def test_pipeline_without_beh_and_bad_beh(study, tmp_path):
    from analysis.erp.config import event_map
    from analysis.erp.pipeline import process_subject, process_subjects

    cfg = _load(study, beh=None)
    res = process_subject(study["sim"]["files"][1], cfg, event_map(cfg))
    assert res.single_trials["stimulus"].isna().all() and len(res.single_trials) == 5 * res.qc["n_epochs"]
    # a beh file one trial short: the subject fails with one line naming the file
    beh = tmp_path / "sub-02_beh.tsv"
    rows = pd.read_csv(next((study["dir"] / "data" / "sub-02" / "beh").glob("*_beh.tsv")), sep="\t")
    rows.iloc[:-1].to_csv(beh, sep="\t", index=False)
    with pytest.raises(AppealInputError, match=r"sub-02_beh.tsv: trigger: \d+ trials sent codes of the event map, but"):
        process_subject(study["sim"]["files"][1], cfg, event_map(cfg), beh=beh)
    # no file for a subject: stopped before any subject runs
    with pytest.raises(AppealInputError, match=r"erp.yaml: beh: no file for subject 02"):
        process_subjects(_load(study, beh=study["dir"] / "data" / "sub-01" / "beh" / "*.tsv"),
                         source=study["dir"] / "erp.yaml")
