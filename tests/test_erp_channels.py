"""10-5 -> BioSemi-128 mapping: the shipped table, exact coincidences, mirror symmetry, cluster resolution."""

from __future__ import annotations

import pandas as pd
import pytest

from analysis.erp.channels import BIOSEMI128_MAP_FILE, biosemi128_map, nearest_channel_table, resolve_cluster
from analysis.erp_schema import THESIS_COMPONENTS
from appeal.errors import AppealInputError


def test_shipped_table_equals_nearest_position_computation():
    shipped = pd.read_csv(BIOSEMI128_MAP_FILE, comment="#")
    fresh = nearest_channel_table(shipped["name_1005"])
    assert list(shipped["biosemi128"]) == list(fresh["biosemi128"])
    assert (shipped["angle_deg"] - fresh["angle_deg"]).abs().max() < 0.01
    assert len(shipped) == 344 and shipped["angle_deg"].max() < 15


def test_known_positions():
    # Cz is BioSemi's A1 (both layouts put it at the vertex: angle 0)
    row = nearest_channel_table(["Cz"]).iloc[0]
    assert row["biosemi128"] == "A1" and row["angle_deg"] < 1e-6
    m = biosemi128_map()
    # thesis §7.3 cluster members (values read off the shipped table; checked against the
    # BioSemi 128 layout: A9/A10 left of the inion row, B5-B7 their mirror images)
    assert m["po9h"] == "A9" and m["po9"] == "A10" and m["i1"] == "A15" and m["oi1"] == "A16"
    assert m["po8"] == "B5" and m["po10"] == "B7" and m["i2"] == "A28"


def test_mirror_names_map_to_mirror_electrodes():
    import numpy as np

    from analysis.erp.channels import make_montage

    pos = make_montage("biosemi128").get_positions()["ch_pos"]
    m = biosemi128_map()
    for left, right in [("PO9h", "PO10h"), ("PO7", "PO8"), ("TP7", "TP8"), ("P9", "P10"), ("CP5", "CP6"), ("O1", "O2")]:
        a, b = pos[m[left.lower()]], pos[m[right.lower()]]
        assert np.allclose(a * [-1, 1, 1], b, atol=0.012), (left, right)


def test_thesis_clusters_resolve_to_biosemi_labels():
    from analysis.erp.channels import make_montage

    chans = make_montage("biosemi128").ch_names
    left = resolve_cluster(THESIS_COMPONENTS["N170"]["clusters"]["left"], chans, "biosemi128", where="x")
    right = resolve_cluster(THESIS_COMPONENTS["N170"]["clusters"]["right"], chans, "biosemi128", where="x")
    parietal = resolve_cluster(THESIS_COMPONENTS["LPP"]["clusters"]["parietal"], chans, "biosemi128", where="x")
    assert len(left) == len(right) == 11  # 15 positions share 11 electrodes per side
    assert not set(left) & set(right)
    assert len(parietal) >= 15
    # labels already in the recording are kept as they are
    assert resolve_cluster(["B7", "PO8"], chans, "biosemi128", where="x") == ["B7", "B5"]


def test_missing_cluster_channels_are_a_one_line_error():
    with pytest.raises(AppealInputError, match=r"comp.N170.clusters.left: channels not in the recording: PO9h \(= A9\)"):
        resolve_cluster(["PO9h"], ["A1", "A2"], "biosemi128", where="comp.N170.clusters.left")
    with pytest.raises(AppealInputError, match="XYZ"):
        resolve_cluster(["XYZ"], ["A1"], None, where="w")


# --------------------------------------------------------------------------- channels.rename
def test_positional_map_follows_biosemi_order(shared_data):
    import mne

    from analysis.erp.channels import biosemi_positional_map

    # MNE's test.bdf is a 64-electrode BioSemi file labelled with 10-20 names in BioSemi's
    # A1..B32 order: the biosemi64 montage lists them in the same order
    raw = mne.io.read_raw_bdf(shared_data / "eeg/biosemi/test.bdf", verbose="error")
    m64 = biosemi_positional_map("biosemi64")
    assert list(m64) == [f"A{i}" for i in range(1, 33)] + [f"B{i}" for i in range(1, 33)]
    assert list(m64.values()) == raw.ch_names[:64]
    m16 = biosemi_positional_map("biosemi16")
    assert m16["A1"] == "Fp1" and m16["A4"] == "Fz" and m16["A8"] == "Cz" and m16["A16"] == "O2"
    # biosemi128 and larger already use the positional labels
    assert all(k == v for k, v in biosemi_positional_map("biosemi128").items())


def test_rename_a1_style_and_labelled_files(shared_data):
    from analysis.erp.channels import rename_channels
    from analysis.erp.io import read_recording

    path = shared_data / "eeg/biosemi/Newtest17-256.bdf"
    raw = read_recording(path)
    applied = rename_channels(raw, "biosemi16", path)
    assert len(applied) == 16 and raw.ch_names[:4] == ["Fp1", "Fp2", "F4", "Fz"] and raw.ch_names[-1] == "Status"
    # a file already labelled with the montage's names passes unchanged through the same option
    labelled = read_recording(shared_data / "eeg/biosemi/test.bdf")
    before = list(labelled.ch_names)
    assert rename_channels(labelled, "biosemi64", "test.bdf") == {} and labelled.ch_names == before
    # an explicit mapping; a new name that is another channel of the file is an error
    raw = read_recording(path)
    assert rename_channels(raw, {"A1": "Fp1", "X9": "Oz"}, path) == {"A1": "Fp1"}
    with pytest.raises(AppealInputError, match=r"Newtest17-256.bdf: channels.rename: A2 -> A3: the recording "
                                               r"already has a channel A3"):
        rename_channels(raw, {"A2": "A3"}, path)


def test_montage_error_suggests_rename(shared_data):
    from analysis.erp.io import read_recording
    from analysis.erp.preprocessing import setup_channels

    path = shared_data / "eeg/biosemi/Newtest17-256.bdf"
    with pytest.raises(AppealInputError) as err:
        setup_channels(read_recording(path), "biosemi16", [], path)
    assert len(err.value.lines) == 1
    assert "montage: 'biosemi16' has positions for 0 of the 16 EEG channels" in err.value.lines[0]
    assert "channels: {rename: biosemi16}" in err.value.lines[0]


@pytest.mark.parametrize("rename, message", [
    ("biosemi17", "channels.rename: unknown BioSemi layout 'biosemi17' (did you mean 'biosemi16'?)"),
    ({"A1": "Fp1", "A2": "Fp1"}, "channels.rename: several channels renamed to Fp1"),
    ({"A1": " "}, "channels.rename: expected non-empty channel names"),
])
def test_rename_option_validated(tmp_path, rename, message):
    import yaml

    from analysis.erp.config import load_erp_config
    from appeal.errors import StudyFileError

    p = tmp_path / "c.yaml"
    p.write_text(yaml.safe_dump({"kind": "erp", "recordings": "x.bdf", "events": {1: {"a": "b"}},
                                 "channels": {"rename": rename}}))
    with pytest.raises(StudyFileError) as err:
        load_erp_config(p)
    assert len(err.value.lines) == 1 and err.value.lines[0].startswith(f"{p}: {message}")
