"""README.md and docs/*.md point only to files in the repository.

Checked: Markdown link targets; backticked paths that start with a top-level folder of the
repository (``benchmarks/erp.py``, ``tests/x.py::test_y``); and any absolute path or path
leaving the checkout (only ``../shared/data``, the third-party data the README names, may).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ["README.md", *sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "docs").glob("*.md"))]
TOP = sorted(p.name for p in ROOT.iterdir() if p.is_dir() and not p.name.startswith("."))
PLACEHOLDER = re.compile(r"[*?<>{}\[\]]|\bN\b|NAME|XX|DIR")


def pointers(text: str) -> list[str]:
    """Paths a reader is sent to: link targets and backticked repository or outside paths."""
    out = [t for t in re.findall(r"\]\(([^)\s]+)\)", text) if not re.match(r"[a-z]+://|#|mailto:", t)]
    for code in re.findall(r"`([^`\n]+)`", text):
        for word in code.split():
            word = word.split("::")[0].split(":")[0].rstrip(".,;)")
            outside = re.match(r"(/|\.\./|~/)[\w.-]", word)  # /work/x, ../x, ~/x (not R's ~A or a lone /)
            if (outside or word.split("/")[0] in TOP and "/" in word) and not PLACEHOLDER.search(word):
                out.append(word)
    return out


@pytest.mark.parametrize("doc", DOCS)
def test_doc_points_only_to_repository_files(doc):
    path = ROOT / doc
    missing = []
    for target in pointers(path.read_text(encoding="utf-8")):
        if target.startswith("../shared/data"):
            continue  # the third-party data beside the checkout (README: "The tests read real third-party data")
        if target.startswith(("/", "~", "../")):
            missing.append(f"{target} (outside the repository)")
        elif not ((path.parent / target).exists() or (ROOT / target).exists()):
            missing.append(target)
    assert missing == [], f"{doc} points to files not in the repository: {missing}"


def test_pointer_scanner_finds_outside_and_missing_paths():
    text = ("See `/work/notes/issue-8.md` and `benchmarks/erp.py:plain_mne`, [x](../README.md), `tests/nope.py::t`,"
            " `y ~ A`, `a / b`, `../stimuli/<study>/manifest.csv`.")
    assert pointers(text) == ["../README.md", "/work/notes/issue-8.md", "benchmarks/erp.py", "tests/nope.py"]
