"""Progress bars that hide themselves when stderr is not a terminal or output is quiet."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

__all__ = ["progress", "set_quiet", "is_quiet", "progress_enabled"]

T = TypeVar("T")
_QUIET = False


def set_quiet(quiet: bool) -> None:
    """Hide (True) or allow (False) progress bars process-wide (``-q/--quiet``)."""
    global _QUIET
    _QUIET = bool(quiet)


def is_quiet() -> bool:
    """Whether progress output is switched off."""
    return _QUIET


def progress_enabled() -> bool:
    """True when a progress bar would be shown (not quiet, and stderr is a TTY)."""
    return not _QUIET and sys.stderr.isatty()


def progress(iterable: Iterable[T], *, total: int | None = None, desc: str | None = None, unit: str = "it") -> Iterator[T]:
    """Wrap ``iterable`` in a tqdm bar on stderr when :func:`progress_enabled`.

    Parameters
    ----------
    iterable : iterable
        What to iterate over.
    total : int | None
        Number of items, if ``iterable`` has no ``len``.
    desc : str | None
        Label in front of the bar.
    unit : str
        Unit name of one item.

    Yields
    ------
    object
        The items of ``iterable``.
    """
    from tqdm.auto import tqdm  # loaded with the first bar: every command imports this module at start-up

    yield from tqdm(iterable, total=total, desc=desc, unit=unit, disable=not progress_enabled(),
                    file=sys.stderr, dynamic_ncols=True, leave=False)
