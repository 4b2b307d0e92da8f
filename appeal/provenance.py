"""Provenance records: what was run, on which inputs, with which software and seed."""

from __future__ import annotations

import hashlib
import json
import platform
import re
import subprocess
import sys
from collections.abc import Iterable
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any

from appeal.atomic import atomic_write_text

__all__ = ["constraints_status", "read_constraints", "file_sha256", "package_versions", "git_describe", "provenance_record",
           "write_provenance", "now_iso"]

#: Packages whose versions every provenance record lists (when installed).
TRACKED_PACKAGES = (
    "appeal-lab", "numpy", "scipy", "pandas", "statsmodels", "pingouin", "mne", "trimesh",
    "pyrender", "PyOpenGL", "psychopy", "pydantic", "joblib", "dask", "distributed", "matplotlib",
)


def now_iso() -> str:
    """The current UTC time as an ISO 8601 string."""
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds")


def file_sha256(path: str | Path, chunk: int = 1 << 20) -> str:
    """SHA-256 hex digest of a file, read in chunks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def package_versions(names: Iterable[str] = TRACKED_PACKAGES) -> dict[str, str | None]:
    """Installed versions of ``names`` (None for packages that are not installed)."""
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


#: The pins ``make`` installs from: the versions the test-suite last passed with (a checkout's root).
CONSTRAINTS_FILE = Path(__file__).resolve().parent.parent / "constraints.txt"


def _canonical(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def read_constraints(path: str | Path) -> dict[str, str]:
    """``name==version`` pins of a pip constraints file (canonical names; comments skipped)."""
    pins = {}
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        line = line.split("#", 1)[0].strip()
        if "==" in line:
            name, version = line.split("==", 1)
            pins[_canonical(name.split("[")[0].strip())] = version.split(";")[0].strip()
    return pins


def constraints_status(path: str | Path | None = None) -> dict[str, Any] | None:
    """How the installed packages compare with the constraints file ``make`` installs from.

    Returns
    -------
    dict | None
        ``file``, its ``sha256``, the number of ``pinned`` packages and ``differs``: for each
        pinned package installed at another version (or missing), ``{"pinned": ..,
        "installed": ..}``; empty when the environment is the tested one. None where there is
        no constraints file (an installed wheel, not a checkout).
    """
    path = Path(path) if path is not None else CONSTRAINTS_FILE
    if not path.is_file():
        return None
    pins = read_constraints(path)
    installed = {_canonical(d.metadata["Name"] or ""): d.version for d in metadata.distributions()}
    differs = {name: {"pinned": v, "installed": installed.get(name)}
               for name, v in sorted(pins.items()) if installed.get(name) != v}
    return {"file": str(path), "sha256": file_sha256(path), "pinned": len(pins), "differs": differs}


def git_describe(path: str | Path | None = None) -> str | None:
    """``git describe --always --dirty`` of the checkout holding ``path`` (None outside git)."""
    where = Path(path) if path is not None else Path(__file__).resolve().parent
    try:
        res = subprocess.run(
            ["git", "describe", "--always", "--dirty", "--tags"],
            cwd=where, capture_output=True, text=True, timeout=10, check=False,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return res.stdout.strip() or None if res.returncode == 0 else None


def _input_entry(path: Path) -> dict[str, Any]:
    if path.is_file():
        return {"path": str(path), "sha256": file_sha256(path), "bytes": path.stat().st_size}
    if path.is_dir():
        files = sorted(p for p in path.rglob("*") if p.is_file())
        h = hashlib.sha256()
        for p in files:
            h.update(str(p.relative_to(path)).encode())
            h.update(file_sha256(p).encode())
        return {"path": str(path), "sha256": h.hexdigest(), "files": len(files)}
    return {"path": str(path), "sha256": None}


def provenance_record(
    *,
    argv: list[str] | None = None,
    inputs: Iterable[str | Path] = (),
    seed: int | dict[str, int] | None = None,
    started: str | None = None,
    ended: str | None = None,
    extra: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Build the provenance dictionary written to ``DIR/provenance.json``.

    Parameters
    ----------
    argv : list of str | None
        The command line (default: ``sys.argv``).
    inputs : iterable of path-like
        Input files or folders; each is hashed (folders: over all files inside).
    seed : int | dict of str to int | None
        The seed all randomness came from (a mapping when there are several; None when
        the command makes no random choices).
    started, ended : str | None
        ISO timestamps.
    extra : dict | None
        Anything else worth recording (e.g. the status of the run).

    Returns
    -------
    dict
        JSON-serialisable record.
    """
    return {
        "command": list(sys.argv if argv is None else argv),
        "inputs": [_input_entry(Path(p)) for p in inputs],
        "seed": seed,
        "versions": package_versions(),
        "constraints": constraints_status(),
        "git_describe": git_describe(),
        "platform": platform.platform(),
        "started": started,
        "ended": ended,
        **(extra or {}),
    }


def write_provenance(out_dir: str | Path, record: dict[str, Any]) -> Path:
    """Write ``record`` to ``out_dir/provenance.json`` atomically."""
    return atomic_write_text(Path(out_dir) / "provenance.json", json.dumps(record, indent=2, default=str) + "\n")
