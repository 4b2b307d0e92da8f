"""Embedded default assets: files shipped inside the package and the repository's folders.

The demo and the tests run on embedded defaults only (nothing is downloaded). Larger
third-party data are never embedded; users point commands at them with a path, and the
test-suite finds the shared data folder with :func:`shared_data_dir`.
"""

from __future__ import annotations

import os
from pathlib import Path

from appeal.errors import AppealInputError

__all__ = ["asset_path", "repo_root", "protocols_dir", "shared_data_dir"]

_ASSETS = Path(__file__).resolve().parent / "assets"

#: Environment variable pointing at a folder laid out like ``shared/data``.
DATA_ENV = "APPEAL_DATA"


def asset_path(name: str) -> Path:
    """Path of a file shipped in ``appeal/assets`` (raises a one-line error if absent)."""
    path = _ASSETS / name
    if not path.exists():
        raise AppealInputError(f"{path}: embedded asset '{name}' is missing from the installation")
    return path


def repo_root() -> Path:
    """The folder holding ``appeal/`` and ``protocols/`` (the checkout, for editable installs)."""
    return Path(__file__).resolve().parent.parent


def protocols_dir() -> Path:
    """The shipped ``protocols/`` folder."""
    return repo_root() / "protocols"


def shared_data_dir() -> Path | None:
    """The third-party data folder: ``$APPEAL_DATA``, else ``../shared/data`` beside the checkout."""
    env = os.environ.get(DATA_ENV)
    candidates = [Path(env)] if env else []
    candidates.append(repo_root().parent / "shared" / "data")
    for c in candidates:
        if c.is_dir():
            return c.resolve()
    return None
