"""BIDS labels: the one rule for every participant, session and task label a path is built from.

A label becomes part of a folder and file name (``sub-<label>/ses-<n>/beh/sub-<label>_...``), so a
label from a file, a query string, a manifest or the command line is checked here before any
path is built from it: letters and digits only (BIDS), at most :data:`MAX_LABEL` characters. The
lab runner, the web importer, the analysis readers and the web export share these functions.
"""

from __future__ import annotations

import re
from typing import Any

from appeal.errors import AppealInputError

__all__ = ["LABEL_PATTERN", "MAX_LABEL", "MAX_SESSION", "label_problem", "check_label", "check_session",
           "shown"]

#: A BIDS label: letters and digits, nothing else (no ``/``, ``.``, ``-``, ``_`` or space).
LABEL_PATTERN = re.compile(r"[A-Za-z0-9]+")
#: The longest label accepted (recruitment-site ids are 24 characters; longer is not an id).
MAX_LABEL = 64
#: The highest session number accepted.
MAX_SESSION = 9999


def shown(value: Any, width: int = 40) -> str:
    """``value`` as it may appear in a one-line message: quoted, control characters escaped, cut
    to ``width`` characters (a hostile value cannot break the line or colour the terminal)."""
    text = repr(str(value))
    return text if len(text) <= width else text[:width - 4] + "...'"


def label_problem(value: Any) -> str | None:
    """Why ``value`` is not a BIDS label (a phrase starting ``expected``), or None when it is one."""
    if not isinstance(value, str):
        return f"expected text (a BIDS label), not {type(value).__name__}"
    if len(value) > MAX_LABEL:
        return f"expected letters and digits only (a BIDS label) of at most {MAX_LABEL} characters"
    if not LABEL_PATTERN.fullmatch(value):
        return "expected letters and digits only (a BIDS label)"
    return None


def check_label(value: Any, field: str, where: str | None = None) -> str:
    """``value`` if it is a BIDS label, else a one-line :class:`AppealInputError`.

    Parameters
    ----------
    value : str
        The label (participant, session or task) as found.
    field : str
        What it is, as the message names it (``--participant``, ``column 'participant_id'``).
    where : str, optional
        The file (and line) it came from, put first in the message.

    Returns
    -------
    str
        ``value``, unchanged.
    """
    problem = label_problem(value)
    if problem is not None:
        msg = f"{field}: {problem}, got {shown(value)}"
        raise AppealInputError(f"{where}: {msg}" if where else msg)
    return value


def check_session(value: Any, field: str, where: str | None = None) -> int:
    """A session number (1 to :data:`MAX_SESSION`) from an int or its decimal text; else a one-line error."""
    number: int | None = None
    if isinstance(value, int) and not isinstance(value, bool):
        number = value
    elif isinstance(value, str) and re.fullmatch(r"[0-9]{1,4}", value):
        number = int(value)
    if number is None or not 1 <= number <= MAX_SESSION:
        msg = f"{field}: expected a session number from 1 to {MAX_SESSION}, got {shown(value)}"
        raise AppealInputError(f"{where}: {msg}" if where else msg)
    return number
