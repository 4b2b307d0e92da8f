"""EDF and BDF headers read as untrusted input, against the EDF spec, before MNE opens the file.

An EDF/BDF header must hold what the EDF spec (Kemp et al. 1992; BioSemi's 24-bit BDF) says in
every field MNE uses, within bounds that keep memory and time proportional to the file: a
signal count, header size, sample counts, record duration and digital/physical ranges that are
numbers in range, labels that are printable and distinct, annotations MNE parses in linear time.
Every problem is one line of :class:`~appeal.errors.AppealInputError` naming the file and the field.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError
from appeal.labels import shown

from analysis.erp.file_checks import DECIMAL, MAX_SFREQ_HZ, check_regular_file, readable

__all__ = ["EdfHeader", "TAL_LABELS", "MAX_EXPANSION", "read_edf_header", "check_edf_size"]

#: Labels that MNE reads as EDF+/BDF+ annotation (TAL) signals rather than as data channels.
TAL_LABELS = ("EDF Annotations", "BDF Annotations")
#: MNE holds every data channel at the rate of the fastest one: at most this many samples in
#: memory per sample stored in the file (channels at very different rates would let a small
#: file ask for a huge array; a sleep recording with 100 Hz EEG and 1 Hz sensors needs 2.3).
MAX_EXPANSION = 16
#: The per-signal fields of an EDF/BDF header, in file order, with their widths in bytes.
_SIGNAL_FIELDS = (("label", 16), ("transducer type", 80), ("physical dimension", 8), ("physical minimum", 8),
                  ("physical maximum", 8), ("digital minimum", 8), ("digital maximum", 8), ("prefiltering", 80),
                  ("samples per data record", 8), ("reserved", 32))
#: Digital range of a sample: 16 bits (EDF) or 24 bits (BDF), by bytes per sample.
_DIGITAL_RANGE = {2: (-32768, 32767), 3: (-8388608, 8388607)}
_WHOLE = re.compile(r"[+-]?[0-9]+")
#: EDF+ time-stamped annotation lists (TALs) in zero padding: ``+onset[\x15duration]\x14``, texts
#: each closed by ``\x14`` (no NUL, no line break), then ``\x00``. A file that matches is parsed
#: by MNE's regular expression in linear time; other bytes can make it take hours.
_TALS = re.compile(rb"(?:\x00*[+-][0-9]{1,20}(?:\.[0-9]{0,20})?(?:\x15[0-9]{1,20}(?:\.[0-9]{0,20})?)?"
                   rb"\x14[^\x00\x14\n]*(?:\x14[^\x00\x14\n]*)*\x14\x00)*\x00*")


@dataclass(frozen=True)
class EdfHeader:
    """The fields of an EDF/BDF header that reading depends on, as MNE reads them.

    Attributes
    ----------
    path : Path
        The file.
    bytes_per_sample : int
        2 (EDF) or 3 (BDF).
    header_bytes : int
        Size of the header: 256 x (1 + number of signals).
    n_records : int
        Data records announced (-1: unknown, the recording was not closed).
    record_s : float
        Duration of a data record in seconds.
    labels : tuple of str
        Signal labels (annotation signals included).
    samples : tuple of int
        Samples per data record of each signal.
    """

    path: Path
    bytes_per_sample: int
    header_bytes: int
    n_records: int
    record_s: float
    labels: tuple[str, ...]
    samples: tuple[int, ...]

    @property
    def annotation_signals(self) -> list[int]:
        """Indices of the annotation (TAL) signals."""
        return [i for i, label in enumerate(self.labels) if label in TAL_LABELS]

    @property
    def data_signals(self) -> list[int]:
        """Indices of the signals MNE reads as channels."""
        return [i for i, label in enumerate(self.labels) if label not in TAL_LABELS]

    @property
    def record_bytes(self) -> int:
        """Bytes of one data record."""
        return sum(self.samples) * self.bytes_per_sample


def _got(raw: bytes) -> str:
    """A header field's bytes as a message shows them."""
    text = raw.decode("latin-1").strip(" ")
    return shown(text) if text else "a blank field"


def _text(raw: bytes) -> str:
    """A numeric header field as MNE reads it: up to the first NUL, Latin-1, blanks stripped."""
    return raw.split(b"\x00")[0].decode("latin-1").strip()


def _whole(path: Path, field: str, raw: bytes, lo: int, hi: int, expected: str | None = None) -> int:
    """A whole-number header field from ``lo`` to ``hi``, else a one-line error."""
    text = _text(raw)
    if _WHOLE.fullmatch(text) and lo <= int(text) <= hi:
        return int(text)
    raise AppealInputError(f"{path}: {field}: expected {expected or f'a whole number from {lo} to {hi}'}, "
                           f"got {_got(raw)}")


