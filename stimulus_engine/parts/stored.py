"""A part bound to a rig (hair, a bust) as named arrays for the render cache's ``.npz``, and back.

Every field of the part's dataclass is stored under ``prefix + name``; a field whose default is
a tuple (a colour) comes back as a tuple of floats.
"""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

import numpy as np

__all__ = ["part_arrays", "part_from_arrays"]

T = TypeVar("T")


def part_arrays(part: Any | None, prefix: str) -> dict[str, np.ndarray]:
    """``part`` (a dataclass instance) as named arrays; empty for None."""
    if part is None:
        return {}
    return {prefix + f.name: np.asarray(getattr(part, f.name)) for f in dataclasses.fields(part)}


def part_from_arrays(cls: type[T], arrays: Any, prefix: str) -> T | None:
    """The ``cls`` stored by :func:`part_arrays` in ``arrays`` (a mapping or an npz), or None."""
    fields = dataclasses.fields(cls)
    if prefix + fields[0].name not in arrays:
        return None
    d = {f.name: arrays[prefix + f.name] for f in fields if prefix + f.name in arrays or f.default is dataclasses.MISSING}
    for f in fields:
        if f.name not in d:  # stored before the field was added: its default
            continue
        if isinstance(f.default, tuple):
            d[f.name] = tuple(float(c) for c in d[f.name])
        elif isinstance(f.default, bool):
            d[f.name] = bool(d[f.name])
    return cls(**d)
