"""The core rules every reader of untrusted files shares: BIDS labels, paths that stay inside the
output folder, spreadsheet-formula cells, one-line messages whatever a value holds."""

from __future__ import annotations

import os

import pandas as pd
import pytest

from appeal.cells import formula_like, neutralise, write_table
from appeal.errors import AppealInputError
from appeal.labels import check_label, check_session, label_problem
from appeal.outputs import remove_inside, require_inside


@pytest.mark.parametrize("value", ["01", "abc", "5f1a2b3c4d5e6f7a8b9c0d1e", "A" * 64])
def test_bids_labels_pass(value):
    assert check_label(value, "participant_id") == value and label_problem(value) is None


@pytest.mark.parametrize("value", ["", "x/../../escaped", "..", "a b", "a-b", "a_b", "a.b", "/etc", "é", "1\n2",
                                   "a\x00", "A" * 65, "٣", "ａ"])
def test_everything_else_is_refused_in_one_line(value):
    with pytest.raises(AppealInputError) as e:
        check_label(value, "column 'participant_id'", "f.tsv:2")
    assert len(e.value.lines) == 1 and e.value.lines[0].startswith("f.tsv:2: column 'participant_id': expected")
    assert "\n" not in str(e.value) and "\x00" not in str(e.value)


def test_session_numbers():
    assert check_session("3", "session") == 3 and check_session(12, "--session") == 12
    for bad in ("0", "-1", "1.0", "１", "10000", "", " 1", True, 0):
        with pytest.raises(AppealInputError, match="expected a session number"):
            check_session(bad, "session")


def test_messages_never_carry_control_characters():
    err = AppealInputError("f.tsv: column 'browser': \x1b[31mred\x1b[0m\r\nline two\tand\x00")
    assert err.lines == ["f.tsv: column 'browser': \\x1b[31mred\\x1b[0m  line two and\\x00"]


def test_paths_must_resolve_inside_the_output_folder(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    assert require_inside(out, out / "sub-01" / "ses-1" / "x.tsv") == (out / "sub-01/ses-1/x.tsv").resolve()
    with pytest.raises(AppealInputError, match="outside the output folder"):
        require_inside(out, out / "sub-x" / ".." / ".." / "escaped")
    (tmp_path / "elsewhere").mkdir()
    os.symlink(tmp_path / "elsewhere", out / "sub-02")
    with pytest.raises(AppealInputError, match="symbolic link"):
        require_inside(out, out / "sub-02" / "ses-1" / "beh" / "x.tsv")
    # a link is removed itself, never what it points to
    (tmp_path / "elsewhere" / "keep.txt").write_text("kept")
    remove_inside(out, out / "sub-02")
    assert not (out / "sub-02").exists() and (tmp_path / "elsewhere" / "keep.txt").read_text() == "kept"


@pytest.mark.parametrize("text,formula", [
    ("=HYPERLINK(\"http://x\")", True), ("+cmd|' /C calc'!A0", True), ("-2+3+cmd|' /C calc'!A0", True),
    ("@SUM(A1)", True), ("\t=1", True), ("\r=1", True), ("-0.5", False), ("+3", False), ("1e-7", False),
    ("-", False), ("Mozilla/5.0 (X11; Linux x86_64)", False), ("n/a", False), ("", False)])
def test_formula_cells(text, formula):
    assert formula_like(text) is formula
    assert neutralise(text) == ("'" + text if formula else text)


def test_tables_are_written_with_formulas_neutralised(tmp_path):
    df = pd.DataFrame({"participant_id": ["01", "02"], "note": ["=1+1", "fine"], "x": [-1.5, 2.0]})
    back = pd.read_csv(write_table(df, tmp_path / "t.csv"), dtype=str)
    assert back["note"].tolist() == ["'=1+1", "fine"] and back["x"].tolist() == ["-1.5", "2.0"]
    assert df["note"].tolist() == ["=1+1", "fine"]  # the caller's table is not changed
