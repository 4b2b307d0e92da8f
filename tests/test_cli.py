"""The ``appeal`` command: help everywhere, exit codes, one-line errors, no tracebacks."""

from __future__ import annotations

import subprocess
import sys

import click
import pytest

from appeal_cli import _hoist_global_flags, _load_commands, cli, main


def _all_commands():
    _load_commands()
    out = []

    def walk(cmd, path):
        out.append(path)
        if isinstance(cmd, click.Group):
            for name, sub in cmd.commands.items():
                walk(sub, path + [name])

    walk(cli, [])
    return out


@pytest.mark.parametrize("path", _all_commands(), ids=lambda p: " ".join(p) or "appeal")
def test_every_command_has_help_with_examples(path, capsys):
    assert main(path + ["--help"]) == 0
    text = capsys.readouterr().out
    assert "Usage: appeal" in text
    if path and path[0] not in ("stimuli", "analyze") or len(path) > 1:
        assert "Example" in text, f"'appeal {' '.join(path)} --help' shows no examples"


def test_version(capsys):
    assert main(["--version"]) == 0
    assert "appeal, version" in capsys.readouterr().out


def test_usage_error_is_one_line_exit_2(capsys):
    assert main(["validate"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Missing argument" in err[0]
    assert main(["no-such-command"]) == 2


def test_bad_input_exit_2_without_traceback(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("kind: nonsense\n")
    assert main(["validate", str(bad), str(tmp_path / "missing.yaml")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert lines[0] == f"{bad}: kind: unknown kind 'nonsense' (expected one of: grid, protocol, ratings, psychometric, erp)"
    assert lines[1] == f"{tmp_path / 'missing.yaml'}: file not found"


def test_missing_kind(tmp_path, capsys):
    f = tmp_path / "f.yaml"
    f.write_text("title: x\n")
    assert main(["validate", str(f)]) == 2
    assert "kind: required field is missing" in capsys.readouterr().err


def test_kind_typo_suggests(tmp_path, capsys):
    f = tmp_path / "f.yaml"
    f.write_text("kind: protocl\n")
    assert main(["validate", str(f)]) == 2
    assert "did you mean 'protocol'?" in capsys.readouterr().err


def test_global_flags_anywhere():
    assert _hoist_global_flags(["demo", "--out", "x", "-q"]) == ["--quiet", "demo", "--out", "x"]
    assert _hoist_global_flags(["-v", "validate", "a", "--", "-q"]) == ["--verbose", "validate", "a", "--", "-q"]


def test_internal_error_exit_1(monkeypatch, capsys):
    from appeal_cli import demo as demo_mod

    def boom():
        raise RuntimeError("kaput")

    monkeypatch.setattr(demo_mod, "discover_stages", boom)
    assert main(["demo", "--list"]) == 1
    err = capsys.readouterr().err
    assert err.strip() == "appeal: internal error: RuntimeError: kaput (run with -v for the traceback)"


def test_out_refuses_non_empty(tmp_path, capsys):
    (tmp_path / "x").write_text("1")
    assert main(["demo", "--out", str(tmp_path), "--only", "environment"]) == 2
    assert "output folder is not empty" in capsys.readouterr().err


def test_console_script_runs():
    res = subprocess.run([sys.executable, "-m", "appeal_cli", "--help"], capture_output=True, text=True, check=False)
    assert res.returncode == 0 and "stimuli" in res.stdout
