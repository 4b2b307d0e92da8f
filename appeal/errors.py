"""Error types whose messages are shown to users as-is (one line per problem)."""

from __future__ import annotations

from collections.abc import Iterable


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
        self.lines: list[str] = [line.replace("\n", " ").strip() for line in lines]
        super().__init__("\n".join(self.lines))


class StudyFileError(AppealInputError):
    """A study file (grid, protocol, analysis config) failed to load or validate."""
