"""Reproducible installs: `make` installs from pinned versions, and provenance says whether a run used them."""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

import pytest

from appeal.provenance import constraints_status, provenance_record, read_constraints

ROOT = Path(__file__).resolve().parent.parent


def _name(requirement: str) -> str:
    return re.sub(r"[-_.]+", "-", re.split(r"[\s\[<>=!~;]", requirement, maxsplit=1)[0]).lower()


@pytest.mark.parametrize("file", ["constraints.txt", "constraints-cycles.txt"])
def test_constraints_pin_exact_versions(file):
    lines = [ln.strip() for ln in (ROOT / file).read_text().splitlines()]
    pins = [ln for ln in lines if ln and not ln.startswith("#")]
    assert pins and all(re.fullmatch(r"[A-Za-z0-9_.\-]+==[A-Za-z0-9_.+!\-]+", p) for p in pins), pins
    assert len(read_constraints(ROOT / file)) == len(pins)  # no name twice


def test_every_dependency_is_pinned():
    """Every requirement of pyproject.toml (and its extras that make installs) has a pin."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    wanted = project["dependencies"] + [r for extra in ("dev", "fast", "atlas") for r in project["optional-dependencies"][extra]]
    pins = read_constraints(ROOT / "constraints.txt")
    assert [_name(r) for r in wanted if _name(r) not in pins] == []
    assert pins["pyrender"] == "0.1.45"
    assert "bpy" in read_constraints(ROOT / "constraints-cycles.txt")


def test_make_installs_from_the_pins():
    make = (ROOT / "Makefile").read_text()
    installs = [ln for ln in make.splitlines() if "pip install" in ln and "--upgrade pip" not in ln]
    pinned = [ln for ln in installs if ".venv-upgrade" not in ln]
    assert pinned and all("-c $(CONSTRAINTS)" in ln or "-c $(CYCLES_CONSTRAINTS)" in ln for ln in pinned), pinned
    assert "upgrade-constraints:" in make and "upgrade-constraints" in (ROOT / "README.md").read_text()


def test_status_names_what_differs(tmp_path):
    import numpy

    f = tmp_path / "constraints.txt"
    f.write_text(f"# a comment\nnumpy=={numpy.__version__}\nPyYAML==0.0.1  # too old\nno-such-package==1.0\n")
    st = constraints_status(f)
    assert st["pinned"] == 3 and len(st["sha256"]) == 64
    assert st["differs"]["pyyaml"]["pinned"] == "0.0.1" and st["differs"]["pyyaml"]["installed"]
    assert st["differs"]["no-such-package"] == {"pinned": "1.0", "installed": None}
    assert "numpy" not in st["differs"]
    assert constraints_status(tmp_path / "missing.txt") is None


def test_provenance_records_the_constraints():
    rec = provenance_record(argv=["appeal"])
    assert rec["constraints"]["file"].endswith("constraints.txt") and rec["constraints"]["pinned"] > 100


@pytest.mark.skipif(Path(sys.prefix).resolve() != (ROOT / ".venv").resolve(), reason="not the environment `make` installs")
def test_the_make_environment_is_the_pinned_one():
    assert constraints_status()["differs"] == {}
