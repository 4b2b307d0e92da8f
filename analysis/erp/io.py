"""Reading recordings (BDF, EDF, FIF, BrainVision, EEGLAB) and their trigger events.

Recordings come from devices and other labs, so they are read as untrusted input: before MNE
opens a file it must be a regular file (never a folder, device or pipe;
:mod:`analysis.erp.file_checks`), an EDF/BDF header must hold what the EDF spec says in every
field MNE uses (:mod:`analysis.erp.edf_header`), and a BrainVision header may only name data and
marker files beside it (:mod:`analysis.erp.brainvision_header`). Every problem becomes one line of
:class:`~appeal.errors.AppealInputError` naming the file, the field and what was expected.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError
from appeal.labels import shown

from analysis.erp.brainvision_header import check_brainvision_files
from analysis.erp.edf_header import TAL_LABELS, EdfHeader, check_edf_size, read_edf_header
from analysis.erp.file_checks import check_regular_file, readable

__all__ = ["EdfHeader", "TAL_LABELS", "read_edf_header", "check_regular_file", "check_edf_size",
           "check_brainvision_files", "check_recording", "read_recording", "find_trigger_events", "select_events"]


def check_recording(path: str | Path) -> None:
    """Check a recording before MNE reads it, as far as its format allows without reading the data.

    Every file must be a regular file (:func:`check_regular_file`); an EDF/BDF file's header,
    size and annotations are checked (:func:`check_edf_size`), a BrainVision header's fields
    and the files it names (:func:`check_brainvision_files`). FIF and EEGLAB files are left to
    MNE's readers.

    Raises
    ------
    AppealInputError
        One line naming the file, the field and what was expected.
    """
    path = Path(path)
    check_regular_file(path)
    suffix = path.suffix.lower()
    with readable(path):
        if suffix in (".bdf", ".edf"):
            check_edf_size(path)
        elif suffix == ".vhdr":
            check_brainvision_files(path)


def read_recording(path: str | Path):
    """Read a recording into memory with MNE's reader for its format.

    The file is checked first (:func:`check_recording`), the channel names MNE read after
    (:func:`analysis.erp.channels.channel_name_problem`).

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
        When the file is missing, not a regular file, truncated, malformed or unreadable (one line).
    """
    import mne

    from analysis.erp.channels import channel_name_problem

    path = Path(path)
    check_recording(path)
    try:
        if path.suffix.lower() == ".bdf":
            raw = mne.io.read_raw_bdf(path, preload=True, verbose="error")
        else:
            raw = mne.io.read_raw(path, preload=True, verbose="error")
    except Exception as exc:  # noqa: BLE001 - any reader failure is a bad-input report
        raise AppealInputError(f"{path}: cannot read the recording ({_reader_error(exc)})") from None
    problem = channel_name_problem(dict(enumerate(raw.ch_names, 1)))
    if problem:
        raise AppealInputError(f"{path}: {problem}")
    if raw.n_times < 2:
        raise AppealInputError(f"{path}: the recording holds no samples")
    return raw


def _reader_error(exc: Exception) -> str:
    """A reader's exception as part of one message line: its type and first line, cut."""
    text = f"{type(exc).__name__}: {exc}".splitlines()[0]
    return text if len(text) <= 200 else text[:197] + "..."


#: A BrainVision stimulus marker (``Stimulus/S 11``) and a bare code (EEGLAB): ASCII digits only
#: (``str.isdigit`` takes ``²``, which ``int`` refuses) and at most 9 of them (an int64 holds them).
_BV = re.compile(r"(?:Stimulus/)?S\s*([0-9]{1,9})", re.ASCII)
_CODE = re.compile(r"[0-9]{1,9}")


def _annotation_code(description) -> int | None:
    """The trigger code an annotation's description gives, or None (any other text)."""
    text = str(description).strip()
    m = _BV.fullmatch(text)
    code = m.group(1) if m else text
    return int(code) if _CODE.fullmatch(code) else None


def _annotation_events(raw) -> np.ndarray:
    """Events ``(sample, 0, code)`` of the annotations that give a code and lie within the recording."""
    ann = raw.annotations
    codes = [_annotation_code(d) for d in ann.description]
    keep = [i for i, c in enumerate(codes) if c is not None]
    if not keep:
        return np.zeros((0, 3), int)
    samples = raw.time_as_index(np.asarray(ann.onset)[keep], use_rounding=True)
    inside = (samples >= 0) & (samples < raw.n_times)
    events = np.column_stack([samples + raw.first_samp, np.zeros(len(keep), int), [codes[i] for i in keep]])
    return events[inside].astype(int)


def _name(channel: str) -> str:
    """A channel name in a message: as it is when plain, else :func:`appeal.labels.shown`."""
    return channel if re.fullmatch(r"[A-Za-z0-9_.-]{1,32}", channel) else shown(channel)


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
    description is a number (EEGLAB) or a BrainVision ``Stimulus/S 11`` marker give the codes
    (ASCII digits, at most 9; any other description, however odd, is no trigger), at the
    annotation's onset when it lies within the recording.

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
            raise AppealInputError(f"{path}: stim_channel: no channel {shown(stim_channel)} in the recording "
                                   f"(stim channels: {', '.join(map(_name, stim_names)) or 'none'})")
        stim_names = [stim_channel]
    events = np.zeros((0, 3), int)
    if stim_names:
        events = mne.find_events(raw, stim_channel=stim_names[0], shortest_event=1, mask=mask, mask_type="and",
                                 consecutive="increasing", initial_event=False, verbose="error")
    elif len(raw.annotations):
        events = _annotation_events(raw)
    if len(events) == 0:
        where = f"stim channel {_name(stim_names[0])}" if stim_names else "annotations"
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
