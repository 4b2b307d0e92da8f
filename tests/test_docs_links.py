"""The README and docs/ point only to files that are in the repository (or to ../shared/data)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
TOP = ("appeal", "analysis", "experiments", "stimulus_engine", "benchmarks", "docs", "tests", "scripts", "protocols")
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
CODE = re.compile(r"`([^`\s]+)`")
ABSOLUTE = re.compile(r"(?<![\w.])/(?:work|tmp|home|root|mnt)/[\w./-]+")


def _repo_paths(doc: Path) -> list[str]:
    """Relative link targets, and backticked repository paths (no wildcards or placeholders)."""
    text = doc.read_text(encoding="utf-8")
    found = [t for t in LINK.findall(text) if "://" not in t and not t.startswith("mailto:")]
    for code in CODE.findall(text):
        path = code.split(":")[0].rstrip(".,;")
        if path.split("/")[0] in TOP and "/" in path and not re.search(r"[*?<>{}\[\]]|\bN\b|\bNAME\b|XX", path):
            found.append(path)
    return found


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_doc_points_only_to_files_in_the_repository(doc):
    missing = []
    for target in _repo_paths(doc):
        if not ((doc.parent / target).exists() or (ROOT / target).exists()):
            missing.append(target)
    assert not missing, f"{doc.name} points to files not in the repository: {missing}"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_doc_has_no_absolute_paths_outside_the_repository(doc):
    text = doc.read_text(encoding="utf-8")
    assert not ABSOLUTE.findall(text), f"{doc.name}: absolute paths a reader does not have: {ABSOLUTE.findall(text)}"
