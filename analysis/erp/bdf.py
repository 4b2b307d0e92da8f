"""A BioSemi Data Format (BDF, 24-bit EDF) writer for simulated recordings.

MNE writes EDF but not BDF; this writes the BioSemi layout: data channels in microvolts with
BioSemi's range (±262144 µV over 24 bits, 1/32 µV steps) and a ``Status`` channel holding
the trigger codes in its low 16 bits.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np

from appeal.atomic import atomic_write_bytes

__all__ = ["write_bdf"]

_DIG_MIN, _DIG_MAX = -8388608, 8388607
_PHYS_UV = 262144.0


def _field(values, width: int) -> bytes:
    out = b""
    for v in values:
        s = str(v)
        if len(s) > width:
            s = s[:width]
        out += s.ljust(width).encode("ascii")
    return out


def _num(x: float) -> str:
    s = f"{x:.8g}"
    return s if len(s) <= 8 else f"{x:.0f}"[:8]


def write_bdf(path: str | Path, data_uV: np.ndarray, ch_names: list[str], sfreq: int, status: np.ndarray,
              *, record_s: int = 1, start: _dt.datetime | None = None, subject: str = "X") -> Path:
    """Write channels (µV) and a Status channel as a BioSemi BDF file.

    Parameters
    ----------
    path : path-like
        The ``.bdf`` file.
    data_uV : ndarray, shape (n_channels, n_times)
        Data channels in microvolts (clipped to ±262144 µV).
    ch_names : list of str
        Labels of the data channels (at most 16 characters each).
    sfreq : int
        Sampling rate in Hz (integer, as BDF needs whole samples per record).
    status : ndarray of int, shape (n_times,)
        Status channel words (trigger codes in bits 0-15).
    record_s : int
        Data-record duration in seconds; the data are cut to whole records.
    start : datetime | None
        Recording start (default 2020-01-01 00:00:00).
    subject : str
        Patient field.

    Returns
    -------
    Path
        ``path``.
    """
    sfreq = int(sfreq)
    spr = sfreq * record_s
    n_ch, n_times = data_uV.shape
    n_rec = n_times // spr
    if n_rec < 1:
        raise ValueError(f"need at least one {record_s}-s record ({spr} samples), got {n_times}")
    n = n_rec * spr
    labels = list(ch_names) + ["Status"]
    ns = n_ch + 1
    start = start or _dt.datetime(2020, 1, 1)
    head = (b"\xffBIOSEMI" + _field([f"{subject}"], 80) + _field(["Startdate simulated by appeal-lab"], 80)
            + _field([start.strftime("%d.%m.%y")], 8) + _field([start.strftime("%H.%M.%S")], 8)
            + _field([256 * (ns + 1)], 8) + _field(["24BIT"], 44) + _field([n_rec], 8) + _field([record_s], 8)
            + _field([ns], 4))
    head += _field(labels, 16)
    head += _field(["Active Electrode"] * n_ch + ["Triggers and Status"], 80)
    head += _field(["uV"] * n_ch + ["Boolean"], 8)
    head += _field([_num(-_PHYS_UV)] * n_ch + [_DIG_MIN], 8)
    head += _field([_num(_PHYS_UV - 1)] * n_ch + [_DIG_MAX], 8)
    head += _field([_DIG_MIN] * ns, 8)
    head += _field([_DIG_MAX] * ns, 8)
    head += _field(["HP:DC; LP:417 Hz"] * n_ch + ["No filtering"], 80)
    head += _field([spr] * ns, 8)
    head += _field([""] * ns, 32)
    assert len(head) == 256 * (ns + 1)
    scale = (_DIG_MAX - _DIG_MIN) / (2 * _PHYS_UV - 1)
    chunks = [head]
    step = max(1, int(2e7 // (ns * spr)))  # records per block, bounded memory
    for r0 in range(0, n_rec, step):
        r1 = min(n_rec, r0 + step)
        a, b = r0 * spr, r1 * spr
        dig = np.empty((ns, b - a), np.int32)
        dig[:n_ch] = np.clip(np.round((np.asarray(data_uV[:, a:b], float) + _PHYS_UV) * scale + _DIG_MIN),
                             _DIG_MIN, _DIG_MAX).astype(np.int32)
        dig[n_ch] = np.asarray(status[a:b], np.int64).astype(np.int32)
        # (channels, records, spr) -> (records, channels, spr) -> 3 little-endian bytes per sample
        block = dig.reshape(ns, r1 - r0, spr).transpose(1, 0, 2).astype("<i4")
        chunks.append(np.ascontiguousarray(block).view(np.uint8).reshape(-1, 4)[:, :3].tobytes())
    return atomic_write_bytes(Path(path), b"".join(chunks))
