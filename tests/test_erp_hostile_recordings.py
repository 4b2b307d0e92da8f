"""EEG recordings as untrusted input: every malformed or odd file is read correctly or refused
with one line naming the file, the field and what was expected (issue 47).

The corpus is built in tmp_path from a small valid BDF written by :func:`analysis.erp.bdf.write_bdf`
(or from the real BioSemi sample in shared/data) by changing bytes where the EDF spec puts each
field; what MNE itself does with each is noted where it matters (MNE 1.13: ``n_signals = -1``
raises "read length must be non-negative", a wrong header size an empty AssertionError, a channel
called ``auto`` an UnboundLocalError, ``samples = 0`` or ``duration = nan`` silently misread).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from cli_errors import one_line_error
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_erp_io import small  # noqa: F401 - a fixture: one simulated subject and its config

from analysis.erp.bdf import write_bdf
from analysis.erp.config import subject_id
from analysis.erp.io import check_edf_size, find_trigger_events, read_recording
from appeal.errors import AppealInputError
from appeal_cli import main

LABELS = ["Fp1", "Fp2", "Cz", "Oz"]  # + Status: 5 signals, header 1536 bytes
SFREQ = 128

#: EDF main-header fields: offset, width (Kemp et al. 1992).
MAIN = {"version": (0, 8), "patient": (8, 80), "recording": (88, 80), "startdate": (168, 8), "starttime": (176, 8),
        "header_bytes": (184, 8), "reserved": (192, 44), "n_records": (236, 8), "duration": (244, 8),
        "n_signals": (252, 4)}
#: Per-signal fields in file order and their widths.
SIGNAL = [("label", 16), ("transducer", 80), ("dimension", 8), ("physical_min", 8), ("physical_max", 8),
          ("digital_min", 8), ("digital_max", 8), ("prefiltering", 80), ("samples", 8), ("reserved", 32)]


def valid_bdf(path: Path, labels=LABELS, n_records: int = 2, sfreq: int = SFREQ) -> Path:
    """A small valid BDF: ``labels`` + Status, triggers 11 and 12, ``n_records`` 1-s records."""
    n = n_records * sfreq
    status = np.zeros(n, int)
    status[40:42], status[150:152] = 11, 12
    data = np.random.default_rng(0).normal(0, 10, (len(labels), n))
    return write_bdf(path, data, list(labels), sfreq, status)


def n_signals_of(path: Path) -> int:
    return int(path.read_bytes()[252:256])


def signal_offset(n_signals: int, field: str, i: int) -> tuple[int, int]:
    """Offset and width of ``field`` of signal ``i`` (0-based)."""
    at = 256
    for name, width in SIGNAL:
        if name == field:
            return at + i * width, width
        at += n_signals * width
    raise KeyError(field)


def put(path: Path, offset: int, width: int, value: bytes) -> Path:
    """Write ``value`` (space-padded to ``width``) at ``offset``."""
    raw = bytearray(path.read_bytes())
    raw[offset:offset + width] = value.ljust(width, b" ")[:width]
    path.write_bytes(bytes(raw))
    return path


def put_main(path: Path, field: str, value: bytes) -> Path:
    return put(path, *MAIN[field], value)


def put_signal(path: Path, field: str, i: int, value: bytes) -> Path:
    return put(path, *signal_offset(n_signals_of(path), field, i), value)


def refusal(path: Path, *needles: str, named: str | None = None) -> str:
    """``read_recording(path)`` raises one line naming the file (``named``: the file at fault, when
    another) and every needle; return it."""
    with pytest.raises(AppealInputError) as err:
        read_recording(path)
    assert len(err.value.lines) == 1, err.value.lines
    line = err.value.lines[0]
    assert "\n" not in str(err.value) and "\x1b" not in line and len(line) < 600, line
    assert (named or path.name) in line, line
    for needle in needles:
        assert needle in line, line
    return line


# --------------------------------------------------------------------------- the header's numbers
MAIN_CASES = {
    # n_signals: MNE f.read(-8)s the whole file for -1; 0 gives an empty AssertionError
    "n_signals -1": ("n_signals", b"-1", "number of signals"),
    "n_signals 0": ("n_signals", b"0", "number of signals"),
    "n_signals blank": ("n_signals", b"", "number of signals: expected a whole number from 1 to 9999, got a blank"),
    "n_signals not ascii": ("n_signals", b"\xb2\xb3", "number of signals"),
    "n_signals text": ("n_signals", b"five", "number of signals"),
    "n_signals huge": ("n_signals", b"9999", "number of bytes in header record: expected 256 x (1 + 9999 signals)"),
    "header_bytes wrong": ("header_bytes", b"1000",
                           "number of bytes in header record: expected 256 x (1 + 5 signals) = 1536, got '1000'"),
    "header_bytes negative": ("header_bytes", b"-1536", "number of bytes in header record"),
    "header_bytes garbled": ("header_bytes", b"\x00\x01abc", "number of bytes in header record"),
    "n_records zero": ("n_records", b"0", "number of data records: expected at least 1 (or -1: unknown)"),
    "n_records -5": ("n_records", b"-5", "number of data records"),
    "n_records underscore": ("n_records", b"1_0", "number of data records"),  # int('1_0') == 10
    "n_records huge": ("n_records", b"99999999", "truncated: header announces 99999999 data records"),
    "duration zero": ("duration", b"0", "duration of a data record: expected a positive number of seconds"),
    "duration negative": ("duration", b"-1", "duration of a data record"),  # MNE: sfreq -128
    "duration nan": ("duration", b"nan", "duration of a data record"),  # MNE: sfreq nan
    "duration inf": ("duration", b"inf", "duration of a data record"),
    "duration comma": ("duration", b"0,5", "duration of a data record"),  # MNE: ValueError
    "duration exponent": ("duration", b"1e999", "duration of a data record"),
    "duration tiny": ("duration", b"1e-9", "would be sampled at 1.28e+11 Hz"),
    "version garbage": ("version", b"GARBAGE!", "version (first 8 bytes): expected '\\xffBIOSEMI' (BDF)"),
    "version of EDF": ("version", b"0", "name it .edf"),
    "patient key=value=": ("patient", b"X M 01-JAN-2000 name a=b=c", "local patient identification"),
    "starttime 25h": ("starttime", b"25.61.61", "starttime of recording: expected hh.mm.ss"),
}


@pytest.mark.parametrize("case", sorted(MAIN_CASES))
def test_main_header_field_refused(tmp_path, case):
    field, value, needle = MAIN_CASES[case]
    path = put_main(valid_bdf(tmp_path / "x.bdf"), field, value)
    refusal(path, needle)


SIGNAL_CASES = {
    "samples 0": ("samples", b"0", "samples per data record of signal 1 ('Fp1'): expected a whole number of at least 1"),
    "samples -5": ("samples", b"-5", "samples per data record of signal 1"),  # MNE misreads silently
    "samples garbled": ("samples", b"x\xff", "samples per data record of signal 1"),  # MNE: ValueError
    "samples blank": ("samples", b"", "samples per data record of signal 1"),
    "physical min text": ("physical_min", b"abc", "physical minimum of signal 1"),
    "physical min nan": ("physical_min", b"nan", "physical minimum of signal 1"),  # MNE: all-NaN channel
    "physical min 1e308": ("physical_min", b"-1e308", "physical minimum of signal 1"),
    "physical max = min": ("physical_max", b"-262144", "physical maximum of signal 1"),
    "digital min beyond 24 bits": ("digital_min", b"-9999999", "digital minimum of signal 1"),
    "digital max <= min": ("digital_max", b"-8388608", "digital maximum of signal 1"),
    "reserved not utf-8": ("reserved", b"\xff\xfe", "reserved field of signal 1"),  # MNE: UnicodeDecodeError
}


@pytest.mark.parametrize("case", sorted(SIGNAL_CASES))
def test_signal_header_field_refused(tmp_path, case):
    field, value, needle = SIGNAL_CASES[case]
    path = put_signal(valid_bdf(tmp_path / "x.bdf"), field, 0, value)
    refusal(path, needle)


def test_unknown_record_count_reads_every_record(tmp_path):
    """-1 (the recording was not closed): MNE counts the records from the file size, and so do we."""
    ok = read_recording(valid_bdf(tmp_path / "ok.bdf"))
    path = put_main(valid_bdf(tmp_path / "open.bdf"), "n_records", b"-1")
    raw = read_recording(path)
    assert raw.n_times == ok.n_times == 2 * SFREQ and np.array_equal(raw.get_data(), ok.get_data())
    # -1 and not one whole record: truncated
    header_only = tmp_path / "empty.bdf"
    header_only.write_bytes(path.read_bytes()[:1536 + 100])
    refusal(header_only, "truncated: the number of data records is unknown (-1)")


def test_real_sample_header_changes(shared_data, tmp_path):
    """The real BioSemi file: an unknown record count reads the same data; an odd label is a name;
    a cut file is refused."""
    real = shared_data / "eeg/biosemi/test_bdf_stim_channel.bdf"
    want = read_recording(real)
    copy = tmp_path / "stim.bdf"
    copy.write_bytes(real.read_bytes())
    put_main(copy, "n_records", b"-1")
    put_signal(copy, "label", 0, b'=HYPERLINK("x")')
    raw = read_recording(copy)
    assert raw.ch_names[0] == '=HYPERLINK("x")' and np.array_equal(raw.get_data(), want.get_data())
    assert np.array_equal(find_trigger_events(raw, copy), find_trigger_events(want, real))
    cut = tmp_path / "cut.bdf"
    cut.write_bytes(real.read_bytes()[:30_000])
    refusal(cut, "truncated: header announces 10 data records")


def test_rates_that_would_blow_up_memory(tmp_path):
    """Channel rates far apart: MNE upsamples all to the fastest (40 x the file's samples here)."""
    labels = [f"E{k}" for k in range(40)]
    path = valid_bdf(tmp_path / "x.bdf", labels, n_records=1)
    total = 41 * SFREQ
    put_signal(path, "samples", 0, str(total - 40).encode())
    for i in range(1, 41):
        put_signal(path, "samples", i, b"1")
    refusal(path, "samples per data record: reading would hold", "expected at most 16 times")


# --------------------------------------------------------------------------- channel labels
LABEL_REFUSED = {
    "escape": (b"\x1b[31mX", "label of signal 1: expected printable text, got '\\x1b[31mX'"),
    "tab": (b"A\tB", "label of signal 1: expected printable text"),
    "NUL padding": (b"Fp1\x00\x00\x00", "label of signal 1: expected printable text"),  # MNE keeps the NULs
    "C1 control": (b"A\x9b2J", "label of signal 1: expected printable text"),  # 8-bit CSI
    "utf-8 bytes": ("Fp\u20ac".encode(), "label of signal 1: expected printable text"),  # latin-1: 'Fpâ\x82¬'
    "empty": (b"", "label of signal 1: expected a channel name, got an empty label"),  # MNE: '-0', '-1'
    "duplicate": (b"Fp2", "labels of signals 1 and 2: expected each channel name once"),  # MNE: Fp2-0, Fp2-1
    "duplicate but case": (b"FP2", "labels of signals 1 and 2"),
    "second status": (b"status", "labels of signals 1 and 5"),  # MNE takes this one as the trigger channel
    "auto": (b"auto", "label of signal 1: expected a channel name other than 'auto'"),  # MNE: UnboundLocalError
}


@pytest.mark.parametrize("case", sorted(LABEL_REFUSED))
def test_label_refused(tmp_path, case):
    value, needle = LABEL_REFUSED[case]
    path = valid_bdf(tmp_path / "x.bdf")
    put_signal(path, "label", 0, value)
    if case == "empty":
        put_signal(path, "label", 1, b"")
    refusal(path, needle)


LABEL_READ = {
    "latin-1": (b"Fp\xe91", "Fp\xe91"),
    "formula": (b'=HYPERLINK("x")', '=HYPERLINK("x")'),
    "plus": (b"+cmd", "+cmd"),
    "minus": (b"-x", "-x"),
    "at": (b"@x", "@x"),
    "16 characters": (b"ABCDEFGHIJKLMNOP", "ABCDEFGHIJKLMNOP"),
    "leading blanks": (b"   Fp1", "Fp1"),
}


@pytest.mark.parametrize("case", sorted(LABEL_READ))
def test_label_read_as_it_is(tmp_path, case):
    value, name = LABEL_READ[case]
    path = put_signal(valid_bdf(tmp_path / "x.bdf"), "label", 0, value)
    raw = read_recording(path)
    assert raw.ch_names == [name, *LABELS[1:], "Status"]
    assert find_trigger_events(raw, path)[:, 2].tolist() == [11, 12]


def test_all_signals_annotations(tmp_path):
    path = valid_bdf(tmp_path / "x.bdf")
    for i in range(5):
        put_signal(path, "label", i, b"BDF Annotations")
    refusal(path, "number of signals: all 5 signals are annotation signals")


# --------------------------------------------------------------------------- not a recording at all
def test_files_that_are_no_recording(tmp_path):
    from PIL import Image

    empty = tmp_path / "empty.bdf"
    empty.write_bytes(b"")
    refusal(empty, "truncated: 0 bytes, shorter than the 256-byte EDF/BDF header")
    noise = tmp_path / "noise.bdf"
    noise.write_bytes(np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    refusal(noise, "version (first 8 bytes)", "not an EDF/BDF file")
    png = tmp_path / "face.bdf"
    Image.new("RGB", (64, 64), (200, 150, 120)).save(png, format="PNG")
    refusal(png, "version (first 8 bytes): expected '\\xffBIOSEMI' (BDF), got '\\x89PNG", "not an EDF/BDF file")
    bdf_as_edf = tmp_path / "x.edf"
    bdf_as_edf.write_bytes(valid_bdf(tmp_path / "y.bdf").read_bytes())
    refusal(bdf_as_edf, "version (first 8 bytes): expected '0' (EDF)", "name it .bdf")
    folder = tmp_path / "sub-01_eeg.bdf"
    folder.mkdir()
    refusal(folder, "is a folder, not a file")
    header = valid_bdf(tmp_path / "z.bdf").read_bytes()
    for name, size, needle in [("head.bdf", 100, "truncated: 100 bytes"),
                               ("signals.bdf", 600, "truncated: the signal header of 5 channels is incomplete"),
                               ("data.bdf", 4000, "truncated: header announces 2 data records")]:
        (tmp_path / name).write_bytes(header[:size])
        refusal(tmp_path / name, needle)


def test_devices_and_pipes_are_not_read(tmp_path):
    """A link to /dev/zero would read forever and a pipe would wait for a writer: both refused at once."""
    zero = tmp_path / "zero.bdf"
    zero.symlink_to("/dev/zero")
    pipe = tmp_path / "pipe.bdf"
    os.mkfifo(pipe)
    start = time.monotonic()
    refusal(zero, "is a device, pipe or socket, not a regular file")
    refusal(pipe, "is a device, pipe or socket, not a regular file")
    with pytest.raises(AppealInputError, match="not a regular file"):
        check_edf_size(zero)
    assert time.monotonic() - start < 10


# --------------------------------------------------------------------------- EDF+/BDF+ annotations
def annotated_bdf(path: Path, records: list[bytes], sfreq: int = SFREQ) -> Path:
    """A BDF whose Status signal is relabelled 'BDF Annotations' and holds ``records[r]`` (zero-padded
    TAL bytes) in data record ``r``: events then come from the annotations."""
    valid_bdf(path, ["Cz", "Oz"], n_records=len(records), sfreq=sfreq)
    put_signal(path, "label", 2, b"BDF Annotations")
    raw = bytearray(path.read_bytes())
    width = 3 * sfreq
    for r, tal in enumerate(records):
        at = 256 * 4 + r * 3 * width + 2 * width
        raw[at:at + width] = tal.ljust(width, b"\x00")
    path.write_bytes(bytes(raw))
    return path


def test_odd_annotation_descriptions_are_no_triggers(tmp_path):
    """Only ASCII codes count; '²' (isdigit, but int() fails), Arabic-Indic digits, a 20-digit number,
    formulas and escapes are descriptions, not triggers, and crash nothing."""
    odd = ["\u00b2", "\u0661\u0662", "99999999999999999999", '=HYPERLINK("x")', "\x1b[31m", "Stimulus/S\u0663"]
    tals = [b"+0\x14\x14\x00+0.5\x14Stimulus/S  7\x14\x00",
            b"+1\x14\x14\x00" + b"".join(f"+1.{k}\x14{d}\x14\x00".encode() for k, d in enumerate(odd)),
            b"+2\x14\x14\x00+2.5\x1512\x1412\x14\x00+9999\x1413\x14\x00"]  # the last lies after the end
    path = annotated_bdf(tmp_path / "ann.bdf", tals)
    raw = read_recording(path)
    assert [d for d in raw.annotations.description] == ["Stimulus/S  7", *odd, "12"]
    events = find_trigger_events(raw, path)
    assert events.tolist() == [[64, 0, 7], [320, 0, 12]]


TAL_REFUSED = {
    "line break": ([b"+0\x14\x14\x00+0.5\x14a\nb\x14\x00"], "bytes that are no TAL"),  # MNE drops the TAL
    "not closed": ([b"+0\x14\x14\x00+0.5\x14abc"], "a record not closed by"),
    "not utf-8": ([b"+0\x14\x14\x00+0.5\x14\xff\xfe\x14\x00"], "text that is not UTF-8"),  # MNE: bare Exception
    "no text": ([b"+0\x14\x14\x00+0.5\x14\x00"], "bytes that are no TAL"),
    "garbage": ([b"xyz\x14\x00"], "bytes that are no TAL"),
}


@pytest.mark.parametrize("case", sorted(TAL_REFUSED))
def test_malformed_annotations_refused(tmp_path, case):
    records, needle = TAL_REFUSED[case]
    path = annotated_bdf(tmp_path / "ann.bdf", records + [b""])
    refusal(path, "annotations in data record 1 of signal 3 ('BDF Annotations')", needle)


def test_annotations_that_would_take_mne_hours(tmp_path):
    """MNE's TAL expression scans from every '+1\\x14' to the end when no TAL is closed: 100 kB of
    them took 17 s, these 1.2 MB would take about 40 min. Refused at once; a valid file as large reads
    in seconds."""
    width = 3 * 4096
    hostile = annotated_bdf(tmp_path / "hostile.bdf", [b"+1\x14" * (width // 3)] * 100, sfreq=4096)
    start = time.monotonic()
    refusal(hostile, "annotations in data record 1", "a record not closed by")
    assert time.monotonic() - start < 10
    many = [b"".join(b"+%d.%03d\x14S  1\x14\x00" % (r, k) for k in range(300)) for r in range(20)]
    raw = read_recording(annotated_bdf(tmp_path / "many.bdf", many, sfreq=4096))
    assert len(raw.annotations) == 20 * 300


# --------------------------------------------------------------------------- BrainVision
def brainvision(folder: Path, markers: list[str], data_file: str = "rec.eeg", common: str = "") -> Path:
    """A two-channel BrainVision recording (float32, 256 Hz, 2 s) with ``MkN=`` marker lines."""
    folder.mkdir(parents=True, exist_ok=True)
    np.random.default_rng(0).normal(0, 10, (512, 2)).astype("<f4").tofile(folder / "rec.eeg")
    settings_ = {"Codepage": "UTF-8", "DataFile": data_file, "MarkerFile": "rec.vmrk", "DataFormat": "BINARY",
                 "DataOrientation": "MULTIPLEXED", "NumberOfChannels": "2", "SamplingInterval": "3906.25"}
    settings_.update(dict(line.split("=", 1) for line in common.splitlines() if line))
    (folder / "rec.vhdr").write_text(
        "Brain Vision Data Exchange Header File Version 1.0\n[Common Infos]\n"
        + "".join(f"{k}={v}\n" for k, v in settings_.items())
        + "[Binary Infos]\nBinaryFormat=IEEE_FLOAT_32\n[Channel Infos]\nCh1=Cz,,0.1,µV\nCh2=Oz,,0.1,µV\n")
    (folder / "rec.vmrk").write_text(
        "Brain Vision Data Exchange Marker File, Version 1.0\n[Common Infos]\nCodepage=UTF-8\nDataFile=rec.eeg\n"
        "[Marker Infos]\n" + "".join(f"Mk{i}={m}\n" for i, m in enumerate(markers, 1)), encoding="utf-8")
    return folder / "rec.vhdr"


def test_brainvision_odd_marker_descriptions(tmp_path):
    odd = ["S\u00b2", "S\u0661\u0662", "S 99999999999999999999", '=HYPERLINK("x")', "\x1b[31m"]
    markers = (["New Segment,,1,1,0,20200101000000000000", "Stimulus,S  7,100,1,0"]
               + [f"Stimulus,{d},{110 + k},1,0" for k, d in enumerate(odd)]
               + ["Stimulus,S 12,9999,1,0", "Stimulus,S 14,200,1,0"])  # S 12 lies after the end
    path = brainvision(tmp_path / "bv", markers)
    raw = read_recording(path)
    assert "Stimulus/S 99999999999999999999" in raw.annotations.description
    assert find_trigger_events(raw, path).tolist() == [[99, 0, 7], [199, 0, 14]]


BV_REFUSED = {
    "data file elsewhere": ({"common": "DataFile=../other/rec.eeg"}, "rec.vhdr",
                            "DataFile: expected the name of a file beside the header (no folders)"),
    "data file is a device": ({"common": "DataFile=zero.eeg"}, "rec.vhdr", "DataFile: 'zero.eeg' is a device"),
    "marker without position": ({"markers": ["Stimulus,S  7"]}, "rec.vmrk", "Mk1: expected type,description,position"),
    "marker position text": ({"markers": ["Stimulus,S  7,abc,1,0"]}, "rec.vmrk", "Mk1"),
    "no channels": ({"common": "NumberOfChannels=0"}, "rec.vhdr", "NumberOfChannels: expected a whole number"),
    "a billion channels": ({"common": "NumberOfChannels=999999999"}, "rec.vhdr", "NumberOfChannels"),
    "no interval": ({"common": "SamplingInterval=0"}, "rec.vhdr", "SamplingInterval"),
    "unknown codepage": ({"common": "Codepage=klingon"}, "rec.vhdr", "Codepage: expected a text encoding"),
}


@pytest.mark.parametrize("case", sorted(BV_REFUSED))
def test_brainvision_refused(tmp_path, case):
    kwargs, named, needle = BV_REFUSED[case]
    folder = tmp_path / "bv"
    path = brainvision(folder, kwargs.get("markers", ["Stimulus,S  7,100,1,0"]), common=kwargs.get("common", ""))
    if case == "data file is a device":
        (folder / "zero.eeg").symlink_to("/dev/zero")
    refusal(path, needle, named=named)


def test_brainvision_channel_names(tmp_path):
    """No 16-byte limit here: MNE keeps a 300-character name (read as it is; a message cuts it), and
    the names MNE read are checked like EDF labels."""
    path = brainvision(tmp_path / "bv", ["Stimulus,S  7,100,1,0"])
    header = path.read_text()
    path.write_text(header.replace("Ch1=Cz", "Ch1=" + "X" * 300))
    assert [len(c) for c in read_recording(path).ch_names] == [300, 2]
    path.write_text(header.replace("Ch1=Cz", "Ch1=" + "X" * 300).replace("Ch2=Oz", "Ch2=" + "x" * 300))
    line = refusal(path, "labels of channels 1 and 2: expected each channel name once", "XXX...'")
    assert len(line) < len(str(path)) + 200
    path.write_text(header.replace("Ch1=Cz", "Ch1=\x1b[31mCz"))
    refusal(path, "label of channel 1: expected printable text, got '\\x1b[31mCz'")


# --------------------------------------------------------------------------- subject ids
@pytest.mark.parametrize("name, expected", [
    ("sub-01_task-faces_eeg.bdf", "01"), ("Newtest17-256.bdf", "Newtest17-256"), ("Subject 7.bdf", "Subject 7"),
])
def test_subject_ids_from_file_names(name, expected):
    assert subject_id(Path(name), r"sub-([A-Za-z0-9]+)") == expected


@pytest.mark.parametrize("name", ["a$\\frac$b.bdf", "x\x1b[2J.bdf", "=HYPERLINK(1).bdf", "-x.bdf", "ü\u202etxt.bdf"])
def test_subject_ids_that_are_refused(name):
    """'$' would start TeX in the figures' tick labels (matplotlib stops on '$\\frac$'), escapes would
    reach the log and terminal; no path is built from an id, but ids are checked where they are made."""
    with pytest.raises(AppealInputError) as err:
        subject_id(Path("data") / name, r"sub-([A-Za-z0-9]+)")
    line = err.value.lines[0]
    assert len(err.value.lines) == 1 and "subject id: expected letters, digits" in line and "\x1b" not in line


# --------------------------------------------------------------------------- through the command
def _config(folder: Path, recordings, **extra) -> Path:
    cfg = {"kind": "erp", "recordings": recordings, "events": {11: {"emotion": "angry"}, 12: {"emotion": "happy"}},
           "source": {"enabled": False}, **extra}
    path = folder / "erp.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def test_command_refuses_a_hostile_recording_in_one_line(tmp_path, capsys):
    folder = tmp_path / "study"
    folder.mkdir()
    bad = put_main(valid_bdf(folder / "sub-01_eeg.bdf"), "n_signals", b"-1")
    line = one_line_error(capsys, ["analyze", "erp", str(_config(folder, "sub-*_eeg.bdf")), "--out",
                                   str(tmp_path / "out"), "--n-jobs", "1"],
                          "01: ", bad.name, "number of signals: expected a whole number from 1 to 9999, got '-1'")
    assert "Traceback" not in line
    # an escape in a label is shown escaped, never sent to the terminal
    put_main(bad, "n_signals", b"5")
    put_signal(bad, "label", 0, b"\x1b[2J\x1b[31m")
    line = one_line_error(capsys, ["analyze", "erp", str(_config(folder, "sub-*_eeg.bdf")), "--out",
                                   str(tmp_path / "out2"), "--n-jobs", "1"], "label of signal 1", "\\x1b[2J")
    assert "\x1b" not in line


def test_command_refuses_an_odd_subject_id(tmp_path, capsys):
    folder = tmp_path / "study"
    folder.mkdir()
    valid_bdf(folder / "a$\\frac$b.bdf")
    one_line_error(capsys, ["analyze", "erp", str(_config(folder, "*.bdf")), "--out", str(tmp_path / "out"),
                            "--n-jobs", "1"], "subject id: expected letters, digits", "a$\\\\frac$b")


def test_command_runs_with_formula_labels_and_neutralises_them(small, tmp_path):  # noqa: F811 - the fixture
    """Formula-like labels are channel names like any other: on unused electrodes the run goes on;
    a bad electrode called ``=HYPERLINK(...)`` ends up in qc.csv, written as text (``'=...``)."""
    import mne

    from analysis.erp.channels import make_montage

    d, path = small
    truth = yaml.safe_load((d / "truth.yaml").read_text())
    bad = truth["bad_channels"]["01"][0]
    # BDF: four electrodes without a position in biosemi128 (so: misc), the run is unchanged otherwise
    copy = tmp_path / "sub-01_task-faces_eeg.bdf"
    copy.write_bytes(path.read_bytes())
    raw = read_recording(copy)
    spare = [c for c in ["C1", "C2", "C3", "C4", "C5"] if c != bad][:4]  # in no default cluster
    for label, formula in zip(spare, [b'=HYPERLINK("x")', b"+cmd", b"-x", b"@x"]):
        put_signal(copy, "label", raw.ch_names.index(label), formula)
    cfg = yaml.safe_load((d / "erp.yaml").read_text())
    config = tmp_path / "erp.yaml"
    config.write_text(yaml.safe_dump({**cfg, "recordings": str(copy)}))
    assert main(["-q", "analyze", "erp", str(config), "--out", str(tmp_path / "bdf"), "--n-jobs", "1"]) == 0
    assert pd.read_csv(tmp_path / "bdf" / "qc.csv")["n_channels"].tolist() == [124]
    # FIF with positions (montage: none): the planted bad electrode carries a formula name
    fif = mne.io.read_raw_bdf(path, preload=True, verbose="error")
    fif.set_channel_types({c: "eog" for c in cfg["eog"]}, verbose="error")
    fif.set_montage(make_montage("biosemi128"), verbose="error")
    fif.rename_channels({bad: '=HYPERLINK("x")'})
    fif_path = tmp_path / "sub-01_task-faces_eeg.fif"
    fif.save(fif_path, verbose="error")
    cluster = {"right": [c for c in ["B7", "B8", "B9", "B10"] if c != bad][:3]}
    config.write_text(yaml.safe_dump({**cfg, "recordings": str(fif_path), "montage": "none",
                                      "components": {"N170": {"window_s": [0.13, 0.21], "clusters": cluster}},
                                      "figures": {"channels": cluster["right"][:1]}}))
    assert main(["-q", "analyze", "erp", str(config), "--out", str(tmp_path / "fif"), "--n-jobs", "1"]) == 0
    text = (tmp_path / "fif" / "qc.csv").read_text()
    assert "'=HYPERLINK" in text and ',=HYPERLINK' not in text


# --------------------------------------------------------------------------- fuzzing the header
@pytest.fixture(scope="module")
def fuzz_base(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    plain = valid_bdf(d / "plain.bdf", ["Fp1", "Cz"], n_records=2, sfreq=32)
    annotated = annotated_bdf(d / "annotated.bdf", [b"+0\x14\x14\x00+0.5\x14Stimulus/S  7\x14\x00", b"+1\x14\x14\x00"],
                              sfreq=32)
    return d, {"plain": plain.read_bytes(), "annotated": annotated.read_bytes()}


NUMBERS = [b"-1", b"0", b"1", b"+5", b"-0", b"1e308", b"nan", b"inf", b"1_0", b"", b"99999999", b"0,5", b"1.5", b"\xff",
           b"\x00", b"  7  ", b"0x10", b"\xb2", b"-9999999"]


@st.composite
def mutated(draw):
    """A valid file with 1-4 changes: a header field (random bytes or a number-like text), any header
    byte, or a byte of the annotations."""
    name = draw(st.sampled_from(["plain", "annotated"]))
    n_signals = 3
    fields = [MAIN[f] for f in MAIN] + [signal_offset(n_signals, f, i) for f, _ in SIGNAL for i in range(n_signals)]
    changes = []
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["field", "number", "byte", "annotation"]))
        if kind == "byte":
            changes.append((draw(st.integers(0, 1023)), 1, draw(st.binary(min_size=1, max_size=1))))
            continue
        if kind == "annotation":
            at = 1024 + draw(st.integers(0, 1)) * 3 * 96 + 2 * 96 + draw(st.integers(0, 95))
            changes.append((at, 1, draw(st.binary(min_size=1, max_size=1))))
            continue
        offset, width = draw(st.sampled_from(fields))
        value = (draw(st.binary(max_size=width)) if kind == "field"
                 else draw(st.sampled_from(NUMBERS)))
        changes.append((offset, width, value))
    return name, changes


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=mutated())
def test_mutated_headers_read_or_refused_in_one_line(fuzz_base, case):
    import mne

    d, base = fuzz_base
    name, changes = case
    raw_bytes = bytearray(base[name])
    for offset, width, value in changes:
        raw_bytes[offset:offset + width] = value.ljust(width, b" ")[:width]
    path = d / f"m_{name}.bdf"
    path.write_bytes(bytes(raw_bytes))
    try:
        raw = read_recording(path)
    except AppealInputError as err:
        assert len(err.lines) == 1 and path.name in err.lines[0] and "\n" not in str(err), err.lines
        assert not any(ch in err.lines[0] for ch in "\x00\x1b\x9b"), err.lines
        return
    assert isinstance(raw, mne.io.BaseRaw) and raw.n_times >= 2 and np.isfinite(raw.info["sfreq"])
    try:
        find_trigger_events(raw, path)
    except AppealInputError as err:
        assert len(err.lines) == 1
