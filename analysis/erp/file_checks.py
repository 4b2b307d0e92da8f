"""What every recording reader checks before a file is opened: a regular file, read errors as one line.

Recordings come from devices and other labs, so they are untrusted input; see
:mod:`analysis.erp.io` for the checks of each format.
"""

from __future__ import annotations

import os
import re
import stat
from contextlib import contextmanager
from pathlib import Path

from appeal.errors import AppealInputError

__all__ = ["MAX_SFREQ_HZ", "check_regular_file", "not_regular", "readable"]

#: The fastest sampling rate accepted (Hz): filter lengths grow with it.
MAX_SFREQ_HZ = 1_000_000
DECIMAL = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]{1,3})?")
CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")

def not_regular(path: Path) -> str | None:
    """Why ``path`` is no regular file to read (a phrase), or None (a symbolic link is followed)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "not found"
    except OSError as exc:
        return f"cannot be read ({exc.strerror})"
    if stat.S_ISDIR(mode):
        return "is a folder, not a file"
    if not stat.S_ISREG(mode):
        return "is a device, pipe or socket, not a regular file"
    return None


def check_regular_file(path: str | Path) -> None:
    """Check that ``path`` is a regular file (a symbolic link is followed) before anything opens it.

    A folder, a device (``/dev/zero`` would read forever), a pipe (opening it waits for a writer)
    or a socket named like a recording is refused.

    Raises
    ------
    AppealInputError
        When the file is missing or not a regular file.
    """
    why = not_regular(Path(path))
    if why == "not found":
        raise AppealInputError(f"{path}: recording not found")
    if why:
        raise AppealInputError(f"{path}: {why} (expected a recording file)")


@contextmanager
def readable(path: Path):
    """Turn an operating-system error while checking ``path`` (permissions, a file that vanished)
    into a one-line :class:`~appeal.errors.AppealInputError`."""
    try:
        yield
    except OSError as exc:
        raise AppealInputError(f"{path}: cannot be read ({exc.strerror or type(exc).__name__})") from None
