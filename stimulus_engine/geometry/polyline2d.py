"""Small 2D curve helpers for cutting scans along facial contours (seen along +z): curves through
landmarks, inside tests, closest points, evening out the triangles around a cut, and keeping
a part (an eyeball, teeth) behind the skin in front of it."""

from __future__ import annotations

import numpy as np

__all__ = ["catmull_rom", "closest_on_polygon", "inside_polygon", "push_behind", "relax_around"]


def catmull_rom(p: np.ndarray, n: int) -> np.ndarray:
    """An open Catmull-Rom curve through ``p`` (end tangents mirrored), ``n`` samples per span."""
    q = np.vstack([2 * p[0] - p[1], p, 2 * p[-1] - p[-2]])
    t = np.linspace(0, 1, n, endpoint=False)[:, None]
    out = []
    for i in range(1, len(q) - 2):
        p0, p1, p2, p3 = q[i - 1], q[i], q[i + 1], q[i + 2]
        out.append(0.5 * (2 * p1 + (p2 - p0) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t**2
                          + (3 * p1 - p0 - 3 * p2 + p3) * t**3))
    return np.vstack(out)


def inside_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd test of 2D ``points`` against a closed 2D ``polygon``."""
    x, y = points[:, 0:1], points[:, 1:2]
    a, b = polygon, np.roll(polygon, -1, axis=0)
    crosses = ((a[:, 1] > y) != (b[:, 1] > y)) & (
        x < (b[:, 0] - a[:, 0]) * (y - a[:, 1]) / np.where(b[:, 1] == a[:, 1], 1e-300, b[:, 1] - a[:, 1]) + a[:, 0])
    return crosses.sum(axis=1) % 2 == 1


def closest_on_polygon(points: np.ndarray, polygon: np.ndarray, closed: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Where on a 2D polyline each of the 2D ``points`` is closest to it.

    Returns
    -------
    segment : (n,) int array
        The segment (from vertex ``segment`` to the next; the last one closes the polygon when
        ``closed``).
    t : (n,) array in [0, 1]
        The position along that segment.
    """
    a, b = (polygon, np.roll(polygon, -1, axis=0)) if closed else (polygon[:-1], polygon[1:])
    ab = b - a
    t = np.clip(((points[:, None, :] - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0, 1)
    q = a + t[..., None] * ab
    k = np.argmin(((points[:, None, :] - q) ** 2).sum(-1), axis=1)
    return k, t[np.arange(len(points)), k]


def relax_around(v: np.ndarray, faces: np.ndarray, contour: np.ndarray, fixed: np.ndarray,
                 near: np.ndarray, steps: int = 30, closed: bool = True,
                 band: float | None = None) -> None:
    """Even out, in place, a mesh's triangles around a cut after its rim moved onto ``contour``.

    The vertices within ``band`` of it (default a third of the contour's width; among ``near``;
    ``fixed`` held)
    take a few uniform-Laplacian steps in x, y: a rim vertex pulled far would otherwise fold its
    neighbours over (back-facing triangles show what is behind the cut).
    """
    from scipy import sparse

    band = float(np.ptp(contour[:, 0])) / 3 if band is None else band
    d = np.full(len(v), np.inf)
    idx = np.flatnonzero(near)
    k, t = closest_on_polygon(v[idx, :2], contour[:, :2], closed)
    a, b = contour[k, :2], (np.roll(contour, -1, axis=0) if closed else contour[1:])[k, :2]
    d[idx] = np.linalg.norm(v[idx, :2] - (a + t[:, None] * (b - a)), axis=1)
    free = d < band
    free[fixed] = False
    e = np.vstack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.vstack([e, e[:, ::-1]])
    adj = sparse.csr_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(len(v), len(v)))
    adj.data[:] = 1.0
    deg = np.asarray(adj.sum(axis=1)).ravel()
    move = np.flatnonzero(free & (deg > 0))
    for _ in range(steps):
        avg = adj[move] @ v[:, :2] / deg[move, None]
        v[move, :2] += 0.5 * (avg - v[move, :2])


def push_behind(points: np.ndarray, surface: np.ndarray, gap: float = 0.0,
                opening: np.ndarray | None = None) -> np.ndarray:
    """``points`` moved back (-z) until none lies in front of the surface sampled by ``surface``.

    Parameters
    ----------
    points : (n, 3) array
        A part that must stay behind the skin (an eyeball, teeth).
    surface : (m, 3) array
        Skin vertices around it; its depth at each point's (x, y) is interpolated linearly
        (points outside their hull are not checked).
    gap : float
        How far behind the skin the frontmost point ends.
    opening : (k, 3) array, optional
        A closed contour (seen along z) inside which the part may show (an eye's opening).

    Returns
    -------
    (n, 3) array
        ``points`` shifted as one along -z (unchanged when already behind).
    """
    from scipy.interpolate import LinearNDInterpolator

    p = np.asarray(points, np.float64)
    depth = LinearNDInterpolator(surface[:, :2], surface[:, 2])(p[:, :2])
    check = np.isfinite(depth)
    if opening is not None:
        check &= ~inside_polygon(p[:, :2], opening[:, :2])
    if not check.any():
        return p
    shift = max(0.0, float(np.max(p[check, 2] - depth[check])) + gap)
    return p - np.array([0.0, 0.0, shift])

