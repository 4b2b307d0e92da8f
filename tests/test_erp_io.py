"""Readers on the real BioSemi files, bad input -> one-line errors naming file and field, and the
ERP workflow taking the config it is given."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest
import yaml

from analysis.erp.config import event_map, load_erp_config, read_protocol_codes
from analysis.erp.io import find_trigger_events, read_recording, select_events
from analysis.erp.pipeline import preprocess, run_erp
from analysis.erp.simulate import SimulationDesign, simulate_study
from appeal.errors import AppealInputError, StudyFileError


def test_test_bdf_equals_eeglab_reading(shared_data):
    from scipy.io import loadmat

    raw = read_recording(shared_data / "eeg/biosemi/test.bdf")
    eeglab = loadmat(shared_data / "eeg/biosemi/test_bdf_eeglab.mat")["data"]  # 72 x 2048, µV
    assert raw.info["sfreq"] == 2048 and raw.ch_names[-1] == "Status"
    ours = raw.get_data()[:72] * 1e6
    # EEGLAB keeps single precision: values agree to < 0.01 µV (BioSemi's step is 1/32 µV)
    assert np.abs(ours - eeglab).max() < 0.01
    assert np.corrcoef(ours.ravel(), eeglab.ravel())[0, 1] > 0.999999


# Expected events of every real BDF in shared/data/eeg, produced with plain MNE 1.13:
#   raw = mne.io.read_raw_bdf(path); ev = mne.find_events(raw)   (MNE's defaults)
# -> n events, first (sample, code), last (sample, code), code counts. For
# multiple_annotation_chans.bdf MNE's default stops ("4932 events shorter than the
# shortest_event"); the numbers are those of mne.find_events(raw, shortest_event=1), the one
# setting ours changes. Its "Trigger" channel is not a BioSemi Status (it varies sample by sample).
REAL_BDF_EVENTS = {
    # BioSemi's sample: Status rests at 254 and steps to 255 for each trigger (bit 16 set at the
    # start); the return to 254 is not an event (it was read as "unknown trigger code 254").
    "Newtest17-256.bdf": (40, (414, 255), (15304, 255), {255: 40}),
    "test.bdf": (1, (589, 128), (589, 128), {128: 1}),
    "test_bdf_stim_channel.bdf": (9, (242, 4), (4790, 1), {1: 7, 2: 1, 4: 1}),
    "multiple_annotation_chans.bdf": (14643, (2, 41845), (30874, 41691), None),
}


def test_every_real_bdf_is_in_the_table(shared_data):
    assert sorted(p.name for p in (shared_data / "eeg").rglob("*.bdf")) == sorted(REAL_BDF_EVENTS)


@pytest.mark.parametrize("name", sorted(REAL_BDF_EVENTS))
def test_events_equal_mne_find_events(shared_data, name):
    import mne

    path = shared_data / "eeg/biosemi" / name
    ev = find_trigger_events(read_recording(path), path)
    n, first, last, counts = REAL_BDF_EVENTS[name]
    assert len(ev) == n and tuple(ev[0, [0, 2]]) == first and tuple(ev[-1, [0, 2]]) == last
    if counts is not None:
        assert dict(zip(*(a.tolist() for a in np.unique(ev[:, 2], return_counts=True)))) == counts
    # and the same array as plain MNE, here and now (MNE's defaults where they run)
    raw = mne.io.read_raw_bdf(path, verbose="error")
    shortest = 1 if counts is None else 2
    assert np.array_equal(ev, mne.find_events(raw, shortest_event=shortest, verbose="error"))


def test_newtest_sample_has_no_unknown_codes(shared_data):
    path = shared_data / "eeg/biosemi/Newtest17-256.bdf"
    ev = select_events(find_trigger_events(read_recording(path), path), codes=[255], path=path)
    assert len(ev) == 40


def test_unknown_code_message(shared_data):
    path = shared_data / "eeg/biosemi/test_bdf_stim_channel.bdf"
    ev = find_trigger_events(read_recording(path), path)
    with pytest.raises(AppealInputError, match=r"events: unknown trigger codes 4 \(1x\)"):
        select_events(ev, codes=[1, 2], path=path)
    assert len(select_events(ev, codes=[1, 2], ignore=[4], path=path)) == 8


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    d = tmp_path_factory.mktemp("erp_small")
    design = SimulationDesign(n_subjects=1, trials_per_cell=2, sfreq=128, spacing_mm=15.0)
    sim = simulate_study(d, design)
    cfg = {"kind": "erp", "recordings": "sub-*_eeg.bdf", "events": {int(c): lv for c, lv in design.events.items()},
           "eog": ["EXG1", "EXG2", "EXG3", "EXG4"], "source": {"enabled": False}}
    (d / "erp.yaml").write_text(yaml.safe_dump(cfg))
    return d, sim["files"][0]


def _run(d, path, **changes):
    cfg = load_erp_config(d / "erp.yaml")
    cfg = cfg.model_copy(update=changes)
    return preprocess(path, cfg, event_map(cfg))


def test_small_recording_runs(small):
    """Checked against what the simulation planted (its truth.yaml), not against the pipeline's own QC."""
    d, path = small
    truth = yaml.safe_load((d / "truth.yaml").read_text())
    epochs, qc = _run(d, path)
    per_cell = truth["design"]["trials_per_cell"]
    planted = {int(c): per_cell for c in truth["events"]}
    # every planted trigger became an epoch of its own code: the data are clean once the blinks are
    # regressed out (EOG channels), so nothing may be rejected
    assert dict(zip(*(a.tolist() for a in np.unique(epochs.events[:, 2], return_counts=True)))) == planted
    assert qc["n_events"] == qc["n_epochs"] == sum(planted.values()) and qc["pct_trials_rejected"] == 0
    # the planted bad channel was found and interpolated
    assert qc["bad_channels"].split() == truth["bad_channels"]["01"]
    assert qc["pct_channels_interpolated"] == pytest.approx(100 * len(truth["bad_channels"]["01"]) / 128)


