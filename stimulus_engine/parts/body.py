"""A neck, shoulders and a plain garment under any character's head (thesis Fig. 2.1: the
model is completed "by adding eyes, teeth, hair and clothes").

The shipped bust (``stimulus_engine/data/body/``, rebuilt by ``scripts/make_body_asset.py``) is
MakeHuman's CC0 base mesh from under the jaw to the upper chest, arms lowered, each vertex marked
neck skin or garment (a crew neck). :func:`fit_body` puts it under a character:

1. **Placed** by the eyes: scaled by the ratio of the inter-ocular distances and moved so the
   eye midpoints meet.
2. **Covered or free.** A neck-skin vertex of the bust higher than the character's lower
   border reaches around it (the highest border point within :data:`COLLAR_WINDOW_DEG`;
   :data:`FREE_BELOW_IOD` lower where that border is under the garment, :data:`TUCK_IOD` higher
   where the bust's neck continues it, tucked behind the character's skin) lies
   where the character already has a neck, and is dropped (the character's neck is drawn
   instead): only below a character's border (a scan that ends above the neckline) does the
   bust's neck show, behind the scan's own neck where that goes on lower.
   The character's own skin under the garment, more than :data:`UNDER_GARMENT_IOD` inside its
   neckline, is hidden beforehand (:func:`under_garment`): the character's neck goes on a little
   under the garment's edge, so where it ends is never seen, and the garment, kept whole, is what
   shows below the neck. A scan's own collar is hidden with everything below its top edge
   (:func:`clothes_faces`), so the scan ends in a clean line there and the bust's neck
   continues it down to the garment.
3. **Joined.** The character's lower border (the *ring*: border vertices more than
   :data:`RING_BELOW_IOD` below the eyes) and the bust rarely meet, nor does the garment's
   neckline sit on a character's own neck. Each ring vertex's gap to the bust surface, and each
   neckline vertex's gap to the neck beside it (within :data:`HUG_REACH_IOD`), is spread over
   the free bust vertices by distance-weighted interpolation, fading out
   :data:`JOIN_REACH_IOD` away, so the bust's surface passes just behind the ring (:data:`SINK_IOD`
   under it: through it, slivers of background showed between a scan's ragged border and the
   neck) and the collar hugs the neck: no gap, no step. Neck-skin faces that straddle the ring are kept, their covered
   corners sunk :data:`SINK_IOD` under the character's skin, so the join has no crack.

The result, :class:`Body`, is bound to the character's skin like the hair is: every vertex is a
fixed weighted sum of skin vertices (the ring's, or a skin triangle's) plus an offset, so the
bust follows expressions and stylised shapes with its seam closed. The neck skin is drawn with
the character's own albedo (each vertex takes the texture coordinate of the skin a little above
its ring point, on skin texels only: the skin colour continues down the neck, and every material
style restyles it with the face); the garment with a knit texture times its colour. A scan's
skin fades into that colour toward its border (:func:`fade_into_neck`), so its ragged outline
is not drawn in a colour of its own.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from stimulus_engine.data import DATA_DIR
from stimulus_engine.parts.stored import part_arrays, part_from_arrays

__all__ = ["Body", "BustAsset", "DEFAULT_GARMENT", "NECK_SPAN_IOD", "NECK_TEXTURE_SIZE", "UNDER_GARMENT_IOD", "body_arrays", "body_from_arrays", "bust_asset", "clothes_faces",
           "fade_into_neck", "fit_body", "neck_axis", "neckline", "placed_bust", "texel_index", "under_garment"]

_DATA = DATA_DIR / "body"
#: Default garment colour (linear RGB; multiplies the grey knit texture): a muted slate blue.
DEFAULT_GARMENT: tuple[float, float, float] = (0.09, 0.11, 0.15)
#: The bust's neck goes on this far above the base mesh's cut under the jaw (iod; see
#: :func:`_neck_extended`).
NECK_EXTENSION_IOD = 0.3
#: ... at the sides and back only: beyond this angle from the front around the neck's axis
#: (degrees; under the chin, the extension came through james's chin).
NECK_EXTENSION_FROM_DEG = 30.0
#: The garment goes on this far straight down below the base mesh's cut across the chest (iod; see
#: :func:`_hem_extended`): a designed cartoon's larger head is framed from further away, and its
#: bust's cut edge, 5.3 iod under the eyes, came into the picture (Lee Perry-Smith's cartoon).
HEM_EXTENSION_IOD = 6.0
#: The crew neckline, in inter-ocular distances (iod) below the eye centres: lowest in front
#: (just above the sternal notch), highest at the back (the seventh vertebra); and its radius
#: from the neck's axis, where it crosses the slope of the shoulders at the sides.
NECKLINE_FRONT_IOD, NECKLINE_BACK_IOD, NECKLINE_RADIUS_IOD = 3.05, 2.45, 1.3
#: The neck's axis is found at this depth below the eyes, half a neck's depth behind its front
#: (iod; MakeHuman's base neck: 11 cm deep).
NECK_AXIS_IOD, NECK_HALF_DEPTH_IOD = 2.6, 0.9
#: How far under the garment a character's own skin goes on before it is hidden (inter-ocular
#: distances inside the neckline; about 1.3 cm).
UNDER_GARMENT_IOD = 0.2
#: A scan's collar is hidden with everything under its top edge, taken as the highest collar
#: point within this angle around the neck (the bust's neck likewise shows below the highest
#: border point within it), plus this margin (inter-ocular distances).
COLLAR_WINDOW_DEG, COLLAR_MARGIN_IOD = 25.0, 0.05
#: A face is the collar where the clothing mask at its centre exceeds this (the mask's blurred
#: edge included: above 0.5 only, light collar-edge texels were left on james's neck).
COLLAR_MASK_LEVEL = 0.2
#: Border vertices at least this far below the eye centres form the ring (inter-ocular distances).
RING_BELOW_IOD = 1.6
#: Height of the garment over a character's own skin (inter-ocular distances; about 3 mm).
GARMENT_LIFT_IOD = 0.05
#: How far below the ring the join fades out.
JOIN_REACH_IOD = 1.5
#: The bust's neck shows from this far below a border under the garment, and goes on this far
#: above a border it continues, tucked behind the character's skin, so no crack opens between
#: the two (iod).
FREE_BELOW_IOD, TUCK_IOD = 0.15, 0.3
#: The collar's rib: its edge stands this much further off the neck than the garment elsewhere
#: (iod; with it, the collar's edge closes over the neck's sides where they meet the shoulders).
COLLAR_RIB_IOD = 0.05
#: The bust's neck takes its colour from the skin this far above the border it continues (iod).
#: Nearer, a scan's border held the blurred edge of its collar, until that was hidden from mask
#: level 0.2; further (0.35), james's neck took the colour of his beard, olive under a pale
#: border, and the border's ragged outline showed.
NECK_COLOUR_ABOVE_IOD = 0.1
#: A scan's skin fades into the neck's colour toward the lower border the bust's neck continues:
#: wholly within the first distance of that border, not at all from the second (iod). The
#: border of a scan is ragged (james's ends in torn tufts under his chin, in texels paler than
#: his skin); faded, its outline lies on a neck of its own colour (a step in the shading remains).
NECK_FADE_IOD = (0.15, 0.6)
#: A texel is skin (a sample of the neck's colour, a texel to fade) where the skin weight of the
#: albedo's region masks (:func:`~stimulus_engine.characters.scan_regions.skin_texels`)
#: exceeds this.
SKIN_TEXEL_LEVEL = 0.5
#: The garment's neckline hugs the character's neck where the neck is within this distance of it.
HUG_REACH_IOD = 1.1
#: Depth under the character's skin of the neck-skin corners it covers (hides the join's edge).
SINK_IOD = 0.04
#: The neck's texture (rows, columns), :data:`NECK_SPAN_IOD` square, seen from the front
#: (:mod:`stimulus_engine.characters.neck_skin` paints it): a texel is 0.006 iod (0.4 mm).
NECK_TEXTURE_SIZE = (640, 640)
NECK_SPAN_IOD = 4.0


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
    axis : (3,) array
        A point on the neck's axis (:func:`neck_axis`).
    """

    vertices: np.ndarray
    faces: np.ndarray
    cloth: np.ndarray
    cloth_face: np.ndarray
    eyes: np.ndarray
    texture: np.ndarray
    axis: np.ndarray


