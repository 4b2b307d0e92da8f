"""No CLI command lets a traceback escape on bad input: missing files and junk files → exit 2.

The commands are discovered, so a command added later is covered without editing this test.
"""

from __future__ import annotations

import click
import pytest

from appeal_cli import _load_commands, cli, main


def _leaf_commands():
    _load_commands()
    out = []

    def walk(cmd, path):
        if isinstance(cmd, click.Group):
            for name, sub in sorted(cmd.commands.items()):
                walk(sub, path + [name])
        elif any(p.required for p in cmd.params):  # commands with no required input (demo) have nothing to break
            out.append((path, cmd))

    walk(cli, [])
    return out


def _args(cmd: click.Command, bad_file: str, out_dir: str) -> list[str]:
    args: list[str] = []
    for p in cmd.params:
        if not p.required:
            continue
        if isinstance(p, click.Argument):
            args += [bad_file] * (2 if p.nargs == -1 else 1)
        else:
            value = out_dir if p.name == "out" else bad_file if isinstance(p.type, click.Path) else "x"
            args += [p.opts[0], value]
    return args


def _junk(tmp_path, name="junk.dat"):
    f = tmp_path / name
    f.write_bytes(b"\x00\x01\x02 not: [valid\n\xff\xfe")
    return f


@pytest.mark.parametrize("path, cmd", _leaf_commands(), ids=lambda v: " ".join(v) if isinstance(v, list) else "")
@pytest.mark.parametrize("problem", ["missing", "junk"])
def test_bad_input_exits_2_with_one_line_errors(path, cmd, problem, tmp_path, capsys):
    bad = str(tmp_path / "does_not_exist.yaml") if problem == "missing" else str(_junk(tmp_path))
    code = main(path + _args(cmd, bad, str(tmp_path / "out")))
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    assert code == 2, f"appeal {' '.join(path)} exited {code} on {problem} input: {err}"
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("appeal: writing to")]
    assert 1 <= len(lines) <= 5, err
