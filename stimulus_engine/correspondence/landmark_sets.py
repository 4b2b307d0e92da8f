"""68-point landmark sets: orderings, the registration subset and menpo LJSON files.

68-point landmark sets come in different orders; :func:`reorder_landmarks` converts between
them using the table in ``stimulus_engine/data/landmark_orderings.json``.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.data import DATA_DIR

__all__ = ["landmark_orderings", "reorder_landmarks", "read_ljson", "LANDMARK_SUBSET_16"]

_ORDERINGS = DATA_DIR / "landmark_orderings.json"


@lru_cache(maxsize=1)
def landmark_orderings() -> dict:
    """The table of 68-point orderings (``stimulus_engine/data/landmark_orderings.json``)."""
    return json.loads(_ORDERINGS.read_text())


def _to_ibug(name: str) -> np.ndarray:
    table = landmark_orderings()
    if name not in table or name.startswith("_") or name == "subsets":
        names = [k for k in table if not k.startswith("_") and k != "subsets"]
        raise AppealInputError(f"landmark ordering '{name}' is unknown (expected one of {', '.join(names)})")
    entry = table[name]
    if "same_as" in entry:
        entry = table[entry["same_as"]]
    return np.asarray(entry["to_ibug"], dtype=np.int64)


def reorder_landmarks(points, source: str, target: str = "ibug68"):
    """Re-order a 68-point landmark array from ordering ``source`` to ordering ``target``.

    ``points`` has 68 rows (any trailing shape): row ``k`` is point ``k`` of ``source``.
    """
    pts = np.asarray(points)
    if len(pts) != 68:
        raise AppealInputError(f"landmarks: expected 68 points for ordering '{source}' (got {len(pts)})")
    s2i = _to_ibug(source)
    t2i = _to_ibug(target)
    ibug = np.empty_like(pts)
    ibug[s2i] = pts
    return ibug[t2i]


#: 16 well-spread iBUG indices (jaw, brow ends, nose, eye and mouth corners) used for
#: registration; the other 52 are held out for checking.
LANDMARK_SUBSET_16 = np.asarray(landmark_orderings()["subsets"]["ibug16"]["ibug"], dtype=np.int64)


def read_ljson(path) -> tuple[np.ndarray, str]:
    """3D points of a menpo LJSON landmark file and the ordering name (``menpo_ljson``)."""
    path = Path(path)
    if not path.exists():
        raise AppealInputError(f"{path}: landmark file not found")
    try:
        d = json.loads(path.read_text())
        groups = d["groups"]
        g = next(iter(groups.values()))
        pts = np.asarray(g["landmarks"]["points"], dtype=np.float64)
        labels = [lab["label"] for lab in g.get("labels", [])]
    except (json.JSONDecodeError, KeyError, StopIteration, TypeError, ValueError) as exc:
        raise AppealInputError(f"{path}: groups.*.landmarks.points: expected a menpo LJSON landmark file ({exc})") from None
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise AppealInputError(f"{path}: landmarks.points: expected 3D points (got shape {pts.shape})")
    ordering = "menpo_ljson" if labels[:2] == ["chin", "leye"] and len(pts) == 68 else "ibug68"
    return pts, ordering