@functools.lru_cache(maxsize=1)
def bust_asset() -> BustAsset:
    """The shipped bust (see :class:`BustAsset`)."""
    from PIL import Image

    d = np.load(_DATA / "bust.npz")
    with Image.open(_DATA / "jersey.png") as im:
        tex = np.asarray(im.convert("L"))
    vertices, faces, cloth, cloth_face = _neck_extended(d["vertices"].astype(np.float64), d["faces"].astype(np.int64),
                                                        d["cloth"].astype(bool), d["cloth_face"].astype(bool),
                                                        d["eyes"].astype(np.float64), d["axis"].astype(np.float64))
    vertices, faces, cloth, cloth_face = _hem_extended(vertices, faces, cloth, cloth_face, d["eyes"].astype(np.float64))
    arrays = [vertices, faces, cloth, cloth_face, d["eyes"].astype(np.float64), tex, d["axis"].astype(np.float64)]
    for a in arrays:
        a.setflags(write=False)
    return BustAsset(*arrays)


def _hem_extended(vertices: np.ndarray, faces: np.ndarray, cloth: np.ndarray, cloth_face: np.ndarray,
                  eyes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The bust with the garment's open lower edge (the base mesh's cut across the chest) extruded
    straight down by :data:`HEM_EXTENSION_IOD`: (vertices, faces, cloth, cloth_face), the new
    vertices and faces garment."""
    from stimulus_engine.geometry.mesh_ops import boundary_half_edges

    edges = boundary_half_edges(faces)
    edges = edges[cloth[edges].all(axis=1)]
    bottom = np.unique(edges)
    new = np.full(len(vertices), -1, np.int64)
    new[bottom] = len(vertices) + np.arange(len(bottom))
    drop = HEM_EXTENSION_IOD * float(np.linalg.norm(eyes[1] - eyes[0]))
    a, b = edges[:, 0], edges[:, 1]
    quads = np.concatenate([np.stack([b, a, new[a]], axis=1), np.stack([b, new[a], new[b]], axis=1)])
    return (np.concatenate([vertices, vertices[bottom] - [0.0, drop, 0.0]]), np.concatenate([faces, quads]),
            np.concatenate([cloth, np.ones(len(bottom), bool)]), np.concatenate([cloth_face, np.ones(len(quads), bool)]))


def _neck_extended(vertices: np.ndarray, faces: np.ndarray, cloth: np.ndarray, cloth_face: np.ndarray,
                   eyes: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The bust with its neck's open top edge (the base mesh's cut under the jaw) extruded
    straight up by :data:`NECK_EXTENSION_IOD` at the sides and back (beyond
    :data:`NECK_EXTENSION_FROM_DEG` around the neck's ``axis``): (vertices, faces, cloth, cloth_face), the new
    vertices and faces neck skin. Where a character's border lies above the bust's own edge
    (james's ragged border reaches 0.1 iod higher than the bust's edge under his ear), the
    extension goes on behind it, as the bust's neck does elsewhere (:data:`TUCK_IOD`)."""
    from stimulus_engine.geometry.mesh_ops import boundary_half_edges

    edges = boundary_half_edges(faces)
    edges = edges[~cloth[edges].any(axis=1)]  # the neck's top (the garment's edges are its own)
    rel = vertices - axis
    side = np.abs(np.degrees(np.arctan2(rel[:, 0], rel[:, 2]))) > NECK_EXTENSION_FROM_DEG
    edges = edges[side[edges].all(axis=1)]  # not under the chin (it came through james's)
    top = np.unique(edges)
    new = np.full(len(vertices), -1, np.int64)
    new[top] = len(vertices) + np.arange(len(top))
    lift = NECK_EXTENSION_IOD * float(np.linalg.norm(eyes[1] - eyes[0]))
    a, b = edges[:, 0], edges[:, 1]  # each as it runs in its face: the new quad runs b -> a
    quads = np.concatenate([np.stack([b, a, new[a]], axis=1), np.stack([b, new[a], new[b]], axis=1)])
    return (np.concatenate([vertices, vertices[top] + [0.0, lift, 0.0]]), np.concatenate([faces, quads]),
            np.concatenate([cloth, np.zeros(len(top), bool)]), np.concatenate([cloth_face, np.zeros(len(quads), bool)]))


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
        Coordinates in the garment's :attr:`texture` (every vertex).
    neck_uv : (M, 2) array
        Coordinates in the neck's texture
        (:func:`stimulus_engine.characters.neck_skin.neck_texture`), every vertex (the neckline's own
        vertices are corners of neck and garment faces): seen from the front (a planar projection:
        the neck is drawn from the front, and its mottle keeps its size in the picture where the
        neck turns away) and in units of :data:`NECK_SPAN_IOD`, sideways from the neck's middle
        (0.5) and down from its highest point (0).
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
    neck_uv: np.ndarray
    texture: np.ndarray
    ring_uv: np.ndarray
    ring_angle: np.ndarray
    colour: tuple[float, float, float] = DEFAULT_GARMENT

    def front_colours(self, albedo: np.ndarray) -> np.ndarray:
        """(columns of :data:`NECK_TEXTURE_SIZE`, 3) float: the neck's colour (:meth:`neck_colours`)
        in each column of its texture, the angle around the neck that shows there from the front
        (``arcsin`` of the offset from the middle over the neck's half width)."""
        colours = self.neck_colours(albedo).astype(np.float64)
        cols = NECK_TEXTURE_SIZE[1]
        neck = np.unique(self.faces[self.face_part == 0])
        half = float(np.abs(self.neck_uv[neck, 0] - 0.5).max()) if len(neck) else 0.25
        x = (np.arange(cols) + 0.5) / cols - 0.5
        angle = np.arcsin(np.clip(x / max(half, 1e-6), -1.0, 1.0))
        k = (angle / (2 * np.pi) + 0.5) * len(colours) - 0.5
        return np.stack([np.interp(k, np.arange(len(colours)), colours[:, c], period=len(colours))
                         for c in range(3)], axis=1)

    def neck_colours(self, albedo: np.ndarray, bins: int = 64) -> np.ndarray:
        """(bins, 3) uint8: the neck's colour around the neck, from ``albedo`` at the ring
        (the mean per angle bin, empty bins filled around the circle, smoothed); bin ``k`` is the
        angle ``2 pi (k + 0.5) / bins - pi``."""
        from scipy.ndimage import gaussian_filter1d

        colours = _texels(np.asarray(albedo)[..., :3], self.ring_uv).astype(np.float64)
        j = _angle_bin(self.ring_angle, bins)
        total, count = np.zeros((bins, 3)), np.bincount(j, minlength=bins).astype(np.float64)
        np.add.at(total, j, colours)
        have = count > 0
        if not have.any():
            return np.full((bins, 3), 200, np.uint8)
        centres = np.flatnonzero(have)
        filled = np.stack([np.interp(np.arange(bins), centres, total[have, c] / count[have], period=bins)
                           for c in range(3)], axis=1)
        filled = gaussian_filter1d(filled, bins / 12, axis=0, mode="wrap")  # no streaks down the neck
        return np.rint(filled).astype(np.uint8)

    def pose(self, rig_vertices: np.ndarray) -> np.ndarray:
        """(M, 3) bust vertices for a pose of the character it was fitted to."""
        rv = np.asarray(rig_vertices, np.float64)[self.anchors]
        return self.offset + self.weights.astype(np.float64) @ rv


