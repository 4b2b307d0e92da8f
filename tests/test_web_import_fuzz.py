"""Fuzzing the web importer (Hypothesis): 10,000 generated session files, each edited from a real one as
an attacker could (cells replaced by hostile or random text, rows duplicated, dropped or swapped, bytes cut,
inserted or re-encoded, whole files of random bytes). Every file is imported for real (``import_web``): it
must be imported or refused with exactly one :class:`AppealInputError` line; nothing is ever written outside
``--out``, a refused file writes nothing at all, and what is written has no formula cell and only checked
labels in its paths.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from appeal.cells import formula_like
from appeal.errors import AppealInputError
from experiments.web import import_context, import_web
from web_session_files import browser_rows, web_protocol

#: Generated files in the fuzz run (the issue asks for at least 10,000).
N_FILES = int(__import__("os").environ.get("FUZZ_N", 10_000))

HOSTILE = ["x/../../../escaped", "../02", "..", "/etc/passwd", "C:\\Windows", "sub-01/../..", "01\x00", "01/",
           "=HYPERLINK(\"http://x\")", "+cmd|' /C calc'!A0", "-2+3+cmd", "@SUM(A1)", "\u202eexe.gnp", "n/a", "",
           "NaN", "inf", "-inf", "1e999", "-0", "00", "1.0", "0x10", "9" * 40, "A" * 300, "é", "\ufeff01", "\r",
           "\x1b[2J", "2026-02-31T10:00:00Z", "2026-12-01T10:00:00.000Z", "1", "0", "7", "8", "-1", "01", "02",
           "neutral", "anchors", "main", "%s%s%n", "{{7*7}}", "<script>alert(1)</script>", "${jndi:ldap://x}"]


@pytest.fixture(scope="module")
def fuzz_study(tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz")
    proto = web_protocol(root, "exp2_stylisation")
    rows = browser_rows(proto, root, "02")
    lines = ["\t".join(rows.columns), *("\t".join(map(str, r)) for r in rows.itertuples(index=False))]
    return proto, import_context(proto), lines, root


cell_text = st.one_of(st.sampled_from(HOSTILE), st.text(max_size=24),
                      st.text(alphabet=st.characters(min_codepoint=0, max_codepoint=0x2FFF), max_size=12))


@st.composite
def session_bytes(draw, lines: list[str]) -> bytes:
    """A session file: the real one after 1-4 random edits, or (sometimes) random bytes."""
    if draw(st.integers(0, 19)) == 0:
        return draw(st.binary(max_size=4000))
    grid = [ln.split("\t") for ln in lines]
    free_only = draw(st.integers(0, 3)) == 0  # what a participant can send through the URL and nothing else
    for _ in range(draw(st.integers(1, 4))):
        edit = "free" if free_only else draw(st.sampled_from(["cell", "cell", "cell", "column", "free", "dup", "drop",
                                                              "swap", "ragged", "append"]))
        r = draw(st.integers(0, len(grid) - 1))
        if edit == "cell" and grid[r]:
            grid[r][draw(st.integers(0, len(grid[r]) - 1))] = draw(cell_text)
        elif edit == "column":
            c, v = draw(st.integers(0, len(grid[0]) - 1)), draw(cell_text)
            for row in grid[1:]:
                if c < len(row):
                    row[c] = v
        elif edit == "free":  # the free-text columns a participant controls through the URL
            c = lines[0].split("\t").index(draw(st.sampled_from(["browser", "recruitment_pid", "study_id", "session_id"])))
            row = grid[draw(st.integers(0, len(grid) - 1))]
            if c < len(row):
                row[c] = draw(cell_text)
        elif edit == "dup":
            grid.insert(r, list(grid[r]))
        elif edit == "drop" and len(grid) > 1:
            grid.pop(r)
        elif edit == "swap":
            s = draw(st.integers(0, len(grid) - 1))
            grid[r], grid[s] = grid[s], grid[r]
        elif edit == "ragged" and grid[r]:
            grid[r].pop()
        elif edit == "append":
            grid.extend([list(g) for g in grid[1:]] * draw(st.integers(1, 3)))
    data = ("\n".join("\t".join(row) for row in grid) + "\n").encode("utf-8", "surrogatepass")
    byte_edit = draw(st.sampled_from(["none", "none", "none", "cut", "insert", "latin1", "crlf"]))
    if byte_edit == "cut":
        data = data[:draw(st.integers(0, len(data)))]
    elif byte_edit == "insert":
        k = draw(st.integers(0, len(data)))
        data = data[:k] + draw(st.binary(min_size=1, max_size=8)) + data[k:]
    elif byte_edit == "latin1":
        data = data.decode("utf-8", "replace").encode("latin-1", "replace")
    elif byte_edit == "crlf":
        data = data.replace(b"\n", b"\r\n")
    return data


def _outside(root: Path, out: Path, inputs: Path) -> set[Path]:
    return {p for p in root.rglob("*") if out not in (p, *p.parents) and inputs not in (p, *p.parents)}


def test_fuzzed_session_files_are_imported_or_refused_in_one_line(fuzz_study):
    proto, ctx, lines, root = fuzz_study
    inputs, out = root / "inputs", root / "data"
    inputs.mkdir()
    world = _outside(root, out, inputs)
    seen = {"files": 0, "imported": 0, "refused": 0}

    @settings(max_examples=N_FILES, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.large_base_example])
    @given(data=st.data())
    def run(data):
        raw = data.draw(session_bytes(lines))
        f = inputs / "sub-02_ses-1_task-exp2_beh.tsv"
        f.write_bytes(raw)
        seen["files"] += 1
        try:
            done = import_web([f], proto, out, force=True, report=False, context=ctx)
        except AppealInputError as exc:
            seen["refused"] += 1
            assert len(exc.lines) == 1 and exc.lines[0].startswith(str(f)), exc.lines
            assert not any(ch in exc.lines[0] for ch in "\n\r\x00\x1b")
            assert not out.exists() or not any(out.rglob("*")), "a refused file wrote something"
        else:
            seen["imported"] += 1
            (s,) = done
            assert s.beh.resolve().is_relative_to(out.resolve()) and s.participant.isalnum()
            for cell in s.beh.read_text(encoding="utf-8").replace("\n", "\t").split("\t"):
                assert not formula_like(cell), cell
        finally:
            assert _outside(root, out, inputs) == world, "something was written outside --out"
            assert f.read_bytes() == raw, "the participant's file was changed"
            shutil.rmtree(out, ignore_errors=True)

    run()
    assert seen["files"] >= N_FILES, seen
    print(seen)
    assert seen["imported"] > N_FILES / 20 and seen["refused"] > N_FILES / 2, seen  # both paths, often
