"""Smooth ramps between two values, for weights that fade in or out (joins, falloffs, vignettes)."""

from __future__ import annotations

import numpy as np

__all__ = ["smoothstep"]


def smoothstep(x: np.ndarray, lo: float = 0.0, hi: float = 1.0) -> np.ndarray:
    """0 at and below ``lo``, 1 at and above ``hi``, the cubic ``t * t * (3 - 2 t)`` between
    (``t`` the position of ``x`` from ``lo`` to ``hi``): zero slope at both ends."""
    t = np.clip((x - lo) / (hi - lo), 0.0, 1.0)
    return t * t * (3 - 2 * t)
