"""Logging to stderr and to ``DIR/log.txt`` (MNE-style ``verbose`` levels)."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

__all__ = ["logger", "set_log_level", "add_log_file", "remove_log_file"]

logger = logging.getLogger("appeal")
_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


class _CurrentStderrHandler(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is at the time of each message (not the stream of the
    moment the handler was made: a replaced and closed stderr — pytest's capture, a notebook —
    would otherwise turn every later message into a 'Logging error' traceback)."""

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        pass


def _stderr_handler() -> logging.Handler:
    for h in logger.handlers:
        if getattr(h, "_appeal_stderr", False):
            return h
    h = _CurrentStderrHandler()
    h.setFormatter(logging.Formatter("appeal: %(message)s"))
    h._appeal_stderr = True  # type: ignore[attr-defined]
    logger.addHandler(h)
    logger.propagate = False
    return h


def set_log_level(verbose: bool | int | str | None = None) -> None:
    """Set how much ``appeal`` logs to stderr.

    Parameters
    ----------
    verbose : bool | int | str | None
        True or "DEBUG" for everything, False or "WARNING" for warnings only, None or
        "INFO" for the default, or any :mod:`logging` level.
    """
    if verbose is True:
        level = logging.DEBUG
    elif verbose is False:
        level = logging.WARNING
    elif verbose is None:
        level = logging.INFO
    elif isinstance(verbose, str):
        level = logging.getLevelName(verbose.upper())
    else:
        level = int(verbose)
    logger.setLevel(logging.DEBUG)
    _stderr_handler().setLevel(level)


def add_log_file(path: str | Path) -> logging.Handler:
    """Also log (everything from INFO up) to ``path``; returns the handler to remove later."""
    _stderr_handler()
    handler = logging.FileHandler(path, encoding="utf-8")
    handler.setFormatter(logging.Formatter(_FORMAT))
    handler.setLevel(logging.INFO)
    logger.addHandler(handler)
    if logger.level == logging.NOTSET or logger.level > logging.INFO:
        logger.setLevel(logging.INFO)
    return handler


def remove_log_file(handler: logging.Handler) -> None:
    """Detach and close a handler made by :func:`add_log_file`."""
    logger.removeHandler(handler)
    handler.close()
