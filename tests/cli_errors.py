"""The check every bad-input test makes: the command exits 2 with exactly one line on stderr."""

from __future__ import annotations


def one_line_error(capsys, args: list[str], *needles: str) -> str:
    """Run ``appeal ARGS``; assert exit status 2, one line on stderr (besides the output-folder
    notice), no traceback, and every ``needle`` in that line; return the line."""
    from appeal_cli import main

    code = main(args)
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("appeal: writing to")]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in lines[0], lines[0]
    return lines[0]
