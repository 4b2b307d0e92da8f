"""Repository hygiene: every tracked path is one a shell, a URL and any file system take as it is."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SAFE_PATH = re.compile(r"[A-Za-z0-9._/-]+")


def _odd_paths(paths: list[str]) -> list[str]:
    """Paths with a character outside letters, digits and ``._-/`` (spaces, quotes, shell syntax ...)."""
    return [p for p in paths if not SAFE_PATH.fullmatch(p)]


def test_the_check_sees_odd_names():
    assert _odd_paths(["stimulus_engine/geometry/mesh_io.py", "docs/a-b_c.md"]) == []
    assert _odd_paths(['hat is missing""")#', "data/über.csv", "a b.txt", "x;rm.py"]) == [
        'hat is missing""")#', "data/über.csv", "a b.txt", "x;rm.py"]


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="not a git checkout")
def test_every_tracked_path_is_plain():
    out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    paths = [p.decode("utf-8", "surrogateescape") for p in out.split(b"\0") if p]
    assert len(paths) > 100
    assert _odd_paths(paths) == []
