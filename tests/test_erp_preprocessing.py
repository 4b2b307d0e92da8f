"""The memory-saving preprocessing steps give exactly (bit for bit) what the MNE calls give.

``filter_raw`` (``n_jobs=1``), the block-wise ``set_reference`` and the block-wise
``reject_absolute`` replace MNE calls that copy the whole recording; these tests run both on
the same small random recording and compare with ``np.array_equal``.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.erp import preprocessing as pp


def _raw(n_times: int = 3000, sfreq: float = 256.0, bads=()):
    import mne

    names = [f"E{i}" for i in range(12)] + ["EOG1", "EOG2", "STI"]
    info = mne.create_info(names, sfreq, ["eeg"] * 12 + ["eog"] * 2 + ["stim"])
    rng = np.random.default_rng(7)
    data = rng.standard_normal((len(names), n_times)) * 20e-6
    data[-1] = 0
    raw = mne.io.RawArray(data, info, verbose="error")
    raw.info["bads"] = list(bads)
    return raw


@pytest.mark.parametrize("reference", ["average", ["E3", "E7"]])
@pytest.mark.parametrize("bads", [(), ("E5",)])
def test_block_reference_equals_mne(reference, bads):
    ours, theirs = _raw(bads=bads), _raw(bads=bads)
    pp.set_reference(ours, reference, block_s=1.3)  # blocks of 332 samples, the last one shorter
    theirs.set_eeg_reference(reference, projection=False, verbose="error")
    assert np.array_equal(ours.get_data(), theirs.get_data())
    assert ours.info["custom_ref_applied"] == theirs.info["custom_ref_applied"]
    assert not ours.info["projs"]
    if bads:  # MNE leaves bad channels alone
        assert np.array_equal(ours.get_data(picks=list(bads)), _raw().get_data(picks=list(bads)))


def test_reference_none_leaves_data():
    raw = _raw()
    pp.set_reference(raw, "none")
    assert np.array_equal(raw.get_data(), _raw().get_data())


def test_filter_channel_by_channel_equals_mne_default():
    ours, theirs = _raw(n_times=4000), _raw(n_times=4000)
    pp.filter_raw(ours, 0.5, 30.0)
    theirs.filter(0.5, None, picks=["eeg", "eog"], phase="minimum", verbose="error")
    theirs.filter(None, 30.0, picks=["eeg", "eog"], verbose="error")
    assert np.array_equal(ours.get_data(), theirs.get_data())


def test_reject_absolute_blocks_equal_whole_array():
    """Same epochs dropped as the whole-array rule on ``get_data(picks="eeg")`` (bad channels ignored)."""
    import mne

    raw = _raw(n_times=20000, bads=("E2",))
    raw._data[2, 5000:9000] *= 100  # a channel left marked bad (not interpolated) must not reject epochs
    events = np.c_[np.arange(100, 19000, 120), np.zeros(158, int), np.ones(158, int)]
    epochs = mne.Epochs(raw, events, tmin=-0.1, tmax=0.3, baseline=None, picks=["eeg"], preload=True,
                        verbose="error")
    data = epochs.get_data(picks="eeg")
    assert data.shape[1] == 11
    threshold = float(np.median(np.abs(data).max(axis=(1, 2)))) * 1e6
    expected = np.flatnonzero(np.abs(data).max(axis=(1, 2)) > threshold * 1e-6)
    data = epochs.get_data(copy=True)
    assert 0 < len(expected) < len(data)
    assert pp.reject_absolute(epochs, threshold) == len(expected)
    assert np.array_equal(epochs.get_data(), np.delete(data, expected, axis=0))
