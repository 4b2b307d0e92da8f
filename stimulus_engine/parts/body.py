"""A neck, shoulders and a plain garment under any character's head (thesis Fig. 2.1: the
model is completed "by adding eyes, teeth, hair and clothes").

The shipped bust (``stimulus_engine/data/body/``, rebuilt by ``scripts/make_body_asset.py``) is
MakeHuman's CC0 base mesh from under the jaw to the upper chest, arms lowered, each vertex marked
neck skin or garment (a crew neck). :func:`fit_body` puts it under a character:

1. **Placed** by the eyes: scaled by the ratio of the inter-ocular distances and moved so the
   eye midpoints meet.
2. **Covered or free.** Each neck-skin vertex of the bust is projected onto the character's
   skin. One whose closest skin point is inside the skin (not on its border) lies where the
   character already has a surface, and is dropped (the character's neck is drawn instead).
   The character's own skin below :data:`NECK_CUT_IOD` is hidden beforehand (:func:`neck_cut`),
   so the bust's garment, kept whole, is what shows below the neck.
3. **Joined.** The character's lower border (the *ring*: border vertices more than
   :data:`RING_BELOW_IOD` below the eyes) and the bust rarely meet. Each ring vertex's gap to
   the bust surface is spread over the free bust vertices by distance-weighted interpolation,
   fading out :data:`JOIN_REACH_IOD` below the ring, so the bust's surface passes through the
   ring: no gap, no step. Neck-skin faces that straddle the ring are kept, their covered
   corners sunk :data:`SINK_IOD` under the character's skin, so the join has no crack.

The result, :class:`Body`, is bound to the character's skin like the hair is: every vertex is a
fixed weighted sum of skin vertices (the ring's, or a skin triangle's) plus an offset, so the
bust follows expressions and stylised shapes with its seam closed. The neck skin is drawn with
the character's own albedo (each vertex takes the texture coordinate of the skin a little above
its ring point: the skin colour continues down the neck, and every material style restyles it
with the face); the garment with a knit texture times its colour.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from stimulus_engine.data import DATA_DIR
from stimulus_engine.parts.stored import part_arrays, part_from_arrays

__all__ = ["Body", "BustAsset", "DEFAULT_GARMENT", "NECK_CUT_IOD", "body_arrays", "body_from_arrays", "bust_asset", "clothes_faces",
           "fit_body", "neck_cut"]

_DATA = DATA_DIR / "body"
#: Default garment colour (linear RGB; multiplies the grey knit texture): a muted slate blue.
DEFAULT_GARMENT: tuple[float, float, float] = (0.09, 0.11, 0.15)
#: Where a character's own neck ends (inter-ocular distances below the eye centres; about 16 cm,
#: the middle of the neck): skin below it (an ICT rig's chest and shoulders, a scan's collar) is
#: hidden, and the bust's neck and garment take over.
NECK_CUT_IOD = 2.6
#: Border vertices at least this far below the eye centres form the ring (inter-ocular distances).
RING_BELOW_IOD = 1.6
#: Height of the garment over a character's own skin (inter-ocular distances; about 3 mm).
GARMENT_LIFT_IOD = 0.05
#: How far below the ring the join fades out.
JOIN_REACH_IOD = 1.5
#: Depth under the character's skin of the neck-skin corners it covers (hides the join's edge).
SINK_IOD = 0.04


@dataclass(frozen=True)
class BustAsset:
    """The shipped bust on MakeHuman's base mesh (decimetres, +y up, +z forward).

    Attributes
    ----------
    vertices : (M, 3) array
    faces : (F, 3) int array
    cloth : (M,) bool array
        Vertices of the garment (those on the neckline included).
    cloth_face : (F,) bool array
        Faces of the garment (the rest are neck skin).
    eyes : (2, 3) array
        The base mesh's right and left eye centres.
    texture : (H, W) uint8 array
        The garment's knit, grey.
    """

    vertices: np.ndarray
    faces: np.ndarray
    cloth: np.ndarray
    cloth_face: np.ndarray
    eyes: np.ndarray
    texture: np.ndarray


@functools.lru_cache(maxsize=1)
def bust_asset() -> BustAsset:
    """The shipped bust (see :class:`BustAsset`)."""
    from PIL import Image

    d = np.load(_DATA / "bust.npz")
    with Image.open(_DATA / "jersey.png") as im:
        tex = np.asarray(im.convert("L"))
    arrays = [d["vertices"].astype(np.float64), d["faces"].astype(np.int64), d["cloth"].astype(bool),
              d["cloth_face"].astype(bool), d["eyes"].astype(np.float64), tex]
    for a in arrays:
        a.setflags(write=False)
    return BustAsset(*arrays)


@dataclass(frozen=True)
class Body:
    """A bust bound to a character's skin.

    Attributes
    ----------
    anchors : (U,) int array
        The character's vertices the bust follows.
    weights : (M, U) float32 array
        Each bust vertex as a weighted sum of the anchors (rows sum to 1) ...
    offset : (M, 3) array
        ... plus this offset (the character's frame).
    faces : (F, 3) int array
    face_part : (F,) int array
        0: neck skin, 1: garment.
    uv : (M, 2) array
        Garment: coordinates in :attr:`texture`; neck skin: (angle around the neck / 2 pi, 0.5)
        in the neck's texture (:meth:`neck_texture`).
    ring_uv : (K, 2) array
        Where the neck's colour is taken from in the character's albedo: the skin a little
        above each ring vertex ...
    ring_angle : (K,) array
        ... at this angle around the neck (radians, 0 in front).
    texture : (H, W) uint8 array
        The garment's grey knit.
    colour : (3,) tuple of float
        Linear RGB of the garment.
    """

    anchors: np.ndarray
    weights: np.ndarray
    offset: np.ndarray
    faces: np.ndarray
    face_part: np.ndarray
    uv: np.ndarray
    texture: np.ndarray
    ring_uv: np.ndarray
    ring_angle: np.ndarray
    colour: tuple[float, float, float] = DEFAULT_GARMENT

    def neck_texture(self, albedo: np.ndarray, bins: int = 64) -> np.ndarray:
        """(2, bins, 3) uint8: the neck's colour around the neck, from ``albedo`` at the ring
        (the mean per angle bin, empty bins filled around the circle, smoothed)."""
        from scipy.ndimage import gaussian_filter1d

        colours = _texels(np.asarray(albedo)[..., :3], self.ring_uv).astype(np.float64)
        j = np.floor((self.ring_angle / (2 * np.pi) + 0.5) * bins).astype(np.int64) % bins
        total, count = np.zeros((bins, 3)), np.bincount(j, minlength=bins).astype(np.float64)
        np.add.at(total, j, colours)
        have = count > 0
        if not have.any():
            return np.full((2, bins, 3), 200, np.uint8)
        centres = np.flatnonzero(have)
        filled = np.stack([np.interp(np.arange(bins), centres, total[have, c] / count[have], period=bins)
                           for c in range(3)], axis=1)
        filled = gaussian_filter1d(filled, bins / 32, axis=0, mode="wrap")
        return np.repeat(np.rint(filled).astype(np.uint8)[None], 2, axis=0)

    def pose(self, rig_vertices: np.ndarray) -> np.ndarray:
        """(M, 3) bust vertices for a pose of the character it was fitted to."""
        rv = np.asarray(rig_vertices, np.float64)[self.anchors]
        return self.offset + self.weights.astype(np.float64) @ rv


def neck_cut(vertices: np.ndarray, faces: np.ndarray, skin: np.ndarray, eye_right: np.ndarray,
             eye_left: np.ndarray, below_iod: float = NECK_CUT_IOD) -> np.ndarray:
    """Skin faces (a mask over ``faces``; ``skin`` marks the skin faces) wholly lower than
    ``below_iod`` inter-ocular distances under the eyes: the character's neck ends there."""
    v = np.asarray(vertices, np.float64)
    return skin & (v[faces, 1] < _level(eye_right, eye_left, below_iod)).all(axis=1)


def clothes_faces(vertices: np.ndarray, faces: np.ndarray, skin: np.ndarray, uv: np.ndarray, face_uv: np.ndarray,
                  clothes: np.ndarray, eye_right: np.ndarray, eye_left: np.ndarray,
                  below_iod: float = RING_BELOW_IOD) -> np.ndarray:
    """Skin faces (a mask over ``faces``) lower than ``below_iod`` under the eyes whose texel at
    their UV centre is clothing (``clothes``: a soft mask over the texture, > 0.5): a scan's own
    collar, which the bust's garment replaces."""
    v = np.asarray(vertices, np.float64)
    low = v[faces, 1].max(axis=1) < _level(eye_right, eye_left, below_iod)
    return skin & low & (_texels(clothes, uv[face_uv].mean(axis=1)) > 0.5)


def _level(eye_right: np.ndarray, eye_left: np.ndarray, below_iod: float) -> float:
    """The height ``below_iod`` inter-ocular distances under the eye centres."""
    er, el = np.asarray(eye_right, np.float64), np.asarray(eye_left, np.float64)
    return float((er[1] + el[1]) / 2 - below_iod * np.linalg.norm(el - er))


def _texels(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """The texel of ``image`` nearest each texture coordinate (OBJ convention, v up; u = 0 and 1
    at the first and last texel's centre, as :mod:`stimulus_engine.characters.scan_eyes` samples)."""
    h, w = image.shape[:2]
    col = np.clip(np.rint(uv[:, 0] * (w - 1)), 0, w - 1).astype(np.int64)
    row = np.clip(np.rint((1 - uv[:, 1]) * (h - 1)), 0, h - 1).astype(np.int64)
    return image[row, col]


def _ring(vertices: np.ndarray, faces: np.ndarray, below: float) -> np.ndarray:
    """Border vertices of ``faces`` lower than ``below`` (the character's lower border)."""
    from stimulus_engine.geometry.mesh_ops import boundary_vertex_mask

    border = np.flatnonzero(boundary_vertex_mask(faces, len(vertices)))
    return border[vertices[border, 1] < below]


def _join_weights(points: np.ndarray, ring_points: np.ndarray, reach: float) -> np.ndarray:
    """(P, K) weights spreading each ring point's gap over ``points``: normalised inverse-square
    distance weights, times a smooth fade from 1 at the ring to 0 at ``reach`` from it."""
    d = np.linalg.norm(points[:, None, :] - ring_points[None, :, :], axis=2)
    w = 1.0 / np.maximum(d, 1e-3 * reach) ** 2
    w /= w.sum(axis=1, keepdims=True)
    t = np.clip(d.min(axis=1) / reach, 0, 1)
    return w * (1 - t * t * (3 - 2 * t))[:, None]


def _garment_uv(points: np.ndarray, eye_mid: np.ndarray, iod: float) -> np.ndarray:
    """Coordinates for the knit: a front projection (x, y; one texture repeat per inter-ocular
    distance), the knit seen square from the camera."""
    rel = points - eye_mid
    return np.stack([rel[:, 0] / iod, rel[:, 1] / iod], axis=1)


def fit_body(vertices: np.ndarray, skin_faces: np.ndarray, uv: np.ndarray, face_uv: np.ndarray,
             eye_right: np.ndarray, eye_left: np.ndarray,
             colour: tuple[float, float, float] | None = None) -> Body:
    """Put the shipped bust under a character (see the module docstring).

    Parameters
    ----------
    vertices : (N, 3) array
        The character's vertices (+y up, +z forward), rest pose.
    skin_faces : (S, 3) int array
        Its skin triangles.
    uv : (T, 2) array and face_uv : (all faces, 3) int array
        Its texture layout; ``face_uv`` rows for ``skin_faces`` are given as ``face_uv`` of
        the same rows (pass ``face_uv[skin]``).
    eye_right, eye_left : (3,) arrays
        Eye centres.
    colour : (3,) tuple of float, optional
        Linear RGB of the garment (default :data:`DEFAULT_GARMENT`).

    Returns
    -------
    Body
    """
    from stimulus_engine.geometry.closest import SurfaceIndex
    from stimulus_engine.geometry.mesh_ops import vertex_normals

    asset = bust_asset()
    v = np.asarray(vertices, np.float64)
    er, el = np.asarray(eye_right, np.float64), np.asarray(eye_left, np.float64)
    mid, iod = (er + el) / 2, float(np.linalg.norm(el - er))
    bmid, biod = asset.eyes.mean(axis=0), float(np.linalg.norm(asset.eyes[1] - asset.eyes[0]))
    p = (asset.vertices - bmid) * (iod / biod) + mid
    cloth = asset.cloth
    index = SurfaceIndex(v, skin_faces)
    hit = index.query(p)
    covered = ~hit.on_boundary & ~cloth  # the garment is never bound to the skin: its shape is the bust's
    normals = vertex_normals(v, skin_faces)
    ring = _ring(v, skin_faces, _level(er, el, RING_BELOW_IOD))

    # the bust, with each ring point's gap to it (to the garment: the garment's height over the
    # skin) spread around the ring
    if len(ring):
        bust_hit = SurfaceIndex(p, asset.faces).query(v[ring])
        near_cloth = cloth[asset.faces[bust_hit.face]].mean(axis=1) > 0.5
        lift = np.where(near_cloth, GARMENT_LIFT_IOD * iod, 0.0)[:, None] * normals[ring]
        gaps = v[ring] + lift - bust_hit.points
        join = _join_weights(p, bust_hit.points, JOIN_REACH_IOD * iod)
    else:
        gaps, join = np.zeros((0, 3)), np.zeros((len(p), 0))
    placed = p + join @ gaps

    # faces: garment everywhere; neck skin where not wholly covered by the character's skin
    fc = asset.cloth_face
    keep = fc | ~covered[asset.faces].all(axis=1)
    faces = asset.faces[keep]
    face_part = fc[keep].astype(np.int8)

    # anchors: ring vertices (free vertices) and skin triangles (covered ones)
    tri = skin_faces[hit.face]
    anchors = np.unique(np.concatenate([ring, tri[covered].ravel()])).astype(np.int64)
    weights = np.zeros((len(p), len(anchors)))
    offset = np.zeros_like(p)
    # covered neck corners: on their skin triangle, sunk under it
    rows = np.flatnonzero(covered)
    np.add.at(weights, (rows[:, None], np.searchsorted(anchors, tri[rows])), hit.bary[rows])
    n_hit = np.einsum("mk,mkd->md", hit.bary[rows], normals[tri[rows]])
    offset[rows] = -SINK_IOD * iod * n_hit / np.linalg.norm(n_hit, axis=1, keepdims=True)
    if len(ring):  # the rest: the join's weights on the ring, what they leave on the ring's centre
        free = np.flatnonzero(~covered)
        w = join[free] + (1.0 - join[free].sum(axis=1, keepdims=True)) / len(ring)
        weights[np.ix_(free, np.searchsorted(anchors, ring))] += w
    offset[~covered] = (placed - weights @ v[anchors])[~covered]  # no ring: the bust stands still

    # the neck's colour: the skin a little above the ring, by angle around the neck
    uvs = _garment_uv(placed, mid, iod)
    neck_axis = placed[~cloth].mean(axis=0) if (~cloth).any() else mid
    uvs[~cloth] = np.stack([_angle(placed[~cloth], neck_axis) / (2 * np.pi) + 0.5,
                            np.full(int((~cloth).sum()), 0.5)], axis=1)
    if len(ring):
        above = index.query(v[ring] + np.array([0.0, 0.15 * iod, 0.0]))
        ring_uv = np.einsum("nk,nkd->nd", above.bary, uv[face_uv[above.face]])
    else:
        ring_uv = np.zeros((0, 2))
    return Body(anchors, weights.astype(np.float32), offset, faces, face_part, uvs, asset.texture, ring_uv,
                _angle(v[ring], neck_axis), tuple(float(c) for c in (colour or DEFAULT_GARMENT)))


def _angle(points: np.ndarray, axis_point: np.ndarray) -> np.ndarray:
    """Angle of each point around a vertical axis through ``axis_point`` (0 in front, +z)."""
    rel = np.asarray(points, np.float64) - axis_point
    return np.arctan2(rel[:, 0], rel[:, 2])


def body_arrays(body: Body | None, prefix: str = "body_") -> dict[str, np.ndarray]:
    """``body`` as named arrays (for an ``.npz``; empty for none); see :func:`body_from_arrays`."""
    return part_arrays(body, prefix)


def body_from_arrays(arrays, prefix: str = "body_") -> Body | None:
    """The :class:`Body` stored by :func:`body_arrays` in ``arrays`` (a mapping or an npz), or None."""
    return part_from_arrays(Body, arrays, prefix)
