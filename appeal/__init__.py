"""Appeal Lab: the cross-cutting core (study files, outputs, provenance, parallel map, reports).

This package depends on none of the three rooms (``stimulus_engine``, ``experiments``,
``analysis``); only :mod:`appeal_cli` imports them.
"""

__version__ = "0.1.0"

from appeal.errors import AppealInputError, StudyFileError  # noqa: E402

__all__ = ["__version__", "AppealInputError", "StudyFileError"]