def test_run_erp_takes_the_loaded_config(small, tmp_path):
    """The workflow runs the model it is given and never reads the file again (the command and
    the workflow each loaded it before): the file is gone and a change made only to the model shows."""
    d, _ = small
    config = d / "erp_once.yaml"
    shutil.copy(d / "erp.yaml", config)
    cfg = load_erp_config(config)
    config.unlink()
    n170 = cfg.model_copy(update={"components": {"N170": cfg.components["N170"]}})
    result, outputs = run_erp(n170, tmp_path, source=config, n_jobs=1, n_permutations=10)
    assert len(result.subjects) == 1 and result.failures == []
    assert set(pd.read_csv(outputs.amplitudes).component) == {"N170"}
    assert n170.source.n_permutations == cfg.source.n_permutations != 10  # the override copies the model


def test_truncated_file(small, tmp_path):
    d, path = small
    bad = tmp_path / "sub-99_task-faces_eeg.bdf"
    bad.write_bytes(path.read_bytes()[: path.stat().st_size // 2 + 7])
    with pytest.raises(AppealInputError, match=r"sub-99_task-faces_eeg.bdf: truncated: header announces \d+ data records"):
        read_recording(bad)


def test_missing_eog_channel(small):
    d, path = small
    with pytest.raises(AppealInputError, match=r"eog: channels not in the recording: EXG9"):
        _run(d, path, eog=["EXG1", "EXG9"])


def test_wrong_montage(small):
    d, path = small
    with pytest.raises(AppealInputError, match=r"montage: 'biosemi64' has positions for \d+ of the 128 EEG channels"):
        _run(d, path, montage="biosemi64")


def test_unknown_codes_and_no_events(small, tmp_path):
    d, path = small
    cfg = load_erp_config(d / "erp.yaml")
    events = {c: lv for c, lv in cfg.events.items() if c != 11}
    with pytest.raises(AppealInputError, match=r"events: unknown trigger codes 11 \(2x\)"):
        _run(d, path, events=events)
    import mne

    raw = mne.io.read_raw_bdf(path, preload=True, verbose="error")
    raw._data[-1] = 0
    with pytest.raises(AppealInputError, match=r"events: no trigger events found in the stim channel Status"):
        find_trigger_events(raw, path)


def test_protocol_codes_and_config_errors(tmp_path):
    from appeal.assets import protocols_dir

    codes = read_protocol_codes(protocols_dir() / "erp_stylisation.yaml")
    assert {k: codes[11][k] for k in ("stylisation", "emotion")} == {"stylisation": 0, "emotion": "angry"}
    assert set(codes[11]) == {"character", "stylisation", "emotion"}
    assert len(codes) == 36
    p = tmp_path / "bad.yaml"
    p.write_text("kind: erp\nrecordings: x/*.bdf\nevents: {11: {s: 0}}\nreject: {absolute_uV: 100, peak_to_peak_uV: 80}\n"
                 "components: {N170: {window_s: [0.2, 0.1], clusters: {left: [PO7]}}}\nmontage: biosemi129\n")
    with pytest.raises(StudyFileError) as err:
        load_erp_config(p)
    text = str(err.value)
    assert "bad.yaml: reject: give absolute_uV or peak_to_peak_uV, not both" in text
    assert "bad.yaml: components.N170.window_s: window_s must be [start, end] with start < end" in text
    assert "bad.yaml: montage: unknown montage 'biosemi129' (did you mean 'biosemi128'?)" in text
    proto = tmp_path / "proto.yaml"
    proto.write_text("triggers:\n  codes:\n    - {code: x1, emotion: angry}\n")
    with pytest.raises(StudyFileError, match=r"proto.yaml: triggers.codes\[0\]: code must be an integer 1-255 \(got .x1.\)"):
        read_protocol_codes(proto)
    q = tmp_path / "q.yaml"
    q.write_text(f"kind: erp\nrecordings: x.bdf\nevents: {{protocol: {proto.name}}}\nfactors: [emotion]\n")
    with pytest.raises(StudyFileError, match="triggers.codes"):
        event_map(load_erp_config(q), q)
    proto.write_text("triggers:\n  codes:\n    - {code: 1, emotion: angry, s: 0}\n    - {code: 2, emotion: happy, s: 0}\n")
    em = event_map(load_erp_config(q), q)
    assert em.factors == ["emotion"] and em.cells == [("angry",), ("happy",)]
