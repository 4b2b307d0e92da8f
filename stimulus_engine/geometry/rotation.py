"""The smallest rotation taking one direction onto another (eyeball templates, aimed eyes)."""

from __future__ import annotations

import numpy as np

__all__ = ["rotation_onto"]


def rotation_onto(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The 3 × 3 rotation by the smallest angle that takes unit direction ``a`` onto unit direction ``b``.

    Opposite directions get half a turn about an axis across ``a``.

    Examples
    --------
    >>> np.round(rotation_onto(np.array([1.0, 0, 0]), np.array([0, 1.0, 0])) @ [1.0, 0, 0], 12).tolist()
    [0.0, 1.0, 0.0]
    """
    v, c = np.cross(a, b), float(a @ b)
    if c < -1 + 1e-12:
        p = np.eye(3)[np.argmin(np.abs(a))]
        k = np.cross(a, p) / np.linalg.norm(np.cross(a, p))
        return 2 * np.outer(k, k) - np.eye(3)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k / (1.0 + c)
