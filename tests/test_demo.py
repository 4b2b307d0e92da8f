"""The demo runner: stages in order, a failing stage reported, index.html links everything."""

from __future__ import annotations

import json

from appeal.cli import main
from appeal.cli.demo import discover_stages
from appeal.demo import DemoStage, run_demo
from appeal.report import ReportSection


def test_discovers_environment_stage():
    names = [s.name for s in discover_stages()]
    assert names[0] == "environment"


def test_run_demo_reports_failures_and_continues(tmp_path):
    def good(out, seed):
        (out / "t.csv").write_text("a\n1\n")
        return ReportSection("Good", tables=[out / "t.csv"])

    def bad(out, seed):
        raise ValueError("broken stage")

    index, sections = run_demo([DemoStage("b", "Bad", 1, bad), DemoStage("g", "Good", 2, good)], tmp_path, 0)
    assert [s.title for s in sections] == ["Bad", "Good"]
    assert sections[0].failed == "ValueError: broken stage"
    text = index.read_text()
    assert "href='g/t.csv'" in text and "broken stage" in text


def test_demo_command_environment_stage(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--only", "environment", "--seed", "3"]) == 0
    assert (out / "index.html").is_file()
    assert "environment/versions.csv" in (out / "index.html").read_text()
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["seed"] == 3 and prov["failed_stages"] == []
    assert f"Demo report: {out.resolve()}/index.html" in capsys.readouterr().out


def test_demo_unknown_stage(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path / "d"), "--only", "nope"]) == 2
    assert "--only: unknown stage(s) nope" in capsys.readouterr().err


def test_whole_demo_every_stage_succeeds(tmp_path):
    """`appeal demo` end to end (what `make demo` runs): no stage fails, every linked file exists.

    Runs in a subprocess: the grid stage renders with pyrender and the experiment stage opens
    PsychoPy windows in its own subprocesses, as in `make demo`.
    """
    import re
    import subprocess
    import sys

    out = tmp_path / "demo"
    res = subprocess.run([sys.executable, "-m", "appeal", "-q", "demo", "--out", str(out)],
                         capture_output=True, text=True, check=False, timeout=1200)
    assert res.returncode == 0, res.stderr[-2000:]
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["failed_stages"] == []
    page = (out / "index.html").read_text()
    assert "This stage failed" not in page
    names = [s.name for s in discover_stages()]
    assert {"environment", "grid", "correspond", "avatar", "experiment", "ratings", "erp"} <= set(names)
    links = set(re.findall(r"(?:src|href)='([^'#]+)'", page))
    assert len(links) > 20
    missing = [link for link in links if not (out / link).exists()]
    assert not missing, missing