def clothes_faces(vertices: np.ndarray, faces: np.ndarray, skin: np.ndarray, uv: np.ndarray, face_uv: np.ndarray,
                  clothes: np.ndarray, eye_right: np.ndarray, eye_left: np.ndarray,
                  below_iod: float = RING_BELOW_IOD, margin_iod: float = COLLAR_MARGIN_IOD) -> np.ndarray:
    """Skin faces (a mask over ``faces``) of a scan's own collar and below it.

    The collar: faces lower than ``below_iod`` under the eyes whose texel at their UV centre is
    clothing (``clothes``: a soft mask over the texture, > :data:`COLLAR_MASK_LEVEL`). Its top edge, per angle around
    the neck, is smoothed into a clean line (the highest collar face within
    :data:`COLLAR_WINDOW_DEG` of each angle), and every low skin face wholly under that line
    plus ``margin_iod`` is hidden: the scan then ends in a smooth line, not along the collar's
    ragged outline, and the texels of the collar's blurred edge go with it.
    """
    v = np.asarray(vertices, np.float64)
    low = skin & (v[faces, 1].max(axis=1) < _level(eye_right, eye_left, below_iod))
    collar = low & (_texels(clothes, uv[face_uv].mean(axis=1)) > COLLAR_MASK_LEVEL)
    if not collar.any():
        return collar
    centre = v[np.unique(faces[low])].mean(axis=0)
    top = _envelope(_angle(v[faces[collar]].mean(axis=1), centre), v[faces[collar], 1].max(axis=1))
    iod = float(np.linalg.norm(np.asarray(eye_left, np.float64) - np.asarray(eye_right, np.float64)))
    corner_top = top(_angle(v, centre)) + margin_iod * iod
    return collar | (low & (v[faces, 1] < corner_top[faces]).all(axis=1))


