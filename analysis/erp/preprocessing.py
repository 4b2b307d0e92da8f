"""Scalp preprocessing with MNE: channels and montage, filters, bad channels, reference, EOG, epochs.

Each step is one MNE call with MNE's defaults unless the config says otherwise, so a plain
MNE script with the same settings gives the same numbers (tests/test_erp_pipeline.py
checks that). Filtering, interpolation and re-referencing are linear and commute, so the
filters run first (bad-channel detection then sees filtered data) without changing results.

Memory: the recording is held once (float64, as MNE reads it) and every step works on it in
place. The filters run channel by channel (``n_jobs=1``; MNE's default ``n_jobs=None`` collects
every filtered channel in a list before writing back, a second copy of the recording), the
reference is subtracted in time blocks (MNE's ``set_eeg_reference`` indexes all EEG channels
at once, another copy) and the rejection looks at one block of epochs at a time. The numbers
are bit-for-bit those of the MNE calls (tests/test_erp_preprocessing.py).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError

__all__ = [
    "setup_channels",
    "filter_raw",
    "robust_bad_channels",
    "fix_bad_channels",
    "set_reference",
    "correct_eog",
    "make_epochs",
    "reject_absolute",
]


def setup_channels(raw, montage: str, eog: list[str], path: str | Path) -> None:
    """Type the channels (EOG, stim, misc) and attach the montage, in place.

    Channels the montage has no position for (unused BioSemi EXG inputs, for instance) become
    ``misc`` so they take no part in the analysis; with ``montage="none"`` the file's own
    positions are kept.

    Raises
    ------
    AppealInputError
        When EOG channels are missing, or the montage fits none / too few of the EEG channels.
    """
    from analysis.erp.channels import make_montage

    path = Path(path)
    missing = [c for c in eog if c not in raw.ch_names]
    if missing:
        raise AppealInputError(f"{path}: eog: channels not in the recording: {', '.join(missing)} "
                               f"(channels: {', '.join(raw.ch_names[:6])} ... {raw.ch_names[-1]})")
    types = {c: "eog" for c in eog}
    eeg = [raw.ch_names[i] for i in _picks(raw, "eeg") if raw.ch_names[i] not in types]
    if montage != "none":
        mont = make_montage(montage)
        known = {c.lower() for c in mont.ch_names}
        on = [c for c in eeg if c.lower() in known]
        off = [c for c in eeg if c.lower() not in known]
        if len(on) < max(3, len(eeg) // 2):
            positional = sum(bool(re.fullmatch(r"[A-H]\d{1,2}", c)) for c in off) > len(off) // 2
            hint = (f", and channels: {{rename: {montage}}} for BioSemi's positional labels A1, A2, ..."
                    if positional and montage.startswith("biosemi") else "")
            raise AppealInputError(
                f"{path}: montage: {montage!r} has positions for {len(on)} of the {len(eeg)} EEG channels "
                f"(e.g. no {', '.join(off[:4])}); expected the montage the recording was made with{hint}")
        types.update({c: "misc" for c in off})
    raw.set_channel_types(types, on_unit_change="ignore", verbose="error")
    if montage != "none":
        raw.set_montage(mont, match_case=False, on_missing="ignore", verbose="error")
    elif raw.get_montage() is None:
        raise AppealInputError(f"{path}: montage: 'none' keeps the file's positions, but the file has none "
                               "(expected a montage name such as biosemi128)")


def _picks(raw, kind: str) -> np.ndarray:
    import mne

    return mne.pick_types(raw.info, eeg=kind == "eeg", eog=kind == "eog", exclude=())


def filter_raw(raw, highpass_hz: float | None, lowpass_hz: float | None, *, highpass_causal: bool = True,
               method: str = "fir", notch_hz=(), n_jobs: int | None = 1) -> None:
    """Band-limit EEG and EOG channels in place (thesis: causal 0.16 Hz HP, zero-phase 30 Hz LP).

    With ``highpass_causal`` the high-pass runs forward only (MNE ``phase="minimum"`` for FIR,
    ``"forward"`` for IIR) and the low-pass separately with zero phase; otherwise one
    zero-phase band-pass. MNE's default design is used (firwin, Hamming window, automatic
    filter length and transition bands). ``n_jobs=1`` (the default here) makes MNE write each
    filtered channel back at once; any other value (MNE's own default ``None`` included) first
    collects all filtered channels, which doubles the memory of the recording. The filtered
    values are the same either way.
    """
    picks = ["eeg", "eog"]
    kw = dict(picks=picks, method=method, n_jobs=n_jobs, verbose="error")
    if notch_hz:
        raw.notch_filter(list(notch_hz), **kw)
    if highpass_hz and highpass_causal:
        raw.filter(highpass_hz, None, phase="minimum" if method == "fir" else "forward", **kw)
        if lowpass_hz:
            raw.filter(None, lowpass_hz, **kw)
    elif highpass_hz or lowpass_hz:
        raw.filter(highpass_hz, lowpass_hz, **kw)


def robust_bad_channels(data: np.ndarray, z_threshold: float = 5.0, flat: float = 0.0) -> np.ndarray:
    """Indices of bad channels: flat, or an outlying log standard deviation.

    The score of a channel is ``(log sd - median) / max(1.4826 * MAD, 0.15)`` over channels;
    channels beyond ``z_threshold`` (either side) or with ``sd <= flat`` are bad. The floor
    of the spread keeps channels near strong generators (SD within ~2x of the median at the
    default threshold) from being flagged when all channels are equally clean.

    Parameters
    ----------
    data : ndarray, shape (n_channels, n_times)
        Filtered data.
    z_threshold : float
        Robust z-score beyond which a channel is bad.
    flat : float
        Standard deviation at or below which a channel is flat (same unit as ``data``).

    Returns
    -------
    ndarray of int
        Sorted channel indices.
    """
    sd = data.std(axis=1)
    bad = sd <= flat
    logsd = np.log(np.maximum(sd, np.finfo(float).tiny))
    ok = ~bad
    if ok.sum() >= 3:
        med = np.median(logsd[ok])
        spread = max(1.4826 * np.median(np.abs(logsd[ok] - med)), 0.15)
        bad |= ok & (np.abs(logsd - med) / spread > z_threshold)
    return np.flatnonzero(bad)


def fix_bad_channels(raw, *, detect: bool, z_threshold: float, flat_uV: float, mark=(), interpolate: bool = True,
                     path: str | Path = "") -> list[str]:
    """Mark bad EEG channels (given + detected) and interpolate them by spherical splines.

    Returns
    -------
    list of str
        The bad channels.
    """
    eeg = _picks(raw, "eeg")
    names = [raw.ch_names[i] for i in eeg]
    unknown = [c for c in mark if c not in names]
    if unknown:
        raise AppealInputError(f"{path}: bad_channels.mark: not EEG channels of the recording: {', '.join(unknown)}")
    bads = list(mark)
    if detect:
        step = max(1, int(raw.info["sfreq"] // 128))  # the SD needs no more than ~128 samples/s
        data = np.stack([raw.get_data(picks=[i])[0, ::step] for i in eeg])  # one channel copied at a time
        bads += [names[i] for i in robust_bad_channels(data, z_threshold, flat_uV * 1e-6) if names[i] not in bads]
    if len(bads) > len(names) // 2:
        raise AppealInputError(f"{path}: bad_channels: {len(bads)} of {len(names)} EEG channels are bad "
                               "(flat or noisy); check the recording and the montage")
    raw.info["bads"] = bads
    if bads and interpolate:
        raw.interpolate_bads(reset_bads=True, verbose="error")
    return bads


def set_reference(raw, reference, block_s: float = 10.0) -> None:
    """Re-reference EEG in place: ``"average"``, ``"none"`` or a list of channels.

    The same arithmetic as ``raw.set_eeg_reference(reference, projection=False)`` (the mean
    of the reference channels, the good EEG channels for ``"average"``, subtracted from every
    good EEG channel), done in blocks of ``block_s`` seconds so no copy of the whole recording
    is made; MNE then records the custom reference in ``raw.info`` (``set_eeg_reference([])``:
    the data are referenced, MNE adds no projector).
    """
    import mne

    if reference == "none":
        return
    eeg = mne.pick_types(raw.info, eeg=True, exclude="bads")
    if reference == "average":
        ref_from = eeg
    else:
        ref_from = mne.pick_channels(raw.ch_names, list(reference), ordered=True)
    data = raw._data  # preloaded (io.read_recording); MNE's own _apply_reference works on it the same way
    step = max(1, int(block_s * raw.info["sfreq"]))
    for start in range(0, data.shape[1], step):
        block = data[:, start:start + step]  # a view
        block[eeg] -= block[ref_from].mean(axis=0, keepdims=True)
    raw.set_eeg_reference([], projection=False, verbose="error")


def correct_eog(raw, method: str, seed: int = 0) -> dict:
    """Remove eye activity from EEG using the EOG channels, in place.

    ``"regression"``: :class:`mne.preprocessing.EOGRegression` fitted on the continuous
    data. ``"ica"``: :class:`mne.preprocessing.ICA` on a 1 Hz high-passed copy, components
    matching the EOG channels (:meth:`~mne.preprocessing.ICA.find_bads_eog`) removed.

    Returns
    -------
    dict
        What was done (``eog_components`` for ICA).
    """
    import mne

    if method == "regression":
        model = mne.preprocessing.EOGRegression(picks="eeg", picks_artifact="eog").fit(raw)
        model.apply(raw, copy=False)
        return {"eog_method": "regression"}
    fit_raw = raw.copy().filter(1.0, None, picks=["eeg", "eog"], verbose="error")
    ica = mne.preprocessing.ICA(n_components=0.99, random_state=seed, max_iter="auto", verbose="error")
    ica.fit(fit_raw, picks="eeg", decim=max(1, int(raw.info["sfreq"] // 200)), verbose="error")
    idx, _ = ica.find_bads_eog(fit_raw, verbose="error")
    ica.exclude = list(idx)
    ica.apply(raw, verbose="error")
    return {"eog_method": "ica", "eog_components": len(idx)}


def make_epochs(raw, events: np.ndarray, event_id: dict[str, int], tmin: float, tmax: float, baseline,
                peak_to_peak_uV: float | None = None):
    """Epochs around the events with baseline correction (and MNE's peak-to-peak rejection)."""
    import mne

    reject = {"eeg": peak_to_peak_uV * 1e-6} if peak_to_peak_uV else None
    return mne.Epochs(raw, events, event_id, tmin=tmin, tmax=tmax, baseline=None if baseline is None else tuple(baseline),
                      picks=["eeg"], reject=reject, preload=True, on_missing="ignore", reject_by_annotation=True,
                      verbose="error")


def reject_absolute(epochs, threshold_uV: float) -> int:
    """Drop epochs where any EEG sample exceeds ``threshold_uV`` in absolute value (thesis: 120 µV).

    Returns
    -------
    int
        Number of epochs dropped.
    """
    import mne

    data = epochs.get_data(copy=False)  # the preloaded array itself, no copy
    eeg = mne.pick_types(epochs.info, eeg=True, exclude="bads")  # as get_data(picks="eeg"): channels kept bad don't count
    peak = np.concatenate([np.abs(data[i:i + 64][:, eeg]).max(axis=(1, 2)) for i in range(0, len(data), 64)])
    bad = np.flatnonzero(peak > threshold_uV * 1e-6)
    if len(bad):
        epochs.drop(bad, reason=f"ABS {threshold_uV:g} uV", verbose="error")
    return int(len(bad))
