"""Tables out of the statistics: a DataFrame as JSON-ready records, and as a CSV file written
atomically (the folder made first)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from appeal.cells import write_table

__all__ = ["json_records", "write_csv"]


def json_records(df: pd.DataFrame) -> list[dict]:
    """Rows as dicts with NaN → None and numpy scalars → Python numbers and booleans (for JSON)."""
    out = []
    for rec in df.to_dict(orient="records"):
        clean = {}
        for k, v in rec.items():
            if isinstance(v, (np.floating, float)):
                v = None if math.isnan(v) else float(v)
            elif isinstance(v, np.integer):
                v = int(v)
            elif isinstance(v, np.bool_):
                v = bool(v)
            clean[k] = v
        out.append(clean)
    return out


def write_csv(df: pd.DataFrame, path: Path) -> Path:
    """``df`` as ``path`` (CSV, no index), its folder made first; returns the path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    write_table(df, path)
    return path