def _envelope(angles: np.ndarray, heights: np.ndarray, bins: int = 72):
    """The highest of ``heights`` within :data:`COLLAR_WINDOW_DEG` of each angle, as a function
    of angle (-inf where none is near)."""
    j = _angle_bin(angles, bins)
    peak = np.full(bins, -np.inf)
    np.maximum.at(peak, j, heights)
    reach = int(round(COLLAR_WINDOW_DEG / 360 * bins))
    peak = np.max([np.roll(peak, k) for k in range(-reach, reach + 1)], axis=0)

    def at(a: np.ndarray) -> np.ndarray:
        return peak[_angle_bin(a, bins)]

    return at


def _angle_bin(angles: np.ndarray, bins: int) -> np.ndarray:
    """The bin of each angle (radians, -pi..pi) among ``bins`` equal bins around the circle."""
    return np.floor((np.asarray(angles) / (2 * np.pi) + 0.5) * bins).astype(np.int64) % bins


def placed_bust(eye_right: np.ndarray, eye_left: np.ndarray, points: np.ndarray | None = None) -> np.ndarray:
    """The shipped bust's vertices (or ``points`` in its frame) placed under eyes at
    ``eye_right``/``eye_left``: scaled by the ratio of the inter-ocular distances, the eye
    midpoints met."""
    asset = bust_asset()
    er, el = np.asarray(eye_right, np.float64), np.asarray(eye_left, np.float64)
    bmid, biod = asset.eyes.mean(axis=0), float(np.linalg.norm(asset.eyes[1] - asset.eyes[0]))
    p = asset.vertices if points is None else np.asarray(points, np.float64)
    return (p - bmid) * (float(np.linalg.norm(el - er)) / biod) + (er + el) / 2


