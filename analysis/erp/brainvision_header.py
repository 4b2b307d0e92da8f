"""BrainVision headers read as untrusted input: the files they name and the fields MNE unpacks.

A header from elsewhere could point MNE at any file, a device or a pipe; it may only name data
and marker files beside it. Every problem is one line of :class:`~appeal.errors.AppealInputError`.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from appeal.errors import AppealInputError
from appeal.labels import shown

from analysis.erp.file_checks import CONTROL, DECIMAL, MAX_SFREQ_HZ, check_regular_file, not_regular

__all__ = ["MAX_TEXT_BYTES", "check_brainvision_files"]

#: The largest BrainVision header or marker file read (bytes; real ones are kilobytes).
MAX_TEXT_BYTES = 16 * 2**20


def _small_text(path: Path, field: str) -> str:
    """A BrainVision text file (bounded in size), decoded as MNE falls back to: Latin-1."""
    check_regular_file(path)
    size = path.stat().st_size
    if size > MAX_TEXT_BYTES:
        raise AppealInputError(f"{path}: {field}: {size} bytes, expected a text file of at most {MAX_TEXT_BYTES} bytes")
    return path.read_bytes().decode("latin-1")


def _bv_value(text: str, key: str) -> str | None:
    """The value of ``key=value`` in a BrainVision header (configparser: any case, ``=`` or ``:``)."""
    m = re.search(rf"^[ \t]*{key}[ \t]*[=:][ \t]*(.*?)[ \t]*\r?$", text, re.MULTILINE | re.IGNORECASE)
    return m.group(1) if m else None


def _check_codepage(path: Path, text: str) -> None:
    """MNE decodes a BrainVision file with its ``Codepage=`` (ANSI: cp1252)."""
    import codecs

    m = re.search("Codepage=(.+)", text)
    name = m.group(1).strip() if m else "utf-8"
    try:
        codecs.lookup("cp1252" if name == "ANSI" else name)
    except LookupError:
        raise AppealInputError(f"{path}: Codepage: expected a text encoding such as UTF-8 or ANSI, got {shown(name)}") from None


def _beside(path: Path, key: str, name: str | None, required: bool) -> Path | None:
    """The file a BrainVision header names under ``key``: a plain name in the header's folder."""
    if name is None or not name:
        if required:
            raise AppealInputError(f"{path}: {key}: missing (expected the name of a file beside the header)")
        return None
    if "/" in name or "\\" in name or name in (".", "..") or CONTROL.search(name):
        raise AppealInputError(f"{path}: {key}: expected the name of a file beside the header (no folders), "
                               f"got {shown(name)}")
    return path.parent / name


def _check_markers(path: Path, text: str) -> None:
    """Each ``MkN=type,description,position,size[,channel[,date]]`` has the fields MNE unpacks."""
    block = re.search(r"\[Marker Infos\]", text, re.IGNORECASE)
    if not block:
        return
    for m in re.finditer(r"^(Mk\d+)=(.*)", text[block.end():], re.MULTILINE):
        parts = m.group(2).rstrip("\r").split(",")
        if len(parts) < 4 or not re.fullmatch(r"\s*[+-]?[0-9]+\s*", parts[2]):
            raise AppealInputError(f"{path}: {m.group(1)}: expected type,description,position,size with a "
                                   f"whole-number position, got {shown(m.group(2))}")


def check_brainvision_files(path: str | Path) -> None:
    """Check a BrainVision header (``.vhdr``) and what it names before MNE reads them.

    ``DataFile`` and ``MarkerFile`` must be plain names of regular files in the header's
    folder (a header from elsewhere could otherwise point MNE at any file, a device or a pipe);
    ``NumberOfChannels`` (1-9999), ``SamplingInterval`` (µs, at most :data:`MAX_SFREQ_HZ`) and
    ``Codepage`` must be readable, and every marker must have the fields MNE unpacks.

    Raises
    ------
    AppealInputError
        One line naming the file and the field.
    """
    path = Path(path)
    text = _small_text(path, "header")
    _check_codepage(path, text)
    data = _beside(path, "DataFile", _bv_value(text, "DataFile"), required=True)
    why = not_regular(data)
    if why:
        raise AppealInputError(f"{path}: DataFile: {shown(data.name)} {why} (expected the recording's data file "
                               "beside the header)")
    n_channels = _bv_value(text, "NumberOfChannels") or ""
    if not (re.fullmatch(r"[0-9]{1,4}", n_channels) and int(n_channels) >= 1):
        raise AppealInputError(f"{path}: NumberOfChannels: expected a whole number from 1 to 9999, got {shown(n_channels)}")
    interval = _bv_value(text, "SamplingInterval") or ""
    if not (DECIMAL.fullmatch(interval) and 1e6 / MAX_SFREQ_HZ <= float(interval) < math.inf):
        raise AppealInputError(f"{path}: SamplingInterval: expected microseconds between samples of at least "
                               f"{1e6 / MAX_SFREQ_HZ:g}, got {shown(interval)}")
    markers = _beside(path, "MarkerFile", _bv_value(text, "MarkerFile"), required=False)
    why = None if markers is None else not_regular(markers)
    if why and why != "not found":  # a missing one: MNE reads the .vmrk beside the header, or no markers
        raise AppealInputError(f"{path}: MarkerFile: {shown(markers.name)} {why} (expected the marker file "
                               "beside the header)")
    if markers is not None and not why:
        marker_text = _small_text(markers, "MarkerFile")
        _check_codepage(markers, marker_text)
        _check_markers(markers, marker_text)
