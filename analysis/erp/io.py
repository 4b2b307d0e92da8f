"""Reading recordings (BDF, EDF, FIF, BrainVision, EEGLAB) and their trigger events.

Every problem becomes a one-line :class:`~appeal.errors.AppealInputError` naming the file.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError

__all__ = ["check_edf_size", "read_recording", "find_trigger_events", "select_events"]


def check_edf_size(path: str | Path) -> None:
    """Check that an EDF/BDF file holds as many data records as its header announces.

    Raises
    ------
    AppealInputError
        When the header is unreadable or the file is shorter than announced (truncated).
    """
    path = Path(path)
    bps = 3 if path.suffix.lower() == ".bdf" else 2
    with open(path, "rb") as f:
        head = f.read(256)
        if len(head) < 256:
            raise AppealInputError(f"{path}: truncated: {len(head)} bytes, shorter than the 256-byte EDF/BDF header")
        try:
            header_bytes = int(head[184:192])
            n_records = int(head[236:244])
            n_signals = int(head[252:256])
        except ValueError:
            raise AppealInputError(f"{path}: not an EDF/BDF file (header fields are not numbers)") from None
        f.seek(256 + n_signals * 216)
        raw = f.read(n_signals * 8)
    if len(raw) < n_signals * 8:
        raise AppealInputError(f"{path}: truncated: the signal header of {n_signals} channels is incomplete")
    samples = sum(int(raw[i * 8:(i + 1) * 8]) for i in range(n_signals))
    size = path.stat().st_size
    if n_records > 0:
        expected = header_bytes + n_records * samples * bps
        if size < expected:
            whole = (size - header_bytes) // max(samples * bps, 1)
            raise AppealInputError(
                f"{path}: truncated: header announces {n_records} data records ({expected} bytes) "
                f"but the file has {size} bytes ({max(whole, 0)} complete records)")


def read_recording(path: str | Path):
    """Read a recording into memory with MNE's reader for its format.

    Parameters
    ----------
    path : str | Path
        A ``.bdf``, ``.edf``, ``.fif``, ``.vhdr`` or ``.set`` file.

    Returns
    -------
    mne.io.Raw
        The preloaded recording.

    Raises
    ------
    AppealInputError
        When the file is missing, truncated or unreadable.
    """
    import mne

    path = Path(path)
    if not path.is_file():
        raise AppealInputError(f"{path}: recording not found")
    if path.suffix.lower() in (".bdf", ".edf"):
        check_edf_size(path)
    try:
        if path.suffix.lower() == ".bdf":
            raw = mne.io.read_raw_bdf(path, preload=True, verbose="error")
        else:
            raw = mne.io.read_raw(path, preload=True, verbose="error")
    except Exception as exc:  # noqa: BLE001 - any reader failure is a bad-input report
        msg = f"{type(exc).__name__}: {exc}".splitlines()[0]
        raise AppealInputError(f"{path}: cannot read the recording ({msg})") from None
    if raw.n_times < 2:
        raise AppealInputError(f"{path}: the recording holds no samples")
    return raw


_BV = re.compile(r"(?:Stimulus/)?S\s*(\d+)$")


def find_trigger_events(raw, path: str | Path, stim_channel: str = "auto", mask: int = 0xFFFF) -> np.ndarray:
    """Trigger events ``(sample, 0, code)`` from a stim channel (BioSemi Status) or annotations.

    With a stim channel, onsets are found with :func:`mne.find_events` after keeping the
    bits of ``mask`` (BioSemi puts triggers in the low 16 bits of Status and device state
    in the upper 8), with MNE's defaults otherwise: a code counts when the channel steps
    *up* to it (``consecutive="increasing"``), so a return to a resting value is no event
    (BioSemi's own sample file rests at 254 between its 255 triggers), and the value the
    recording starts with is no event (``initial_event=False``). Only ``shortest_event=1``
    differs from MNE's default 2: a pulse shorter than two samples is still an event,
    where MNE would stop with an error. Without a stim channel, annotations whose
    description is a number (EEGLAB) or a BrainVision ``Stimulus/S 11`` marker give the codes.

    Raises
    ------
    AppealInputError
        When the stim channel named does not exist or no events are found.
    """
    import mne

    path = Path(path)
    stim_names = [raw.ch_names[i] for i in mne.pick_types(raw.info, stim=True)]
    if stim_channel != "auto":
        if stim_channel not in raw.ch_names:
            raise AppealInputError(f"{path}: stim_channel: no channel {stim_channel!r} in the recording "
                                   f"(stim channels: {', '.join(stim_names) or 'none'})")
        stim_names = [stim_channel]
    events = np.zeros((0, 3), int)
    if stim_names:
        events = mne.find_events(raw, stim_channel=stim_names[0], shortest_event=1, mask=mask, mask_type="and",
                                 consecutive="increasing", initial_event=False, verbose="error")
    elif len(raw.annotations):
        rows = []
        for onset, desc in zip(raw.annotations.onset, raw.annotations.description):
            m = _BV.match(desc.strip())
            code = m.group(1) if m else desc.strip()
            if code.isdigit():
                rows.append((raw.time_as_index(onset, use_rounding=True)[0] + raw.first_samp, 0, int(code)))
        events = np.array(rows, int).reshape(-1, 3)
    if len(events) == 0:
        where = f"stim channel {stim_names[0]}" if stim_names else "annotations"
        raise AppealInputError(f"{path}: events: no trigger events found in the {where} "
                               "(expected triggers for the codes in the config's events)")
    return events


def select_events(events: np.ndarray, codes, ignore=(), unknown: str = "error", path: str | Path = "") -> np.ndarray:
    """Keep the events whose code is in ``codes``; other codes are an error unless ignored.

    Parameters
    ----------
    events : ndarray, shape (n, 3)
        MNE events.
    codes : iterable of int
        Codes of interest.
    ignore : iterable of int
        Codes silently dropped.
    unknown : {"error", "ignore"}
        What to do with codes in neither list.
    path : str | Path
        The recording, for messages.

    Raises
    ------
    AppealInputError
        On unknown codes (when ``unknown="error"``) or when no event of interest remains.
    """
    codes = set(int(c) for c in codes)
    ignore = set(int(c) for c in ignore)
    found = events[:, 2]
    strange = sorted(set(found.tolist()) - codes - ignore)
    if strange and unknown == "error":
        counts = ", ".join(f"{c} ({int((found == c).sum())}x)" for c in strange[:8])
        raise AppealInputError(f"{path}: events: unknown trigger codes {counts} "
                               "(expected codes of the event map; list them under ignore_codes or set unknown_codes: ignore)")
    keep = np.isin(found, list(codes))
    if not keep.any():
        raise AppealInputError(f"{path}: events: none of the {len(events)} triggers has a code of the event map "
                               f"(found codes {sorted(set(found.tolist()))[:10]})")
    return events[keep]