def _decimal(path: Path, field: str, raw: bytes, expected: str, comma: bool = True) -> float:
    """A decimal header field, no larger than 8 digits can write (an exponent could reach 1e308);
    MNE takes a comma for the point in some fields. Else a one-line error."""
    text = _text(raw).replace(",", ".") if comma else _text(raw)
    value = float(text) if DECIMAL.fullmatch(text) else math.nan
    if abs(value) <= 99_999_999:
        return value
    raise AppealInputError(f"{path}: {field}: expected {expected}, got {_got(raw)}")


def _check_version(path: Path, raw: bytes) -> None:
    """The version field: ``\\xffBIOSEMI`` in a ``.bdf``, ``0`` in a ``.edf`` file."""
    bdf = path.suffix.lower() == ".bdf"
    edf_version = raw.rstrip(b" \x00") == b"0"
    if (raw == b"\xffBIOSEMI") if bdf else edf_version:
        return
    if bdf and edf_version:
        hint = "; an EDF file, with 16-bit samples: name it .edf"
    elif not bdf and raw == b"\xffBIOSEMI":
        hint = "; a BDF file, with 24-bit samples: name it .bdf"
    else:
        hint = "; not an EDF/BDF file"
    want = "'\\xffBIOSEMI' (BDF)" if bdf else "'0' (EDF)"
    raise AppealInputError(f"{path}: version (first 8 bytes): expected {want}, got {shown(raw.decode('latin-1'))}{hint}")


def _check_identification(path: Path, head: bytes) -> None:
    """Patient subfields and start time that MNE's reader would stop on (with an unnamed error)."""
    extra = head[8:88].decode("latin-1").rstrip().split(" ")[4:]
    several = [part for part in extra if part.count("=") > 1]
    if several:
        raise AppealInputError(f"{path}: local patient identification: subfield {shown(several[0])} holds "
                               "several '=' (expected key=value subfields)")
    try:
        hms = [int(x) for x in head[176:184].decode("latin-1").split(".")]
    except ValueError:
        return  # not a time at all: MNE reads no time of day
    if len(hms) == 3 and not (0 <= hms[0] <= 23 and 0 <= hms[1] <= 59 and 0 <= hms[2] <= 59):
        raise AppealInputError(f"{path}: starttime of recording: expected hh.mm.ss, got {_got(head[176:184])}")


def _signal_fields(block: bytes, n: int) -> dict[str, list[bytes]]:
    """The signal header split into its fields: name -> one ``bytes`` per signal."""
    out, at = {}, 0
    for name, width in _SIGNAL_FIELDS:
        out[name] = [block[at + i * width:at + (i + 1) * width] for i in range(n)]
        at += n * width
    return out


def _check_labels(path: Path, labels: list[str]) -> None:
    """Labels MNE would mangle, or the pipeline could not tell apart or show, are refused."""
    from analysis.erp.channels import channel_name_problem

    data = {i: label for i, label in enumerate(labels, 1) if label not in TAL_LABELS}
    if not data:
        raise AppealInputError(f"{path}: number of signals: all {len(labels)} signals are annotation signals "
                               f"({TAL_LABELS[0]}), expected at least one data channel")
    problem = channel_name_problem(data, "signal")
    if problem:
        raise AppealInputError(f"{path}: {problem}")
    if "auto" in labels:  # MNE's reader stops with an UnboundLocalError on a channel called auto
        raise AppealInputError(f"{path}: label of signal {labels.index('auto') + 1}: expected a channel name "
                               "other than 'auto' (MNE's EDF reader cannot read a channel called auto)")


def _check_signal(path: Path, i: int, label: str, fields: dict[str, list[bytes]], bps: int) -> int:
    """The numeric fields of signal ``i`` (0-based); returns its samples per data record."""
    where = f"of signal {i + 1} ({shown(label)})"
    number = "a decimal number of at most 8 digits"
    pmin = _decimal(path, f"physical minimum {where}", fields["physical minimum"][i], number)
    pmax = _decimal(path, f"physical maximum {where}", fields["physical maximum"][i], number)
    if pmax == pmin:
        raise AppealInputError(f"{path}: physical maximum {where}: expected a value other than the physical "
                               f"minimum {pmin:g}, got {_got(fields['physical maximum'][i])}")
    lo, hi = _DIGITAL_RANGE[bps]
    span = f"a whole number from {lo} to {hi} ({8 * bps}-bit samples)"
    dmin = _decimal(path, f"digital minimum {where}", fields["digital minimum"][i], span)
    dmax = _decimal(path, f"digital maximum {where}", fields["digital maximum"][i], span)
    for name, value in (("digital minimum", dmin), ("digital maximum", dmax)):
        if not (lo <= value <= hi and value == int(value)):
            raise AppealInputError(f"{path}: {name} {where}: expected {span}, got {_got(fields[name][i])}")
    if dmax <= dmin:
        raise AppealInputError(f"{path}: digital maximum {where}: expected more than the digital minimum "
                               f"{dmin:.0f}, got {_got(fields['digital maximum'][i])}")
    return _whole(path, f"samples per data record {where}", fields["samples per data record"][i], 1, 99_999_999,
                  "a whole number of at least 1")


