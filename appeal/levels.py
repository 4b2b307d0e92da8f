"""Factor levels: how a level is compared, typed and ordered — one rule for the runner and the analysis.

A level written in a protocol or a manifest may be ``0``, ``0.0``, ``"0"``, ``true`` or
``"angry"``. The runner (:mod:`experiments`) compares levels as strings
(:func:`level_key`), the ERP analysis keeps numbers as numbers (:func:`level_value`); both
derive from one rule, so ``str(level_value(v)) == level_key(v)`` for every ``v``, and both
order levels with :func:`order_levels`: the order a protocol declares (``stimuli.levels``), then
:func:`sort_levels`.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

__all__ = ["level_key", "level_value", "sort_levels", "order_levels"]


def level_value(value: Any) -> int | float | str:
    """The typed form of a level: integer-valued numbers as ``int``, other numbers as ``float``,
    booleans as ``"true"``/``"false"``, text stripped (numeric text as in :func:`level_key`)."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (int, float)):
        return int(value) if float(value).is_integer() else float(value)
    return level_key(value)


def level_key(value: Any) -> str:
    """The string form a factor level is compared by (``0``, ``0.0`` and ``'0'`` are equal;
    ``True`` is ``'true'``)."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    text = str(value).strip()
    try:
        num = float(text)
    except ValueError:
        return text
    return str(int(num)) if num.is_integer() else text


def _natural(value: Any) -> tuple:
    text = level_key(value)
    try:
        return (0, float(text), "")
    except ValueError:
        m = re.match(r"^(\D*)(\d+)$", text)
        return (1, float(m.group(2)), m.group(1)) if m else (2, 0.0, text)


def sort_levels(levels: Iterable[Any]) -> list:
    """Levels in natural order: numeric ones by value, then ``name<number>`` by number
    (``c2`` before ``c10``), then the rest alphabetically. The values are returned as given."""
    return sorted(levels, key=_natural)


def order_levels(levels: Iterable[Any], declared: Iterable[Any] = ()) -> list:
    """Levels in a study's order: those ``declared`` first, in that order, then the rest by :func:`sort_levels`.

    Parameters
    ----------
    levels : iterable
        The levels present (repeats are dropped), as strings or typed values.
    declared : iterable, optional
        A declared order (a protocol's ``stimuli.levels`` entry); compared by :func:`level_key`, so
        ``0.5`` declared orders ``"0.5"`` present. Declared levels not present are left out.

    Returns
    -------
    list
        The present levels, as given.
    """
    rank: dict[str, int] = {}
    for i, value in enumerate(declared):
        rank.setdefault(level_key(value), i)
    present = list(dict.fromkeys(levels))
    first = sorted((v for v in present if level_key(v) in rank), key=lambda v: rank[level_key(v)])
    return first + sort_levels(v for v in present if level_key(v) not in rank)
