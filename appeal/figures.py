"""Figures whose text is drawn as it is: labels from data are never read as matplotlib math.

Matplotlib reads a text with two ``$`` as mathtext (``$x^2$``), and a factor level, condition,
channel label or participant id read from a data file may hold them: ``$\\frac{$`` stopped a
figure with a ``ValueError``, and ``$a$`` would be drawn as math instead of the level's name.
Every function that makes or saves a figure of data runs under :func:`plain_text` (matplotlib's
``text.parse_math`` off for that call only, so a caller's own settings are left as they were).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, TypeVar

__all__ = ["plain_text"]

F = TypeVar("F", bound=Callable[..., Any])


def plain_text(func: F) -> F:
    """Run ``func`` with matplotlib's mathtext off (``rcParams['text.parse_math'] = False``)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        import matplotlib

        with matplotlib.rc_context({"text.parse_math": False}):
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