def _check_reserved(path: Path, fields: dict[str, list[bytes]], labels: list[str]) -> None:
    """MNE decodes the signals' reserved fields as UTF-8."""
    block = b"".join(fields["reserved"])
    try:
        block.decode("utf-8")
    except UnicodeDecodeError as exc:
        i = exc.start // 32
        raise AppealInputError(f"{path}: reserved field of signal {i + 1} ({shown(labels[i])}): expected ASCII "
                               f"text or blanks, got {_got(fields['reserved'][i])}") from None


def read_edf_header(path: str | Path) -> EdfHeader:
    """Read and check an EDF/BDF header: every field MNE's reader uses, against the EDF spec.

    Checked: the version (``0`` for EDF, ``\\xffBIOSEMI`` for BDF: the suffix decides the
    sample width), the number of signals (1-9999), the header size (256 bytes per signal plus
    256), the number of data records (at least 1, or -1: unknown), the record duration (a
    positive number of seconds), each signal's label (see
    :func:`analysis.erp.channels.channel_name_problem`), physical and digital range (numbers,
    a non-empty range within the sample width) and samples per record (at least 1), the
    reserved fields (UTF-8), and the patient subfields and start time MNE parses.

    Parameters
    ----------
    path : str | Path
        A ``.bdf`` or ``.edf`` file.

    Returns
    -------
    EdfHeader
        The fields the size and memory checks need.

    Raises
    ------
    AppealInputError
        One line naming the file, the field and what was expected.
    """
    path = Path(path)
    check_regular_file(path)
    bps = 3 if path.suffix.lower() == ".bdf" else 2
    with open(path, "rb") as f:
        head = f.read(256)
        if len(head) >= 8:  # a short file of another kind is no EDF/BDF file rather than a truncated one
            _check_version(path, head[:8])
        if len(head) < 256:
            raise AppealInputError(f"{path}: truncated: {len(head)} bytes, shorter than the 256-byte EDF/BDF header")
        n = _whole(path, "number of signals", head[252:256], 1, 9999)
        block = f.read(256 * n)
    header_bytes = _whole(path, "number of bytes in header record", head[184:192], 0, 99_999_999)
    if header_bytes != 256 * (n + 1):
        raise AppealInputError(f"{path}: number of bytes in header record: expected 256 x (1 + {n} signals) = "
                               f"{256 * (n + 1)}, got {_got(head[184:192])}")
    n_records = _whole(path, "number of data records", head[236:244], -1, 99_999_999,
                       "a whole number of at least 1 (or -1: unknown)")
    if n_records == 0:
        raise AppealInputError(f"{path}: number of data records: expected at least 1 (or -1: unknown), got '0' "
                               "(the recording holds no data)")
    record_s = _decimal(path, "duration of a data record", head[244:252], "a positive number of seconds", comma=False)
    if record_s <= 0:
        raise AppealInputError(f"{path}: duration of a data record: expected a positive number of seconds, "
                               f"got {_got(head[244:252])}")
    if len(block) < 256 * n:
        raise AppealInputError(f"{path}: truncated: the signal header of {n} channels is incomplete")
    fields = _signal_fields(block, n)
    labels = [raw.strip().decode("latin-1") for raw in fields["label"]]  # as MNE: no NUL split
    _check_labels(path, labels)
    samples = tuple(_check_signal(path, i, labels[i], fields, bps) for i in range(n))
    _check_reserved(path, fields, labels)
    _check_identification(path, head)
    return EdfHeader(path, bps, header_bytes, n_records, record_s, tuple(labels), samples)


