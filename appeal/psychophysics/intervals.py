"""Credible intervals from a posterior mass on a grid (shared by the adaptive procedures and the fits)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["credible_interval"]


def credible_interval(values: NDArray, mass: NDArray, level: float = 0.95) -> tuple[float, float]:
    """Equal-tailed credible interval from a marginal posterior mass on a grid.

    Each grid point's mass is spread evenly over its cell (from the midpoint to its left
    neighbour to the midpoint to its right one; the end cells reach half a spacing beyond the
    grid, clipped to the grid's ends), and the cumulative mass is interpolated linearly.
    """
    values, mass = np.asarray(values, float), np.asarray(mass, float)
    if len(values) == 1:
        return float(values[0]), float(values[0])
    mid = (values[1:] + values[:-1]) / 2
    edges = np.r_[values[0], mid, values[-1]]
    cdf = np.r_[0.0, np.cumsum(mass)] / mass.sum()
    a = (1 - level) / 2
    lo, hi = np.interp(a, cdf, edges), np.interp(1 - a, cdf, edges)
    return float(lo), float(hi)
