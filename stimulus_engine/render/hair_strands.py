"""Hair strands grown over a hair mesh, for the path tracer's true curves (thesis §2.4).

pyrender draws a hair style as its mesh of alpha-blended cards with a strand texture
(:func:`stimulus_engine.characters.render_parts.hair_render_part`). Cycles can do what a
rasteriser cannot: render each hair as a curve with a hair BSDF (Blender's Principled Hair,
Chiang et al. 2016, the successor of the Marschner model the thesis names). This module makes
those curves from the posed hair mesh itself, so they follow every expression and stylised
shape as the mesh does and fall where the texture draws hair:

- the combing direction is the one the strand texture was synthesised along
  (``scripts/make_hair_asset.py``): down the gradient of the distance to the hairline (the hair
  mesh's open border), on the surface;
- roots are spread over the mesh by area with a fixed random generator, kept where the texture's
  alpha has hair; each strand is traced along the combing direction, staying on the surface
  (closest point after every step), and ends where the texture's alpha ends (the hairline and its
  ragged tips) or at its length;
- each strand stands a random height above the mesh, along its outward normal: the strands form
  a layer of some thickness over the hair mesh, which stays beneath them as the
  undercoat (so the scalp does not show between a few ten thousand strands).

The roots are drawn as (triangle, barycentric weights), so the same seed gives the same strands
on every pose of the same mesh. Pure NumPy plus the package's closest-point search.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stimulus_engine.geometry.closest import SurfaceIndex
from stimulus_engine.geometry.mesh_ops import boundary_vertex_mask, face_normals, vertex_normals

__all__ = ["StrandSpec", "combing_directions", "grow_strands", "strand_tangents"]


@dataclass(frozen=True)
class StrandSpec:
    """How many strands, how long and how thick, in millimetres (converted with ``mm_per_unit``).

    Defaults: 40,000 strands of 35–65 mm in 8 segments, 0.07 mm radius at the root tapering to
    40 % at the tip, standing 0–3 mm above the hair mesh. Real scalps carry ~100,000 hairs about
    0.04 mm in radius; fewer and thicker ones over the textured mesh keep a 2-core render short.
    """

    count: int = 40000
    length_mm: tuple[float, float] = (35.0, 65.0)
    segments: int = 8
    radius_mm: float = 0.07
    tip_ratio: float = 0.4
    layer_mm: float = 3.0
    seed: int = 0


def _welded(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One vertex per position (the render mesh repeats vertices along its UV seams): welded
    vertices, faces on them, and each render vertex's welded index."""
    scale = float(np.ptp(vertices, axis=0).max()) or 1.0
    key = np.round(np.asarray(vertices, np.float64) / (scale * 1e-7)).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    return np.asarray(vertices, np.float64)[first], inverse[np.asarray(faces)], inverse


