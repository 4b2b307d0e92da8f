"""Output folders, provenance records, atomic writes and the report page."""

from __future__ import annotations

import json
import sys

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


def test_failed_run_logs_the_error_and_leaves_the_folder_reusable(tmp_path):
    out = tmp_path / "o"
    with pytest.raises(AppealInputError):
        with output_run(out, seed=3):
            raise AppealInputError("study.yaml: data: expected a file")
    log = (out / "log.txt").read_text()
    assert "ERROR appeal: failed: study.yaml: data: expected a file" in log
    assert "Traceback" not in log
    # nothing but the failed run's records: the next run needs no --force, and appends to the log
    with output_run(out, seed=3) as run:
        (run.out / "result.txt").write_text("ok")
    assert json.loads((out / "provenance.json").read_text())["status"] == "ok"
    assert (out / "log.txt").read_text().count("writing to") == 2


def test_internal_error_is_logged_with_its_traceback(tmp_path):
    out = tmp_path / "o"
    with pytest.raises(ZeroDivisionError):
        with output_run(out):
            1 / 0  # noqa: B018
    log = (out / "log.txt").read_text()
    assert "failed with an internal error: ZeroDivisionError" in log
    assert "Traceback (most recent call last)" in log and "1 / 0" in log


def test_failed_run_with_results_is_not_reused_silently(tmp_path):
    out = tmp_path / "o"
    with pytest.raises(RuntimeError):
        with output_run(out) as run:
            (run.out / "part.csv").write_text("half")
            raise RuntimeError("boom")
    with pytest.raises(AppealInputError, match="not empty"):
        prepare_out_dir(out)
    # a successful run's folder is not reused either
    out2 = tmp_path / "o2"
    with output_run(out2):
        pass
    with pytest.raises(AppealInputError, match="not empty"):
        prepare_out_dir(out2)


@pytest.mark.parametrize(("seed", "words"), [(None, "(no random choices)"), (5, "(seed 5)"),
                                             ({"c1.texture_seed": 0, "c2.texture_seed": 4},
                                              "(seeds c1.texture_seed=0, c2.texture_seed=4)")])
def test_log_names_the_seed_actually_used(tmp_path, seed, words):
    with output_run(tmp_path / "o", seed=seed):
        pass
    assert words in (tmp_path / "o" / "log.txt").read_text()
    assert "None" not in (tmp_path / "o" / "log.txt").read_text()
    assert json.loads((tmp_path / "o" / "provenance.json").read_text())["seed"] == seed


@pytest.mark.slow
@pytest.mark.parametrize("umask", [0o022, 0o027])
def test_output_files_are_as_readable_as_the_umask_says(tmp_path, umask):
    """A simulated session writes its data, sidecar, report, log and provenance with 0o666 & ~umask."""
    import os
    import shutil
    import subprocess
    import sys

    import yaml

    from appeal.assets import protocols_dir
    from experiments.drawn_faces import draw_face_grid

    shutil.copytree(protocols_dir(), tmp_path / "protocols")
    protocol = yaml.safe_load((tmp_path / "protocols" / "exp2_stylisation.yaml").read_text(encoding="utf-8"))
    levels = {"character": ["c1"], **protocol["stimuli"]["levels"], "expression": ["neutral"]}
    draw_face_grid((tmp_path / "protocols" / protocol["stimuli"]["manifest"]).parent, levels, size=(40, 30))
    res = subprocess.run([sys.executable, "-m", "appeal_cli", "-q", "run", "protocols/exp2_stylisation.yaml",
                          "--participant", "01", "--simulate", "default", "--no-window"],
                         cwd=tmp_path, env={**os.environ, "MPLBACKEND": "Agg"}, capture_output=True, text=True,
                         timeout=600, check=False, preexec_fn=lambda: os.umask(umask))
    assert res.returncode == 0, res.stderr
    files = [p for p in (tmp_path / "data").rglob("*") if p.is_file()]
    names = {p.name for p in files}
    assert {"participants.tsv", "log.txt", "provenance.json"} <= names
    assert any(n.endswith("_beh.tsv") for n in names) and any(n.endswith("_beh.json") for n in names)
    modes = {str(p.relative_to(tmp_path)): oct(p.stat().st_mode & 0o777) for p in files}
    assert set(modes.values()) == {oct(0o666 & ~umask)}, modes


def test_log_messages_follow_a_replaced_stderr(monkeypatch):
    """The stderr handler writes to the sys.stderr of each message: after the stream it first saw
    is replaced and closed (pytest capture, notebooks), messages still arrive and nothing raises."""
    import io

    from appeal.logs import logger, set_log_level

    first = io.StringIO()
    monkeypatch.setattr(sys, "stderr", first)
    set_log_level("info")
    logger.info("one")
    first.close()
    second = io.StringIO()
    monkeypatch.setattr(sys, "stderr", second)
    logger.info("two")
    assert second.getvalue() == "appeal: two\n"