def neck_axis(vertices: np.ndarray, faces: np.ndarray, eye_right: np.ndarray, eye_left: np.ndarray) -> np.ndarray | None:
    """A point on the neck's vertical axis, :data:`NECK_AXIS_IOD` inter-ocular distances (iod)
    below the eyes, on the eyes' midline, :data:`NECK_HALF_DEPTH_IOD` behind the front of the
    neck there (the front of the surface's plane section at that height); None where the surface
    does not reach that low. Only the front is used: a scan's or a rig's back of the neck is
    often missing or part of the skull."""
    import trimesh

    er, el = np.asarray(eye_right, np.float64), np.asarray(eye_left, np.float64)
    mid, iod = (er + el) / 2, float(np.linalg.norm(el - er))
    y = mid[1] - NECK_AXIS_IOD * iod
    sec = trimesh.Trimesh(vertices, faces, process=False).section(plane_origin=[0.0, y, 0.0], plane_normal=[0.0, 1.0, 0.0])
    pts = np.zeros((0, 3)) if sec is None else np.asarray(sec.vertices)
    pts = pts[np.abs(pts[:, 0] - mid[0]) < 0.4 * iod]  # the front of the neck, not the arms
    if not len(pts):
        return None
    return np.array([mid[0], y, pts[:, 2].max() - NECK_HALF_DEPTH_IOD * iod])


def neckline(vertices: np.ndarray, axis: np.ndarray, eye_right: np.ndarray, eye_left: np.ndarray) -> np.ndarray:
    """Signed distance of each vertex inside the crew neckline, in iod (negative: under the
    garment): below a line running from :data:`NECKLINE_FRONT_IOD` under the eyes in front to
    :data:`NECKLINE_BACK_IOD` at the back (by the cosine of the angle around the neck's
    ``axis``), or, lower than the back's line, further than :data:`NECKLINE_RADIUS_IOD` from
    that axis (the shoulders; the jaw, above, is never inside)."""
    er, el = np.asarray(eye_right, np.float64), np.asarray(eye_left, np.float64)
    eye_y, iod = (er[1] + el[1]) / 2, float(np.linalg.norm(el - er))
    rel = np.asarray(vertices, np.float64) - axis
    r = np.hypot(rel[:, 0], rel[:, 2])
    front = np.clip(rel[:, 2] / np.maximum(r, 1e-9), -1, 1)  # cos of the angle from the front
    depth = (NECKLINE_FRONT_IOD + NECKLINE_BACK_IOD) / 2 + (NECKLINE_FRONT_IOD - NECKLINE_BACK_IOD) / 2 * front
    y = rel[:, 1] + axis[1]
    shoulders = np.maximum(NECKLINE_RADIUS_IOD - r / iod, (y - (eye_y - NECKLINE_BACK_IOD * iod)) / iod)
    return np.minimum((y - (eye_y - depth * iod)) / iod, shoulders)


def _neck_axis_or_bust(vertices: np.ndarray, faces: np.ndarray, eye_right: np.ndarray,
                       eye_left: np.ndarray) -> np.ndarray:
    """The character's :func:`neck_axis`, or the bust's placed by the eyes where the character's
    surface does not reach down the neck."""
    axis = neck_axis(vertices, faces, eye_right, eye_left)
    return placed_bust(eye_right, eye_left, bust_asset().axis[None])[0] if axis is None else axis


def under_garment(vertices: np.ndarray, faces: np.ndarray, skin: np.ndarray, eye_right: np.ndarray,
                  eye_left: np.ndarray, depth_iod: float = UNDER_GARMENT_IOD) -> np.ndarray:
    """Skin faces (a mask over ``faces``; ``skin`` marks the skin faces) that the garment
    covers: every corner more than ``depth_iod`` iod inside the :func:`neckline` around the
    character's own neck axis (the bust's, placed by the eyes, where the character has no
    whole neck). The character's neck goes on under the garment's edge, so the border where it
    ends is hidden (an ICT rig's chest and shoulders, the end of a scan)."""
    v = np.asarray(vertices, np.float64)
    axis = _neck_axis_or_bust(v, faces[skin], eye_right, eye_left)
    low = v[:, 1] < _level(eye_right, eye_left, RING_BELOW_IOD)
    inside = low & (neckline(v, axis, eye_right, eye_left) < -depth_iod)
    return skin & inside[faces].all(axis=1)


def _level(eye_right: np.ndarray, eye_left: np.ndarray, below_iod: float) -> float:
    """The height ``below_iod`` inter-ocular distances under the eye centres."""
    er, el = np.asarray(eye_right, np.float64), np.asarray(eye_left, np.float64)
    return float((er[1] + el[1]) / 2 - below_iod * np.linalg.norm(el - er))


