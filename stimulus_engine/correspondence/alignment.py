"""Closed-form similarity alignment (Umeyama 1991), used to initialise the registration."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from appeal.errors import AppealInputError

__all__ = ["Similarity", "umeyama"]


@dataclass(frozen=True)
class Similarity:
    """``x -> scale * R @ x + t``."""

    scale: float
    rotation: np.ndarray
    translation: np.ndarray

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Transform (N, 3) points."""
        return self.scale * np.asarray(points) @ self.rotation.T + self.translation

    def inverse(self) -> "Similarity":
        """The inverse transform."""
        rt = self.rotation.T
        return Similarity(1.0 / self.scale, rt, -(rt @ self.translation) / self.scale)

    @property
    def matrix(self) -> np.ndarray:
        """4 x 4 homogeneous matrix."""
        m = np.eye(4)
        m[:3, :3] = self.scale * self.rotation
        m[:3, 3] = self.translation
        return m


def umeyama(source: np.ndarray, target: np.ndarray, with_scale: bool = True) -> Similarity:
    """Least-squares similarity ``min Σ ||s R x_m + t - y_m||²`` in closed form.

    Parameters
    ----------
    source, target : (M, 3) arrays
        Corresponding points; M >= 3 and not all collinear.
    with_scale : bool
        False gives the best rigid motion (scale 1).

    Returns
    -------
    Similarity
        ``R`` is a proper rotation (det +1), also for reflected point sets.
    """
    x = np.asarray(source, dtype=np.float64)
    y = np.asarray(target, dtype=np.float64)
    if x.shape != y.shape or x.ndim != 2 or x.shape[1] != 3:
        raise AppealInputError(
            f"landmarks: expected two (M, 3) point sets of equal size (got {x.shape} and {y.shape})"
        )
    if len(x) < 3:
        raise AppealInputError(f"landmarks: need at least 3 correspondences for alignment (got {len(x)})")
    mx, my = x.mean(0), y.mean(0)
    xc, yc = x - mx, y - my
    var_x = (xc**2).sum() / len(x)
    cov = yc.T @ xc / len(x)
    u, d, vt = np.linalg.svd(cov)
    if d[1] < 1e-12 * max(d[0], 1e-300):
        raise AppealInputError("landmarks: correspondences are (nearly) collinear; alignment is undefined")
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        s[2, 2] = -1.0
    r = u @ s @ vt
    scale = float(np.trace(np.diag(d) @ s) / var_x) if with_scale else 1.0
    t = my - scale * r @ mx
    return Similarity(scale, r, t)
