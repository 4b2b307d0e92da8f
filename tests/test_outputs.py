"""Output folders, provenance records, atomic writes and the report page."""

from __future__ import annotations

import json

import pytest

from appeal.atomic import atomic_write_text
from appeal.errors import AppealInputError
from appeal.outputs import output_run, prepare_out_dir
from appeal.provenance import file_sha256
from appeal.report import ReportSection, write_index_html


def test_refuses_non_empty_folder(tmp_path):
    (tmp_path / "keep.txt").write_text("x")
    with pytest.raises(AppealInputError, match="not empty .*--force.*--resume"):
        prepare_out_dir(tmp_path)
    assert prepare_out_dir(tmp_path, resume=True) == tmp_path.resolve()
    # --force on a folder not made by appeal writes into it but deletes nothing
    prepare_out_dir(tmp_path, force=True)
    assert (tmp_path / "keep.txt").exists()


def test_force_empties_an_earlier_run(tmp_path):
    out = tmp_path / "o"
    with output_run(out, seed=1) as run:
        (run.out / "old.txt").write_text("old")
    with output_run(out, force=True, seed=1):
        pass
    assert not (out / "old.txt").exists()


def test_out_is_a_file(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(AppealInputError, match="must be a folder"):
        prepare_out_dir(f)


def test_provenance_record(tmp_path):
    inp = tmp_path / "in.yaml"
    inp.write_text("kind: x\n")
    with output_run(tmp_path / "o", seed=7, inputs=[inp], argv=["appeal", "x"]) as run:
        run.extra["note"] = "hello"
    rec = json.loads((tmp_path / "o" / "provenance.json").read_text())
    assert rec["command"] == ["appeal", "x"]
    assert rec["seed"] == 7
    assert rec["inputs"][0]["sha256"] == file_sha256(inp)
    assert rec["versions"]["numpy"]
    assert rec["status"] == "ok" and rec["note"] == "hello"
    assert rec["started"] <= rec["ended"]
    assert (tmp_path / "o" / "log.txt").read_text().count("writing to") == 1


def test_provenance_records_failure(tmp_path):
    with pytest.raises(RuntimeError):
        with output_run(tmp_path / "o", seed=0):
            raise RuntimeError("boom")
    rec = json.loads((tmp_path / "o" / "provenance.json").read_text())
    assert rec["status"] == "failed: RuntimeError: boom"


def test_atomic_write_leaves_no_temp_files(tmp_path):
    atomic_write_text(tmp_path / "a.txt", "hello")
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]
    assert (tmp_path / "a.txt").read_text() == "hello"


def test_index_html_links_everything(tmp_path):
    (tmp_path / "s").mkdir()
    fig = tmp_path / "s" / "fig.png"
    fig.write_bytes(b"\x89PNG")
    tab = tmp_path / "s" / "t.csv"
    tab.write_text("a,b\n1,2.5\n")
    page = write_index_html(tmp_path / "index.html", "T", [ReportSection("S", "**bold**", [fig], [tab]),
                                                         ReportSection("F", failed="ValueError: x")])
    text = page.read_text()
    assert "src='s/fig.png'" in text and "href='s/t.csv'" in text
    assert "<strong>bold</strong>" in text and "<td>2.5</td>" in text
    assert "This stage failed: ValueError: x" in text
