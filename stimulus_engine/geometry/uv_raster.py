"""Rasterising a UV layout: which texture pixels each triangle covers, with barycentric weights.

The one rasteriser behind every texel-space operation: texture transfer, baked surface points,
the scan's eye and lid maps, gradient-domain blending and the hair asset's strand texture.
"""

from __future__ import annotations

import numpy as np

__all__ = ["rasterize_uv"]


_RASTER: list = []


def rasterize_uv(uv: np.ndarray, face_uv: np.ndarray, width: int, height: int):
    """Pixels covered by UV triangles: ``(rows, cols, face, bary)`` for each covered pixel centre.

    UV (0, 0) is the image's bottom-left corner (OBJ convention); a pixel is covered when its
    centre lies inside (or on) a triangle; the last triangle wins where UV islands overlap.
    The last result is kept for the same layout (by content) and size: a character's texture
    transfer rasterises its rig's layout once for the coverage mask and the re-laid maps.
    """
    import zlib

    key = (zlib.crc32(np.ascontiguousarray(uv, np.float64).tobytes()),
           zlib.crc32(np.ascontiguousarray(face_uv, np.int64).tobytes()), np.shape(uv), np.shape(face_uv), width, height)
    if _RASTER and _RASTER[0] == key:
        return _RASTER[1]
    out = _rasterize_uv(uv, face_uv, width, height)
    for a in out:
        a.setflags(write=False)  # shared by later calls
    _RASTER[:] = [key, out]
    return out


def _rasterize_uv(uv: np.ndarray, face_uv: np.ndarray, width: int, height: int):
    tri = uv[face_uv] * [width, height]  # F x 3 x 2 in pixel units, y up
    lo = np.floor(tri.min(axis=1) - 0.5).astype(np.int64)
    hi = np.ceil(tri.max(axis=1) - 0.5).astype(np.int64)
    lo = np.clip(lo, 0, [width - 1, height - 1])
    hi = np.clip(hi, 0, [width - 1, height - 1])
    nx = hi[:, 0] - lo[:, 0] + 1
    ny = hi[:, 1] - lo[:, 1] + 1
    counts = nx * ny
    fid = np.repeat(np.arange(len(face_uv)), counts)
    local = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    px = lo[fid, 0] + local % nx[fid]
    py = lo[fid, 1] + local // nx[fid]
    p = np.stack([px + 0.5, py + 0.5], axis=1)
    a, b, c = tri[fid, 0], tri[fid, 1], tri[fid, 2]
    v0, v1, v2 = b - a, c - a, p - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        w1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
        w2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    w0 = 1 - w1 - w2
    eps = -1e-9
    inside = (w0 >= eps) & (w1 >= eps) & (w2 >= eps) & np.isfinite(w1) & np.isfinite(w2)
    fid, px, py = fid[inside], px[inside], py[inside]
    bary = np.stack([w0[inside], w1[inside], w2[inside]], axis=1)
    rows = height - 1 - py  # image rows count from the top
    return rows, px, fid, bary
