"""A continuum's levels: finding a level among them (what procedures and their states share)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from appeal.errors import AppealInputError

__all__ = ["level_index"]


def level_index(levels: NDArray, level: float) -> int:
    """Index of ``level`` among ``levels``; a one-line :class:`AppealInputError` when it is outside the
    continuum or not one of its levels."""
    lo, hi = float(levels[0]), float(levels[-1])
    tol = 1e-9 * max(hi - lo, 1.0)
    level = float(level)
    if not np.isfinite(level) or level < lo - tol or level > hi + tol:
        raise AppealInputError(f"level {level:g} is outside the continuum [{lo:g}, {hi:g}]")
    i = int(np.argmin(np.abs(levels - level)))
    if abs(levels[i] - level) > tol:
        raise AppealInputError(f"level {level:g} is not one of the {len(levels)} levels of the continuum "
                               f"[{lo:g}, {hi:g}]")
    return i
