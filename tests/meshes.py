"""Small test meshes shared by the correspondence tests."""

from __future__ import annotations

import numpy as np


def grid(n: int = 6, z=None, lo: float = 0.0, hi: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A regular n x n triangulated grid over [lo, hi]², heights ``z(x, y)`` (flat by default)."""
    x, y = np.meshgrid(np.linspace(lo, hi, n), np.linspace(lo, hi, n))
    v = np.column_stack([x.ravel(), y.ravel(), np.zeros(n * n) if z is None else z(x.ravel(), y.ravel())])
    f = []
    for i in range(n - 1):
        for j in range(n - 1):
            a = i * n + j
            f += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    return v, np.array(f)
