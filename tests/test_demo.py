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