def texel_index(shape: tuple[int, ...], uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row and column of the texel nearest each texture coordinate in an image of ``shape`` (OBJ
    convention, v up; u = 0 and 1 at the first and last texel's centre, as
    :mod:`stimulus_engine.characters.scan_eyes` samples)."""
    h, w = shape[:2]
    col = np.clip(np.rint(uv[:, 0] * (w - 1)), 0, w - 1).astype(np.int64)
    row = np.clip(np.rint((1 - uv[:, 1]) * (h - 1)), 0, h - 1).astype(np.int64)
    return row, col


def _texels(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """The texel of ``image`` nearest each texture coordinate (:func:`texel_index`)."""
    return image[texel_index(image.shape, uv)]


def _ring(vertices: np.ndarray, faces: np.ndarray, below: float) -> np.ndarray:
    """Border vertices of ``faces`` lower than ``below`` (the character's lower border)."""
    from stimulus_engine.geometry.mesh_ops import boundary_vertex_mask

    border = np.flatnonzero(boundary_vertex_mask(faces, len(vertices)))
    return border[vertices[border, 1] < below]


def _join_weights(points: np.ndarray, ring_points: np.ndarray, reach: float) -> np.ndarray:
    """(P, K) weights spreading each ring point's gap over ``points``: normalised inverse-square
    distance weights, times a smooth fade from 1 at the ring to 0 at ``reach`` from it."""
    from stimulus_engine.geometry.ramps import smoothstep

    d = np.linalg.norm(points[:, None, :] - ring_points[None, :, :], axis=2)
    w = 1.0 / np.maximum(d, 1e-3 * reach) ** 2
    w /= w.sum(axis=1, keepdims=True)
    return w * (1 - smoothstep(d.min(axis=1) / reach))[:, None]


def _garment_uv(points: np.ndarray, eye_mid: np.ndarray, iod: float) -> np.ndarray:
    """Coordinates for the knit: a front projection (x, y; one texture repeat per inter-ocular
    distance), the knit seen square from the camera."""
    rel = points - eye_mid
    return np.stack([rel[:, 0] / iod, rel[:, 1] / iod], axis=1)


def fit_body(vertices: np.ndarray, skin_faces: np.ndarray, uv: np.ndarray, face_uv: np.ndarray,
             eye_right: np.ndarray, eye_left: np.ndarray,
             colour: tuple[float, float, float] | None = None, neck_faces: np.ndarray | None = None,
             skin: np.ndarray | None = None) -> Body:
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
    neck_faces : (N, 3) int array, optional
        The skin the collar hugs: the character's skin before :func:`under_garment` hid what
        the garment covers (default ``skin_faces``); at the sides of a narrow neck the collar's
        edge meets it only there.
    skin : (H, W) array, optional
        How much each texel of the albedo is skin
        (:func:`~stimulus_engine.characters.scan_regions.skin_texels`): the neck's colour is
        taken from skin texels only (a scan's border runs into its hair at the back; sampled
        there, the back of the neck was the hair's near-black). Default: every texel.

    Returns
    -------
    Body
    """
    from stimulus_engine.geometry.closest import SurfaceIndex, lift_out
    from stimulus_engine.geometry.mesh_ops import vertex_normals

    asset = bust_asset()
    v = np.asarray(vertices, np.float64)
    er, el = np.asarray(eye_right, np.float64), np.asarray(eye_left, np.float64)
    mid, iod = (er + el) / 2, float(np.linalg.norm(el - er))
    p = placed_bust(er, el)
    cloth = asset.cloth
    index = SurfaceIndex(v, skin_faces)
    normals = vertex_normals(v, skin_faces)
    ring = _ring(v, skin_faces, _level(er, el, RING_BELOW_IOD))
    axis = _neck_axis_or_bust(v, skin_faces, er, el)
    # a neck vertex is free (drawn where it is) only below the highest the character's border
    # reaches around it: where the character's own neck goes on, down under the garment, the
    # bust's neck is not drawn; below a scan's ragged border it is, behind the scan's own neck
    # where that goes on lower. The garment is never bound to the skin (its shape is the bust's).
    # (a border under the garment counts FREE_BELOW_IOD lower: no bust neck beside the neckline)
    under = neckline(v[ring], axis, er, el) < 0
    ring_top = _envelope(_angle(v[ring], axis), v[ring, 1] + np.where(under, -FREE_BELOW_IOD, TUCK_IOD) * iod)
    covered = ~cloth & (p[:, 1] > ring_top(_angle(p, axis)))

    # faces: garment everywhere; neck skin with a free corner (the neckline's own corners, on
    # the garment's edge, do not count: a face from there up to the character's skin is a flap)
    fc, f = asset.cloth_face, asset.faces
    keep = fc | ~(covered | cloth)[f].all(axis=1)
    faces = f[keep]
    face_part = fc[keep].astype(np.int8)

    # the join's sources, each a skin point (corners and weights) with the bust point it pulls:
    # the ring's vertices (to the bust's surface beside them) and, where the character's neck goes
    # on under the garment, the neckline's vertices (to the skin beside them: the collar hugs it)
    edge = np.zeros(len(p), bool)
    edge[f[~fc].ravel()] = True
    hug, hug_tri, hug_bary = _hug(v, skin_faces if neck_faces is None else neck_faces, p, np.flatnonzero(edge & cloth),
                                  axis, HUG_REACH_IOD * iod)
    bust_hit = SurfaceIndex(p, f[keep]).query(v[ring]) if len(ring) else None  # the part drawn
    corners = np.concatenate([np.repeat(ring[:, None], 3, axis=1), hug_tri]).astype(np.int64)
    bary = np.concatenate([np.tile([1.0, 0.0, 0.0], (len(ring), 1)), hug_bary])
    targets = np.concatenate([p[:0] if bust_hit is None else bust_hit.points, p[hug]])
    on_cloth = np.concatenate([np.zeros(0, bool) if bust_hit is None
                               else fc[keep][bust_hit.face], np.ones(len(hug), bool)])
    skin_n = np.einsum("kc,kcd->kd", bary, normals[corners])
    skin_n /= np.maximum(np.linalg.norm(skin_n, axis=1, keepdims=True), 1e-12)
    # each source's gap (to the garment: the garment's height over the skin), spread over the bust
    lift = np.where(on_cloth, GARMENT_LIFT_IOD, -SINK_IOD) + np.r_[np.zeros(len(ring)), np.full(len(hug), COLLAR_RIB_IOD)]
    gaps = np.einsum("kc,kcd->kd", bary, v[corners]) + lift[:, None] * iod * skin_n - targets
    join = _join_weights(p, targets, JOIN_REACH_IOD * iod) if len(targets) else np.zeros((len(p), 0))
    placed = p + join @ gaps
    # the character's neck and chest, where drawn, never come through the cloth
    placed[cloth] = lift_out(placed[cloth], index, normals, GARMENT_LIFT_IOD * iod, HUG_REACH_IOD * iod, at_border=True)
    neck_edge = np.flatnonzero(edge & cloth)
    placed[neck_edge] = _without_dips(placed[neck_edge], axis)

    # anchors: the sources' corners (free vertices) and skin triangles (covered ones)
    rows = np.flatnonzero(covered)
    hit = index.query(p[rows])
    tri = skin_faces[hit.face]
    anchors = np.unique(np.concatenate([corners.ravel(), tri.ravel()])).astype(np.int64)
    weights = np.zeros((len(p), len(anchors)))
    offset = np.zeros_like(p)
    # covered neck corners: on their skin triangle, sunk under it
    np.add.at(weights, (rows[:, None], np.searchsorted(anchors, tri)), hit.bary)
    n_hit = np.einsum("mk,mkd->md", hit.bary, normals[tri])
    offset[rows] = -SINK_IOD * iod * n_hit / np.linalg.norm(n_hit, axis=1, keepdims=True)
    if len(targets):  # the rest: the join's weights on the sources, what they leave on their centre
        free = np.flatnonzero(~covered)
        spread = np.zeros((len(targets), len(anchors)))
        np.add.at(spread, (np.arange(len(targets))[:, None], np.searchsorted(anchors, corners)), bary)
        w = join[free] + (1.0 - join[free].sum(axis=1, keepdims=True)) / len(targets)
        weights[free] += w @ spread
    offset[~covered] = (placed - weights @ v[anchors])[~covered]  # no sources: the bust stands still

    # the neck's colour: the skin a little above the ring, by angle around the neck
    centre = placed[~cloth].mean(axis=0) if (~cloth).any() else mid
    top = placed[np.unique(faces[face_part == 0]), 1].max() if (face_part == 0).any() else mid[1]
    span = NECK_SPAN_IOD * iod
    neck_uv = np.clip(np.stack([(placed[:, 0] - centre[0]) / span + 0.5, (top - placed[:, 1]) / span], axis=1), 0.0, 1.0)
    if len(ring):
        above = index.query(v[ring] + np.array([0.0, NECK_COLOUR_ABOVE_IOD * iod, 0.0]))
        ring_uv = np.einsum("nk,nkd->nd", above.bary, uv[face_uv[above.face]])
    else:
        ring_uv = np.zeros((0, 2))
    ring_angle = _angle(v[ring], centre)
    if skin is not None and len(ring):
        on_skin = _texels(np.asarray(skin), ring_uv) > SKIN_TEXEL_LEVEL
        ring_uv, ring_angle = ring_uv[on_skin], ring_angle[on_skin]
    return Body(anchors, weights.astype(np.float32), offset, faces, face_part, _garment_uv(placed, mid, iod), neck_uv,
                asset.texture, ring_uv, ring_angle, tuple(float(c) for c in (colour or DEFAULT_GARMENT)))


def fade_into_neck(albedo: np.ndarray, body: Body, vertices: np.ndarray, skin_faces: np.ndarray, uv: np.ndarray,
                   face_uv: np.ndarray, eye_right: np.ndarray, eye_left: np.ndarray,
                   skin: np.ndarray | None = None) -> np.ndarray:
    """``albedo`` with the character's skin faded into the colour of the bust's neck toward its
    lower border (the ring of :func:`fit_body`; within :data:`NECK_FADE_IOD`).

    Each skin vertex near a ring vertex on skin takes, as its target, the neck's colour
    (:meth:`Body.neck_colours`) at the nearest neck vertex of the bust (what shows behind it);
    targets and fade weights are interpolated over the skin's texels, which move toward their
    target by the weight times their skin weight (``skin``,
    :func:`~stimulus_engine.characters.scan_regions.skin_texels`: hair is left as it is).
    Arguments as for :func:`fit_body` (``face_uv`` rows of ``skin_faces``); returns a new uint8
    albedo.
    """
    from scipy.spatial import cKDTree

    from stimulus_engine.geometry.ramps import smoothstep
    from stimulus_engine.geometry.uv_raster import rasterize_uv

    img = np.asarray(albedo)
    v = np.asarray(vertices, np.float64)
    er, el = np.asarray(eye_right, np.float64), np.asarray(eye_left, np.float64)
    iod = float(np.linalg.norm(el - er))
    skin_w = np.ones(img.shape[:2]) if skin is None else np.asarray(skin, np.float64)
    ring = _ring(v, skin_faces, _level(er, el, RING_BELOW_IOD))
    vertex_uv = np.zeros((len(v), 2))
    vertex_uv[skin_faces.ravel()] = uv[face_uv.ravel()]
    ring = ring[_texels(skin_w, vertex_uv[ring]) > SKIN_TEXEL_LEVEL]
    neck = np.unique(body.faces[body.face_part == 0])
    if not len(ring) or not len(neck) or not len(body.ring_uv):
        return img.copy()
    near, far = (d * iod for d in NECK_FADE_IOD)
    used = np.unique(skin_faces)
    d = cKDTree(v[ring]).query(v[used])[0]
    weight = np.zeros(len(v))
    weight[used] = 1.0 - smoothstep((d - near) / (far - near))
    colours = body.front_colours(img)
    bust = body.pose(v)
    j = cKDTree(bust[neck]).query(v[used])[1]
    column = np.clip((body.neck_uv[neck[j], 0] * len(colours)).astype(np.int64), 0, len(colours) - 1)
    target = np.zeros((len(v), 3))
    target[used] = colours[column]
    faded = weight[skin_faces].max(axis=1) > 0
    rows, cols, face, bary = rasterize_uv(uv, face_uv[faded], img.shape[1], img.shape[0])
    tri = skin_faces[faded][face]
    w = np.einsum("pk,pk->p", bary, weight[tri]) * skin_w[rows, cols]
    t = np.einsum("pk,pkc->pc", bary, target[tri])
    out = img.copy()
    px = out[rows, cols, :3].astype(np.float64)
    out[rows, cols, :3] = np.rint(px + w[:, None] * (t - px)).astype(np.uint8)
    return out


#: Each neckline vertex stands at least as high and as far out as the median of this many
#: neighbours on either side along the neckline.
NECKLINE_EVEN = 2


def _without_dips(points: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The neckline ``points`` with no vertex lower or further in than the median of its
    :data:`NECKLINE_EVEN` neighbours either side (in order of angle around the vertical ``axis``):
    the hug pulled single vertices of the collar's edge down and in onto the skin, and the neck
    showed through each such notch (8 px of skin below Lee Perry-Smith's collar at the throat)."""
    if len(points) < 2 * NECKLINE_EVEN + 1:
        return points
    angle = _angle(points, axis)
    order = np.argsort(angle)
    rel, angle = points[order] - axis, angle[order]
    radius = np.hypot(rel[:, 0], rel[:, 2])
    k = np.arange(-NECKLINE_EVEN, NECKLINE_EVEN + 1)
    k = k[k != 0]
    around = (np.arange(len(points))[:, None] + k[None]) % len(points)
    radius = np.maximum(radius, np.median(radius[around], axis=1))
    y = np.maximum(rel[:, 1], np.median(rel[around, 1], axis=1))
    out = points.copy()
    out[order] = axis + np.column_stack([radius * np.sin(angle), y, radius * np.cos(angle)])
    return out


def _hug(vertices: np.ndarray, skin_faces: np.ndarray, points: np.ndarray, candidates: np.ndarray,
         axis: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``candidates`` (rows of ``points``) with skin straight inwards of them, level, toward
    the vertical ``axis`` within ``reach`` (a ray cast from each): those rows, the hit skin
    triangles' corners (K, 3) and barycentric weights (K, 3)."""
    import trimesh

    if not len(candidates) or not len(skin_faces):
        return np.zeros(0, np.int64), np.zeros((0, 3), np.int64), np.zeros((0, 3))
    inward = axis - points[candidates]
    inward[:, 1] = 0.0
    inward /= np.maximum(np.linalg.norm(inward, axis=1, keepdims=True), 1e-12)
    origins = points[candidates] - reach * inward  # from outside too: a neck wider than the collar
    mesh = trimesh.Trimesh(vertices, skin_faces, process=False)
    loc, ray, tri = mesh.ray.intersects_location(origins, inward, multiple_hits=True)
    d = np.einsum("kd,kd->k", loc - points[candidates][ray], inward[ray])
    ok = np.abs(d) < reach
    loc, ray, tri, d = loc[ok], ray[ok], tri[ok], np.abs(d[ok])
    order = np.lexsort((d, ray))  # per ray, the nearest hit to the collar
    first = order[np.r_[True, ray[order][1:] != ray[order][:-1]]] if len(order) else order
    corners = skin_faces[tri[first]]
    bary = trimesh.triangles.points_to_barycentric(vertices[corners], loc[first])
    return candidates[ray[first]], corners, bary


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