def _records_in_file(header: EdfHeader) -> int:
    """Whole data records in the file (MNE reads them all); refuses a file shorter than announced."""
    path, per = header.path, header.record_bytes
    size = path.stat().st_size
    whole = max(size - header.header_bytes, 0) // per
    if header.n_records > 0 and whole < header.n_records:
        expected = header.header_bytes + header.n_records * per
        raise AppealInputError(
            f"{path}: truncated: header announces {header.n_records} data records ({expected} bytes) "
            f"but the file has {size} bytes ({whole} complete records)")
    if whole < 1:
        raise AppealInputError(f"{path}: truncated: the number of data records is unknown (-1) and the file holds "
                               f"no complete one ({size - header.header_bytes} data bytes, a record takes {per})")
    return whole


def _check_rates(header: EdfHeader) -> None:
    """Sampling rates and the memory MNE needs (every channel at the fastest rate) stay bounded."""
    path, data = header.path, header.data_signals
    for i in data:
        rate = header.samples[i] / header.record_s
        if rate > MAX_SFREQ_HZ:
            raise AppealInputError(
                f"{path}: duration of a data record: signal {i + 1} ({shown(header.labels[i])}) would be sampled at "
                f"{rate:.6g} Hz ({header.samples[i]} samples in {header.record_s:g} s), expected at most "
                f"{MAX_SFREQ_HZ:g} Hz")
    held = len(data) * max(header.samples[i] for i in data)
    if held > MAX_EXPANSION * sum(header.samples):
        raise AppealInputError(
            f"{path}: samples per data record: reading would hold {held} samples per record, "
            f"{held / sum(header.samples):.0f} times the {sum(header.samples)} the file stores (MNE samples every "
            f"channel at the fastest rate), expected at most {MAX_EXPANSION} times (channels at comparable rates)")


def _check_annotations(header: EdfHeader, n_records: int) -> None:
    """EDF+ annotation signals hold well-formed TALs, in UTF-8, each within its data record.

    MNE finds the TALs with a regular expression over all records at once: malformed bytes
    can make that take hours (a megabyte of ``+1\\x14``), and bytes that are not UTF-8 stop it.
    """
    starts = np.cumsum([0, *header.samples]) * header.bytes_per_sample
    data = np.memmap(header.path, np.uint8, "r", offset=header.header_bytes, shape=(n_records, header.record_bytes))
    for i in header.annotation_signals:
        rows = np.ascontiguousarray(data[:, starts[i]:starts[i + 1]])
        problem = _tal_problem(rows)
        if problem:
            record, at, why = problem
            got = rows[record, at:at + 24].tobytes().decode("latin-1")
            raise AppealInputError(
                f"{header.path}: annotations in data record {record + 1} of signal {i + 1} "
                f"({shown(header.labels[i])}): {why} (expected EDF+ TALs: +onset, texts each closed by \\x14, "
                f"\\x00 at the end), got {shown(got)}")


def _tal_problem(rows: np.ndarray) -> tuple[int, int, str] | None:
    """The first malformed record of one annotation signal, ``(record, byte, why)``, or None.

    Each record's bytes (one row) must be zero, or TALs closed by ``\\x14\\x00`` and zero
    padding: then no TAL spans two records, whatever order MNE joins them in.
    """
    width = rows.shape[1]
    nonzero = rows != 0
    last = width - 1 - np.argmax(nonzero[:, ::-1], axis=1)
    closed = (rows[np.arange(len(rows)), last] == 0x14) & (last < width - 1)
    unclosed = np.flatnonzero(nonzero.any(axis=1) & ~closed)
    if len(unclosed):
        record = int(unclosed[0])
        return record, max(int(last[record]) - 20, 0), "a record not closed by \\x14\\x00 and zero padding"
    buf = rows.tobytes()
    end = _TALS.match(buf).end()
    if end < len(buf):
        return end // width, end % width, "bytes that are no TAL"
    try:
        buf.decode("utf-8")
    except UnicodeDecodeError as exc:
        return exc.start // width, exc.start % width, "text that is not UTF-8"
    return None


def check_edf_size(path: str | Path) -> None:
    """Check an EDF/BDF file before MNE reads it: its header, its size and its annotations.

    The header's fields are checked by :func:`read_edf_header`. The file must hold as many
    data records as the header announces (when it announces -1, unknown, at least one); MNE
    reads every whole record the file holds. The channels' sampling rates must not make MNE
    hold more than :data:`MAX_EXPANSION` samples per stored sample, nor exceed
    :data:`MAX_SFREQ_HZ`. Annotation signals (EDF+/BDF+ TALs) must be well formed UTF-8.

    Raises
    ------
    AppealInputError
        When the header is unreadable or breaks the spec, the file is shorter than announced
        (truncated), or the annotations are malformed.
    """
    with readable(Path(path)):
        header = read_edf_header(path)
        n_records = _records_in_file(header)
        _check_rates(header)
        _check_annotations(header, n_records)
