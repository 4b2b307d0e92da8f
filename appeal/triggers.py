"""The trigger-code table of a protocol: code -> the condition it marks.

The runner sends these codes (:mod:`experiments`) and the ERP analysis reads them back from the
same protocol file (:mod:`analysis.erp`); both validate and normalise the table here, so the
codes they use cannot disagree.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from appeal.levels import level_key

__all__ = ["CODE_RANGE", "trigger_table"]

#: Codes an 8-bit trigger port can send (0 is the reset value).
CODE_RANGE = (1, 255)


def trigger_table(entries: Sequence[Mapping[str, Any]]) -> dict[int, dict[str, Any]]:
    """Validate ``triggers.codes`` entries ``{code: 11, <factor>: <level>, ...}``.

    Parameters
    ----------
    entries : sequence of mappings
        As written in the protocol.

    Returns
    -------
    dict
        code -> {factor: level as written}, in the entries' order. Compare or store levels
        through :func:`appeal.levels.level_key` / :func:`appeal.levels.level_value`.

    Raises
    ------
    ValueError
        ``codes[i]: ...`` for the first bad entry: not a mapping, no code, a code that is not an
        integer in :data:`CODE_RANGE`, a code used twice, no factor level, or a condition (its
        levels compared by :func:`~appeal.levels.level_key`) that already has a code.
    """
    if not isinstance(entries, Sequence) or isinstance(entries, (str, bytes)) or not entries:
        raise ValueError("expected a non-empty list of {code: INT, <factor>: <level>, ...} mappings")
    lo, hi = CODE_RANGE
    table: dict[int, dict[str, Any]] = {}
    where_code: dict[int, int] = {}
    conditions: dict[tuple, int] = {}
    for i, entry in enumerate(entries):
        if not isinstance(entry, Mapping):
            raise ValueError(f"codes[{i}]: expected a mapping {{code: INT, <factor>: <level>, ...}} (got {entry!r})")
        if "code" not in entry:
            raise ValueError(f"codes[{i}]: expected a 'code' key (got {sorted(map(str, entry))})")
        code = entry["code"]
        if isinstance(code, bool) or not isinstance(code, int) or not lo <= code <= hi:
            raise ValueError(f"codes[{i}]: code must be an integer {lo}-{hi} (got {code!r})")
        if code in where_code:
            raise ValueError(f"codes[{i}]: code {code} is used twice (also codes[{where_code[code]}])")
        where_code[code] = i
        levels = {str(k): v for k, v in entry.items() if k != "code"}
        cond = tuple(sorted((k, level_key(v)) for k, v in levels.items()))
        if not cond:
            raise ValueError(f"codes[{i}]: code {code} names no factor level")
        if cond in conditions:
            raise ValueError(f"codes[{i}]: condition {dict(cond)} already has a code (codes[{conditions[cond]}])")
        conditions[cond] = i
        table[code] = levels
    return table
