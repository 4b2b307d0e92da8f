"""Error types whose messages are shown to users as-is (one line per problem)."""

from __future__ import annotations

import re
from collections.abc import Iterable

#: Characters a message line never carries: line breaks, tabs and other control characters
#: (a value read from a hostile file cannot break the line or send terminal escapes).
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def _one_line(text: str) -> str:
    text = re.sub(r"[\n\r\t]", " ", text)
    return _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", text).strip()


class AppealInputError(Exception):
    """Bad input from a user: a file, a field or a value that is not what was expected.

    The ``appeal`` command prints the message (one line per problem, no traceback) and
    exits with status 2. Messages should name the file, the field and what was expected.
    """

    def __init__(self, message: str | Iterable[str]):
        if isinstance(message, str):
            lines = [message]
        else:
            lines = list(message)
        self.lines: list[str] = [_one_line(line) for line in lines]
        super().__init__("\n".join(self.lines))


class StudyFileError(AppealInputError):
    """A study file (grid, protocol, analysis config) failed to load or validate."""
