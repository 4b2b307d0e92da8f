"""Upper eyelashes for scans: a curled strip of alpha-blended lash cards along each upper lid.

A scan paints its lashes on the skin, so once its eyes are cut open (:mod:`stimulus_engine.characters.scan_eyes`)
the lid margin is bare. :func:`lash_strip` builds, along the upper lid contour, a strip of
:data:`ROWS` rows (root on the lid margin, a little in front of it; a middle row; the tips,
curled up and forward) whose length peaks two thirds of the way to the outer corner and falls to
a third at the inner one (two thirds at the outer); :func:`lash_texture` draws the lashes on it
(dark tapered strands, alpha-blended; they cast no shadow map, whose depth pass ignores alpha).
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["LASH_LENGTH", "ROWS", "lash_strip", "lash_texture"]

#: Rows of a strip: root, middle, tip.
ROWS = 3
#: Longest lash as a fraction of the eye's width (upper lashes are 8-12 mm on a 30 mm eye).
LASH_LENGTH = 0.3


def lash_strip(arc: np.ndarray, width: float, forward: np.ndarray = (0.0, 0.0, 1.0),
               up: np.ndarray = (0.0, 1.0, 0.0)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A lash strip along an upper lid.

    Parameters
    ----------
    arc : (K, 3) array
        The upper lid margin from one corner to the other.
    width : float
        The eye's width (corner to corner).
    forward, up : (3,) arrays
        The face's forward and up directions.

    Returns
    -------
    vertices : (ROWS * K, 3) array
        Row by row (row r, column k at ``r * K + k``).
    faces : (2 (ROWS - 1)(K - 1), 3) int array
    uv : (ROWS * K, 2) array
        u along the lid, v from root (0) to tip (1).
    """
    arc = np.asarray(arc, np.float64)
    fwd, up = np.asarray(forward, np.float64), np.asarray(up, np.float64)
    k = len(arc)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(arc, axis=0), axis=1))])
    t = s / s[-1]
    # longest past the middle, towards the outer corner (either end of the arc can be outer:
    # the one farther from the face's midline, x = 0 in the rig's frame)
    outer = t if abs(arc[-1, 0]) > abs(arc[0, 0]) else 1 - t
    length = LASH_LENGTH * width * (0.35 + 0.65 * np.sin(np.pi * outer / 1.3))  # longest 0.65 of the way out
    root = arc + 0.03 * width * fwd
    rows = [root,
            root + length[:, None] * 0.5 * (0.85 * fwd + 0.35 * up),
            root + length[:, None] * (0.6 * fwd + 0.8 * up)]
    v = np.vstack(rows)
    uv = np.column_stack([np.tile(t, ROWS), np.repeat(np.linspace(0, 1, ROWS), k)])
    faces = []
    for r in range(ROWS - 1):
        a = r * k + np.arange(k - 1)
        faces += [np.column_stack([a, a + 1, a + k + 1]), np.column_stack([a, a + k + 1, a + k])]
    return v, np.vstack(faces).astype(np.int64), uv


@functools.lru_cache(maxsize=2)
def lash_texture(size: int = 256, n_lashes: int = 55, seed: int = 0) -> np.ndarray:
    """(size, size, 4) uint8: dark tapered lashes from the root (v = 0, the bottom row) to the
    tip, slanting a little each; alpha is each lash's coverage (soft edges, blended)."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
    v = 1.0 - (yy + 0.5) / size  # row 0 is v = 1 (the tips)
    u = (xx + 0.5) / size
    alpha = np.zeros((size, size))
    roots = np.sort(rng.uniform(0.0, 1.0, n_lashes))
    for u0, slant, reach in zip(roots, rng.normal(0.0, 0.04, n_lashes), rng.uniform(0.6, 1.0, n_lashes)):
        centre = u0 + slant * v + 0.02 * v**2
        half = (1.5 / size) * np.clip(1.0 - v / reach, 0.0, 1.0) + 0.5 / size  # tapered to the tip
        edge = np.clip(1.0 - (np.abs(u - centre) - half) * size, 0.0, 1.0)  # one texel of soft edge
        alpha = np.maximum(alpha, edge * (v < reach))
    rgba = np.zeros((size, size, 4), np.uint8)
    rgba[..., :3] = (28, 20, 16)
    rgba[..., 3] = np.rint(255 * alpha)
    rgba.setflags(write=False)
    return rgba
