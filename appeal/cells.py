"""Text cells a spreadsheet would run as formulas (CSV/formula injection), neutralised.

A cell whose text starts with ``=``, ``+``, ``-``, ``@``, a tab or a carriage return is taken by
Excel, LibreOffice and Google Sheets as a formula (``=HYPERLINK(...)``, ``=cmd|' /C calc'!A0``,
``@SUM(...)``), so any text a participant could have typed or sent (a demographics answer, a
browser's user agent, a recruitment-site URL parameter) is written with a leading apostrophe
when it looks like one: the spreadsheet then shows it as text. Numbers (``-0.5``, ``+3``, ``1e-7``)
and a lone sign are not formulas and are written as they are. Every table the project writes goes
through :func:`neutralise` (:func:`write_table`, the session files' cell formatter), following the
OWASP advice on CSV injection.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from appeal.atomic import atomic_write_text

__all__ = ["FORMULA_PREFIXES", "formula_like", "neutralise", "neutralise_table", "write_table"]

#: First characters that make a spreadsheet cell a formula.
FORMULA_PREFIXES = ("=", "+", "-", "@", "\t", "\r")
_NUMBER = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?")


def formula_like(text: Any) -> bool:
    """Whether ``text`` (a str) would be run as a formula by a spreadsheet."""
    return (isinstance(text, str) and len(text) > 1 and text.startswith(FORMULA_PREFIXES)
            and _NUMBER.fullmatch(text) is None)


def neutralise(text: Any) -> Any:
    """``text`` with a leading apostrophe when it is formula-like; anything else unchanged."""
    return "'" + text if formula_like(text) else text


def neutralise_table(df: Any) -> Any:
    """A copy of DataFrame ``df`` whose text cells (and column names) are :func:`neutralise`\\ d;
    ``df`` itself when none is formula-like."""
    from pandas.api.types import is_object_dtype, is_string_dtype

    cols = [df.iloc[:, i] for i in range(df.shape[1])]
    bad = [i for i, col in enumerate(cols)
           if (is_object_dtype(col) or is_string_dtype(col)) and col.map(formula_like).any()]
    bad_names = any(formula_like(str(c)) for c in df.columns)
    if not bad and not bad_names:
        return df
    out = df.copy()
    for i in bad:
        out.isetitem(i, cols[i].map(neutralise))
    if bad_names:
        out.columns = [neutralise(str(c)) for c in out.columns]
    return out


def write_table(df: Any, path: str | Path, *, sep: str = ",", index: bool = False, **to_csv: Any) -> Path:
    """Write DataFrame ``df`` as CSV (or TSV with ``sep="\\t"``) atomically, text cells neutralised.

    Parameters
    ----------
    df : pandas.DataFrame
        The table.
    path : path-like
        The file (its folder must exist).
    sep : str
        Field separator.
    index : bool
        Write the index as the first column.
    **to_csv
        Further arguments of :meth:`pandas.DataFrame.to_csv` (``float_format``, ``na_rep`` ...).

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write_text(path, neutralise_table(df).to_csv(sep=sep, index=index, **to_csv))