def _outward(vertices: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """``normals`` flipped, if need be, to point away from the mesh's centre (a hair mesh's
    winding says nothing: it is drawn double-sided)."""
    away = np.einsum("ij,ij->i", normals, vertices - vertices.mean(axis=0))
    return normals if away.sum() >= 0 else -normals


def combing_directions(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit combing direction at every vertex, and its distance to the hairline.

    The direction is minus the surface gradient of the (Euclidean) distance to the mesh's open
    border, averaged over the triangles around each vertex by area: hair runs from the crown
    towards the nearest hairline, as the strand texture's line-integral convolution runs.

    Parameters
    ----------
    vertices : (N, 3) array
        A welded hair mesh (one vertex per position).
    faces : (F, 3) int array

    Returns
    -------
    directions : (N, 3) array
        Unit tangent vectors (zero where the gradient vanishes).
    distance : (N,) array
    """
    from scipy.spatial import cKDTree

    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    rim = boundary_vertex_mask(f, len(v))
    if not rim.any():
        raise ValueError("the hair mesh has no open border (hairline) to comb towards")
    dist = cKDTree(v[rim]).query(v)[0]
    p0, p1, p2 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    n = np.cross(p1 - p0, p2 - p0)
    area2 = np.linalg.norm(n, axis=1)
    ok = area2 > 0
    nh = np.zeros_like(n)
    nh[ok] = n[ok] / area2[ok, None]
    d0, d1, d2 = dist[f[:, 0]], dist[f[:, 1]], dist[f[:, 2]]
    grad = (d0[:, None] * np.cross(nh, p2 - p1) + d1[:, None] * np.cross(nh, p0 - p2)
            + d2[:, None] * np.cross(nh, p1 - p0))
    grad[ok] /= area2[ok, None]
    acc = np.zeros_like(v)
    for k in range(3):  # area-weighted (the face gradient times twice its area)
        np.add.at(acc, f[:, k], -grad * area2[:, None])
    vn = vertex_normals(v, f)
    acc -= np.einsum("ij,ij->i", acc, vn)[:, None] * vn  # in the tangent plane
    length = np.linalg.norm(acc, axis=1)
    out = np.zeros_like(acc)
    out[length > 0] = acc[length > 0] / length[length > 0, None]
    return out, dist


def strand_tangents(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N, 3) unit combing direction at every vertex of a hair mesh as rendered (vertices may repeat
    along UV seams; they get the same direction): the tangents pyrender's Kajiya-Kay hair shading
    reads. Where the combing has no direction (the crown) any direction in the surface is taken."""
    wv, wf, inverse = _welded(np.asarray(vertices, np.float64), np.asarray(faces, np.int64))
    comb, _ = combing_directions(wv, wf)
    flat = np.linalg.norm(comb, axis=1) < 0.5
    if flat.any():
        n = vertex_normals(wv, wf)[flat]
        side = np.cross(n, [1.0, 0.0, 0.0])
        side[np.linalg.norm(side, axis=1) < 1e-6] = [0.0, 0.0, 1.0]
        comb[flat] = side / np.linalg.norm(side, axis=1, keepdims=True)
    return comb[inverse]


def _alpha_at(alpha: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """The texture's hair mask at UV points (OBJ convention: (0, 0) is the bottom-left)."""
    h, w = alpha.shape
    col = np.clip((uv[:, 0] * w).astype(np.int64), 0, w - 1)
    row = np.clip(h - 1 - (uv[:, 1] * h).astype(np.int64), 0, h - 1)
    return alpha[row, col]


def grow_strands(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray, alpha: np.ndarray, mm_per_unit: float,
                 spec: StrandSpec = StrandSpec()) -> tuple[np.ndarray, np.ndarray]:
    """Strands over a posed hair mesh (see the module docstring).

    Parameters
    ----------
    vertices : (N, 3) array
        The hair mesh as rendered (vertices may repeat along UV seams).
    faces : (F, 3) int array
    uv : (N, 2) array
        Its texture coordinates.
    alpha : (H, W) bool array
        Where its strand texture has hair.
    mm_per_unit : float
        Millimetres per scene unit.
    spec : StrandSpec

    Returns
    -------
    points : (P, 3) float32 array
        The strands' points one after another, each root first.
    sizes : (S,) int array
        Points per strand (2 to ``segments + 1``: a strand ends where the texture's hair does;
        roots on bare texels are dropped, so S ≤ ``spec.count``).
    radius : (P,) float32 array
        Tapering from root to tip.
    """
    v, f = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    uv = np.asarray(uv, np.float64)
    wv, wf, _ = _welded(v, f)
    comb, _ = combing_directions(wv, wf)
    normals = _outward(wv, vertex_normals(wv, wf))
    rng = np.random.default_rng(spec.seed)
    area = face_normals(v, f)[1]
    face = rng.choice(len(f), size=spec.count, p=area / area.sum())
    r1, r2 = rng.random(spec.count), rng.random(spec.count)
    s = np.sqrt(r1)
    bary = np.stack([1 - s, s * (1 - r2), s * r2], axis=1)
    lift = rng.random(spec.count) * spec.layer_mm / mm_per_unit
    length = rng.uniform(*spec.length_mm, size=spec.count) / mm_per_unit
    keep = np.asarray(alpha, bool)
    root_uv = np.einsum("nk,nkj->nj", bary, uv[f[face]])
    ok = _alpha_at(keep, root_uv)
    face, bary, lift, length = face[ok], bary[ok], lift[ok], length[ok]
    index = SurfaceIndex(v, f)
    n_seg = spec.segments
    surf = np.empty((len(face), n_seg + 1, 3))
    up = np.empty_like(surf)
    alive = np.ones(len(face), bool)
    counted = np.zeros(len(face), np.int64)  # segments each strand has inside the hair
    step = length / n_seg
    for k in range(n_seg + 1):
        wfk = wf[face]
        surf[:, k] = np.einsum("nk,nkj->nj", bary, v[f[face]])
        up[:, k] = np.einsum("nk,nkj->nj", bary, normals[wfk])
        if k > 0:  # a strand ends where it leaves the hair
            alive &= _alpha_at(keep, np.einsum("nk,nkj->nj", bary, uv[f[face]]))
            counted += alive
        if k == n_seg:
            break
        d = np.einsum("nk,nkj->nj", bary, comb[wfk])
        face_new, bary_new = index.closest(surf[:, k] + step[:, None] * d)
        face = np.where(alive, face_new, face)
        bary = np.where(alive[:, None], bary_new, bary)
    up /= np.maximum(np.linalg.norm(up, axis=2, keepdims=True), 1e-12)
    points = surf + lift[:, None, None] * up
    sizes = 1 + counted
    taper = 1.0 - (1.0 - spec.tip_ratio) * (np.arange(n_seg + 1)[None, :] / np.maximum(sizes - 1, 1)[:, None])
    radius = spec.radius_mm / mm_per_unit * taper
    used = (np.arange(n_seg + 1)[None, :] < sizes[:, None]) & (sizes[:, None] >= 2)
    return (points[used].astype(np.float32), sizes[sizes >= 2].astype(np.int64), radius[used].astype(np.float32))
