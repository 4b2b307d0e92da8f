"""Eyes for a scan: openings cut along the lids, photographic eyeballs and a wet socket behind.

A photogrammetric scan paints the eyes onto one continuous surface (no eyeball, no highlight,
no depth), and a stylised shape that enlarges the eyes only smears that paint. Here each eye of a
scan becomes a real eye:

1. the lid margin is the detected eye contour (iBUG points 36–41 and 42–47 on the surface),
   drawn as two arcs through the upper and the lower points (:func:`lid_contour`);
2. the scan's triangles inside it are cut out and the hole's rim moved onto the contour, so the
   opening is the lid line, not the triangles' zig-zag (:func:`cut_openings`);
3. an eyeball — MakeHuman's CC0 high-poly eye with its photographic iris texture
   (``stimulus_engine/data/eyes``) — sits behind each opening, sized by anatomy (radius 12 mm for
   an interpupillary distance of 63 mm: 0.19 × the distance between the two eye centres), its
   front pole on the painted surface, looking ahead (:func:`place_eyeballs`);
4. the lids get their thickness (:func:`lid_margins`): a strip from the rim back onto the ball,
   wet pink where it shows (the lower lid's wet line, the caruncle in the inner corner), in the
   upper lid's shadow elsewhere;
5. a socket (the conjunctiva: dark, wet pink) closes the opening behind the margins, so the
   corners of the eye, where the ball curves away, show tissue and not the inside of the head;
6. the bare upper lid margins get lashes (:mod:`stimulus_engine.parts.eyelashes`).

Everything is in the rig's frame (+y up, +z towards the viewer).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from stimulus_engine.parts.eyes import eyeball_asset
from stimulus_engine.parts.eyelashes import lash_strip
from stimulus_engine.geometry.polyline2d import catmull_rom, closest_on_polygon, inside_polygon, push_behind, relax_around

__all__ = ["EyeGeometry", "erase_painted_eyes", "eye_geometry", "lid_contour", "lid_margins", "cut_openings",
           "place_eyeballs", "openness", "painted_iris_colour", "PAINTED_IRIS_LEAST"]

#: Eyeball radius over the distance between the eye centres (12 mm / 63 mm).
EYEBALL_RATIO = 12.0 / 63.0
#: Below this height/width ratio of its contour an eye counts as closed (open eyes: 0.25–0.4).
CLOSED_RATIO = 0.12
#: The least mean grey (sRGB) of the iris colour read off a scan's painted eye: james's painted
#: iris averages 50, shaded by the scan's own light, and rendered it came out a near-black disc
#: (luminance 36 in the image, where London's neutral photographs' irises measure 47-78, 25th-75th
#: percentile, and their pupils show darker inside).
PAINTED_IRIS_LEAST = 68.0


@dataclass(frozen=True)
class EyeGeometry:
    """The eyes added to a scan.

    Attributes
    ----------
    keep : (F,) bool array
        The scan's triangles that stay (False inside the openings).
    vertices : (S, 3) array
        The scan's vertices with the openings' rims on the lid contours.
    balls : list of (V, 3) arrays
        Each eyeball's vertices (right eye first: iBUG 36–41, the subject's right).
    ball_faces, ball_uv : arrays
        Faces and UVs shared by both balls' vertex lists (per eye, indices into its own list).
    sockets : list of ((K + 1, 3) array, (K, 3) int array)
        Each socket's vertices (the contour, then the centre pushed back) and fan faces.
    texture : (H, W, 3) uint8 array
        The eyeball texture.
    lashes : list of ((R, 3) array, (L, 3) int array, (R, 2) array)
        Each upper lid's lash strip (:func:`stimulus_engine.parts.eyelashes.lash_strip`): vertices,
        faces, UVs; drawn with :func:`stimulus_engine.parts.eyelashes.lash_texture`.
    margins : list of ((M, 3) array, (G, 3) int array, (M,) int array, (G,) bool array)
        Each opening's lid margin (:func:`lid_margins`): vertices, faces, the rim vertex of the
        scan each vertex stands on (it moves with it), and the faces of the wet line and caruncle.
    """

    keep: np.ndarray
    vertices: np.ndarray
    balls: list[np.ndarray]
    ball_faces: list[np.ndarray]
    ball_uv: list[np.ndarray]
    sockets: list[tuple[np.ndarray, np.ndarray]]
    texture: np.ndarray
    lashes: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)
    margins: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)


def lid_contour(points: np.ndarray, n: int = 8) -> np.ndarray:
    """The lid margin through an eye's six iBUG points, as a closed polyline.

    Parameters
    ----------
    points : (6, 3) array
        iBUG order: a corner, two upper-lid points, the other corner, two lower-lid points.
    n : int
        Samples per span between points.

    Returns
    -------
    (6 n, 3) array
        The upper arc from the first corner to the second, then the lower arc back (the corners
        stay sharp).
    """
    p = np.asarray(points, np.float64)
    upper = catmull_rom(p[[0, 1, 2, 3]], n)
    lower = catmull_rom(p[[3, 4, 5, 0]], n)
    return np.vstack([upper, lower])


def openness(points: np.ndarray) -> float:
    """Height over width of an eye's six iBUG points (open eyes ≈ 0.25–0.4, closed < 0.12)."""
    p = np.asarray(points, np.float64)
    width = np.linalg.norm(p[3] - p[0])
    height = 0.5 * (np.linalg.norm(p[1] - p[5]) + np.linalg.norm(p[2] - p[4]))
    return float(height / max(width, 1e-12))


def _spanning(v: np.ndarray, f: np.ndarray, candidates: np.ndarray, contour: np.ndarray) -> np.ndarray:
    """The ``candidates`` triangles whose centre lies inside ``contour`` (seen along +z)."""
    idx = np.flatnonzero(candidates)
    out = np.zeros(len(f), bool)
    out[idx[inside_polygon(v[f[idx]].mean(axis=1)[:, :2], contour[:, :2])]] = True
    return out


def _cut_and_snap(v: np.ndarray, f: np.ndarray, keep: np.ndarray, cut: np.ndarray, inside: np.ndarray,
                  snapped: np.ndarray, contour: np.ndarray, near: np.ndarray) -> np.ndarray:
    """Drop the ``cut`` triangles and lay the new rim on the contour until no kept triangle spans
    the opening (a triangle whose rim corners land on either side of a corner does); ``v`` and
    ``snapped`` are updated in place. Returns the new ``keep``."""
    keep = keep.copy()
    for _ in range(4):
        if not cut.any():
            break
        keep &= ~cut
        rim = np.zeros(len(v), bool)
        rim[f[cut].ravel()] = True
        kept = np.zeros(len(v), bool)
        kept[f[keep].ravel()] = True
        idx = np.flatnonzero(rim & kept & ~inside & ~snapped)
        snapped[idx] = True
        if len(idx):
            k, t = closest_on_polygon(v[idx, :2], contour[:, :2])
            a, b = contour[k], np.roll(contour, -1, axis=0)[k]
            v[idx] = a + t[:, None] * (b - a)
        cut = _spanning(v, f, keep & near[f].all(axis=1), contour)
    return keep


def cut_openings(vertices: np.ndarray, faces: np.ndarray, contours: list[np.ndarray],
                 reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Cut the scan open inside each lid contour (seen along +z) and lay the rim on the contour.

    Parameters
    ----------
    vertices : (S, 3) array
    faces : (F, 3) int array
    contours : list of (K, 3) arrays
        Closed lid contours on the surface.
    reach : float
        Only vertices closer than this to a contour's centre are cut or moved (keeps the back
        of the head, which also projects into the contour, intact).

    Returns
    -------
    keep : (F,) bool array
    vertices : (S, 3) array
        A copy with the rim vertices moved onto the contours (x, y from the contour's closest
        point, z interpolated along it).
    """
    v = np.asarray(vertices, np.float64).copy()
    f = np.asarray(faces, np.int64)
    keep = np.ones(len(f), bool)
    for contour in contours:
        near = np.linalg.norm(v - contour.mean(axis=0), axis=1) < reach
        inside = np.zeros(len(v), bool)
        inside[near] = inside_polygon(v[near, :2], contour[:, :2])
        cut = inside[f].any(axis=1)
        snapped = np.zeros(len(v), bool)
        keep = _cut_and_snap(v, f, keep, cut, inside, snapped, contour, near)
        relax_around(v, f[keep], contour, fixed=np.flatnonzero(snapped), near=near)
        # slivers the evening-out pushed into the opening go too, their rims onto the contour
        keep = _cut_and_snap(v, f, keep, _spanning(v, f, keep & near[f].all(axis=1), contour), inside, snapped,
                             contour, near)
    return keep, v


def place_eyeballs(contours: list[np.ndarray], centres: list[np.ndarray]) -> tuple[list[np.ndarray], float]:
    """Each template eyeball moved behind its opening, looking along +z.

    Parameters
    ----------
    contours : list of (K, 3) arrays
        Right and left lid contours.
    centres : list of (3,) arrays
        Each eye's centre on the painted surface (the mean of its six iBUG points).

    Returns
    -------
    balls : list of (V, 3) arrays
    radius : float
        The eyeballs' radius (0.19 × the distance between the eye centres).
    """
    radius = EYEBALL_RATIO * float(np.linalg.norm(centres[0] - centres[1]))
    templates, _ = eyeball_asset()
    out = []
    for (unit, _, _), c in zip(templates, centres):
        ball_centre = np.asarray(c, np.float64) - np.array([0.0, 0.0, radius])
        out.append(ball_centre + radius * unit)
    return out, radius


def _behind_lids(ball: np.ndarray, vertices: np.ndarray, faces: np.ndarray, contour: np.ndarray,
                 reach: float, gap: float = 0.02) -> np.ndarray:
    """``ball`` moved back (-z) until no part of it outside the opening pokes through the lids
    (a scan's lower lid often lies flatter than an eyeball of anatomical size), by ``gap`` of
    the eye's width."""
    used = np.unique(faces)
    near = used[np.linalg.norm(vertices[used] - contour.mean(axis=0), axis=1) < reach]
    return push_behind(ball, vertices[near], gap * float(np.ptp(contour[:, 0])), opening=contour)


#: Seen from the front, the lower lid's margin (its wet line) reaches this far over the eyeball,
#: and at the inner corner the caruncle this far (inter-ocular distances: 1 mm and 2.5 mm of 63),
#: over the inner :data:`CARUNCLE_SHARE` of the eye's width.
WET_LINE_IOD, CARUNCLE_IOD, CARUNCLE_SHARE = 0.016, 0.04, 0.15


def _margin_reach(rim: np.ndarray, middle: np.ndarray, midline: float, width: float) -> np.ndarray:
    """How far (iod) each rim point's margin reaches over the ball, seen from the front: the wet
    line along the lower lid, the caruncle in the inner corner (the side of ``midline``)."""
    from stimulus_engine.geometry.ramps import smoothstep

    lower = smoothstep((middle[1] - rim[:, 1]) / (0.1 * width))  # below the eye's middle
    toward = np.sign(midline - middle[0])
    inner = 1 - smoothstep((middle[0] + toward * width / 2 - rim[:, 0]) * toward / (CARUNCLE_SHARE * width))
    return np.maximum(WET_LINE_IOD * lower, CARUNCLE_IOD * inner)


#: The lid margin's inner edge lies this far outside the eyeball (a fraction of its radius: 0.24 mm
#: on a 12 mm ball), so the margin meets the ball without a gap and without cutting into it.
MARGIN_LIFT = 0.02


def lid_margins(vertices: np.ndarray, faces: np.ndarray, contours: list[np.ndarray], centres: list[np.ndarray],
                radius: float) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None]:
    """The lids' thickness: a strip from each opening's rim back onto its eyeball.

    A scan cut open along its lid line ends in a paper-thin edge; where the eyeball curves away
    behind it (the corners, and wherever the ball sits deeper than the lid) one saw the socket, a
    hard dark outline round the eye. Each rim vertex of an opening (the border of ``faces``
    nearest each contour) gets a twin straight behind it on the ball (the sphere of ``radius``
    about each of ``centres``, :data:`MARGIN_LIFT` outside it), or, where the line of sight
    misses the ball, on the ball's outline as the camera sees it; the quads between rim and
    twins, facing the opening's front, are the margin of the lid. Along the lower lid and in the
    inner corner the twins lie inward of the rim (:func:`_margin_reach`), so the margin shows
    over the ball as the wet line and the caruncle; where the ball comes through the opening in
    front of the rim the twin is the rim itself.

    Returns
    -------
    list of (vertices (2K, 3), faces (2K, 3), roots (2K,), wet (2K,)) or None, per contour
        The rim's copies then the twins; ``roots`` the rim's scan vertex of each; ``wet`` the
        faces of the wet line and the caruncle (the rest, the upper lid's, are in its shadow).
        None where no opening of ``faces`` lies at a contour.
    """
    from stimulus_engine.geometry.mesh_ops import boundary_loops

    v = np.asarray(vertices, np.float64)
    loops = boundary_loops(np.asarray(faces, np.int64))
    r = radius * (1 + MARGIN_LIFT)
    middles = [cn.mean(axis=0) for cn in contours]
    midline = float(np.mean([m[0] for m in middles]))
    iod = float(np.linalg.norm(middles[0] - middles[-1]))
    out = []
    for contour, c in zip(contours, centres):
        middle = contour.mean(axis=0)
        loop = min(loops, key=lambda lp: float(np.linalg.norm(v[lp].mean(axis=0) - middle)))
        if np.linalg.norm(v[loop].mean(axis=0) - middle) > 0.5 * float(np.ptp(contour[:, 0])):
            out.append(None)  # no opening here
            continue
        rim = v[loop]
        rim_in = rim.copy()  # the margin's inner edge seen from the front: the lower lid's wet
        inward = middle[:2] - rim[:, :2]  # margin and the caruncle lie over the ball
        inward /= np.maximum(np.linalg.norm(inward, axis=1, keepdims=True), 1e-12)
        reach = _margin_reach(rim, middle, midline, float(np.ptp(contour[:, 0])))
        rim_in[:, :2] += inward * iod * reach[:, None]
        d = rim_in[:, :2] - c[:2]
        across = np.linalg.norm(d, axis=1)
        hits = across < r
        twin = rim_in.copy()
        twin[hits, 2] = np.minimum(rim[hits, 2], c[2] + np.sqrt(r ** 2 - across[hits] ** 2))
        twin[~hits, :2] = c[:2] + r * d[~hits] / across[~hits, None]
        twin[~hits, 2] = np.minimum(rim[~hits, 2], c[2])
        k = len(loop)
        i, j = np.arange(k), (np.arange(k) + 1) % k
        tri = np.vstack([np.column_stack([i, j, k + j]), np.column_stack([i, k + j, k + i])])
        pts = np.vstack([rim, twin])
        normal = np.cross(pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]])
        front = middle + np.array([0.0, 0.0, r]) - pts[tri].mean(axis=1)
        flip = np.einsum("fd,fd->f", normal, front) < 0
        tri[flip] = tri[flip][:, ::-1]
        wet = reach[tri[:, :2] % k].mean(axis=1) > 0.5 * WET_LINE_IOD
        out.append((pts, tri.astype(np.int64), np.concatenate([loop, loop]).astype(np.int64), wet))
    return out


def _socket(contour: np.ndarray, depth: float) -> tuple[np.ndarray, np.ndarray]:
    """A fan from the contour to its centre pushed ``depth`` back (-z)."""
    centre = contour.mean(axis=0) - np.array([0.0, 0.0, depth])
    k = len(contour)
    faces = np.column_stack([np.arange(k), np.full(k, k), (np.arange(k) + 1) % k])
    return np.vstack([contour, centre]), faces


def painted_iris_colour(texture: np.ndarray, uv: np.ndarray, face_uv: np.ndarray, faces_inside: np.ndarray) -> np.ndarray:
    """The iris colour painted in a scan's texture: the median of the darkest third of the
    texels under the cut-out triangles (the painted eye: sclera, iris, pupil), pupil-dark
    texels (the darkest tenth) left out."""
    h, w = texture.shape[:2]
    # corners and centroids of the triangles inside the openings
    tri = uv[face_uv[faces_inside]]
    samples = np.vstack([tri.reshape(-1, 2), tri.mean(axis=1)])
    px = texture[np.clip(np.rint((1 - samples[:, 1]) * (h - 1)).astype(int), 0, h - 1),
                 np.clip(np.rint(samples[:, 0] * (w - 1)).astype(int), 0, w - 1)].astype(np.float64)
    lum = px @ np.array([0.2126, 0.7152, 0.0722])
    lo, hi = np.percentile(lum, [10, 35])
    sel = (lum >= lo) & (lum <= hi)
    return np.median(px[sel if sel.any() else slice(None)], axis=0)


def lid_shadow(texture: np.ndarray, templates: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
               depth: float = 0.4) -> np.ndarray:
    """The eyeball texture darkened where the lids shade a real eye: towards the top of the ball
    (the upper lid's shadow falls over the upper iris and sclera) and, less, towards the corners.

    A rasteriser casts no such soft shadow from a lid a millimetre in front of the ball, and
    without it the sclera reads as a bright sticker. The factor ``1 − depth · s(y) − depth/3 ·
    s(|x|)`` (``s`` a smoothstep over the ball's unit directions, y up, x across) is painted
    into each template's UV island.
    """
    from stimulus_engine.geometry.uv_raster import rasterize_uv

    h, w = texture.shape[:2]
    out = texture.astype(np.float64)
    for unit, faces, uv in templates:
        d = unit / np.linalg.norm(unit, axis=1, keepdims=True)
        t_up = np.clip((d[:, 1] - 0.05) / 0.5, 0, 1)
        t_side = np.clip((np.abs(d[:, 0]) - 0.3) / 0.5, 0, 1)
        factor = 1 - depth * t_up**2 * (3 - 2 * t_up) - depth / 3 * t_side**2 * (3 - 2 * t_side)
        rows, cols, fid, bary = rasterize_uv(uv, faces, w, h)
        out[rows, cols] *= np.einsum("nk,nk->n", bary, factor[faces[fid]])[:, None]
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def eye_geometry(vertices: np.ndarray, faces: np.ndarray, eye_points: np.ndarray,
                 texture: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> EyeGeometry:
    """Openings, eyeballs and sockets for a scan (all in the rig's frame).

    Parameters
    ----------
    vertices : (S, 3) array
    faces : (F, 3) int array
    eye_points : (12, 3) array
        iBUG points 36–47 on the scan's surface.
    texture : (albedo, uv, face_uv), optional
        The scan's texture and UV layout: the eyeballs' iris takes the colour painted there
        (:func:`painted_iris_colour`); without it the iris stays brown.

    Raises
    ------
    ValueError
        When an eye is closed (its contour's height/width ratio below :data:`CLOSED_RATIO`).
    """
    pts = np.asarray(eye_points, np.float64).reshape(2, 6, 3)
    ratios = [openness(p) for p in pts]
    if min(ratios) < CLOSED_RATIO:
        raise ValueError(f"the scan's eyes look closed (eye opening height/width {min(ratios):.2f}, expected at "
                         f"least {CLOSED_RATIO}): use eyes: scan to keep them, or the scan's shape and photograph on the rig (topology: rig), whose eyes are open")
    contours = [lid_contour(p) for p in pts]
    centres = [p.mean(axis=0) for p in pts]
    width = float(np.mean([np.linalg.norm(p[3] - p[0]) for p in pts]))
    keep, v = cut_openings(vertices, faces, contours, reach=1.2 * width)
    balls, radius = place_eyeballs(contours, centres)
    balls = [_behind_lids(b, v, faces[keep], c, reach=1.2 * width) for b, c in zip(balls, contours)]
    from stimulus_engine.parts.eyes import tint_iris

    templates, eye_texture = eyeball_asset()
    if texture is not None:
        eye_texture = tint_iris(eye_texture, painted_iris_colour(*texture, ~keep), least=PAINTED_IRIS_LEAST)
    eye_texture = lid_shadow(eye_texture, templates)
    ball_centres = [b[0] - radius * t[0][0] for b, t in zip(balls, templates)]
    margins = lid_margins(v, faces[keep], contours, ball_centres, radius)
    # the socket closes the opening behind the lids' margins, from their inner edge to the ball's
    # centre (from the rim, it lay in front of a ball set deep behind the lids: a dark outline)
    inner_edges = [None if m is None else m[0][len(m[0]) // 2:] for m in margins]  # the twins
    sockets = [_socket(c, radius) if e is None else _socket(e, float(e[:, 2].mean() - bc[2]))
               for c, e, bc in zip(contours, inner_edges, ball_centres)]
    half = len(contours[0]) // 2  # the upper arc, corner to corner
    lashes = [lash_strip(c[:half + 1], float(np.linalg.norm(p[3] - p[0]))) for c, p in zip(contours, pts)]
    return EyeGeometry(keep, v, balls, [t[1] for t in templates], [t[2] for t in templates], sockets, eye_texture,
                       lashes, [m for m in margins if m is not None])


def erase_painted_eyes(texture: np.ndarray, vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray,
                       face_uv: np.ndarray, keep: np.ndarray, eye_points: np.ndarray, band: float = 0.3) -> np.ndarray:
    """A scan's albedo with what its painted eyes left on the lids painted over with skin.

    The openings are cut along the detected lid contours; what the photograph shows just outside
    them stays on the kept lids: the glistening wet rim of the lower lid and the painted sclera
    at the corners (a pale smear under the james scan's right eye once a real eyeball sits
    behind it, with its own wet look). Around each eye (kept triangles whose centre lies within
    half the eye's width plus ``band`` widths of its centre), texels much lighter than the skin
    just outside (L* above its median by more than 15) or far paler in colour (chroma under
    55 % of its median, not darker by more than 25 L*: sclera and its grey shade, not lashes or
    the lid crease) are inpainted (OpenCV's Telea method) from the skin around them.

    Parameters
    ----------
    texture : (H, W, 3) uint8 array
    vertices, faces, uv, face_uv
        The scan's surface (with its openings' rims on the contours) and UV layout.
    keep : (F,) bool array
        The triangles that stay (:attr:`EyeGeometry.keep`).
    eye_points : (12, 3) array
        iBUG points 36–47 on the surface.

    Returns
    -------
    (H, W, 3) uint8 array
        A copy.
    """
    import cv2

    from stimulus_engine.geometry.uv_raster import rasterize_uv

    tex = np.ascontiguousarray(texture, np.uint8)
    h, w = tex.shape[:2]
    centroids = np.asarray(vertices, np.float64)[faces].mean(axis=1)
    near, ring = np.zeros(len(faces), bool), np.zeros(len(faces), bool)
    for p in np.asarray(eye_points, np.float64).reshape(2, 6, 3):
        width = float(np.linalg.norm(p[3] - p[0]))
        d = np.linalg.norm(centroids - p.mean(axis=0), axis=1) / width
        near |= keep & (d < 0.5 + band)
        ring |= keep & (d >= 0.5 + band) & (d < 0.5 + 2 * band)

    def texels(sel: np.ndarray) -> np.ndarray:
        mask = np.zeros((h, w), bool)
        if sel.any():
            rows, cols, _, _ = rasterize_uv(uv, face_uv[sel], w, h)
            mask[rows, cols] = True
        return mask

    region, skin = texels(near), texels(ring)
    if not region.any() or skin.sum() < 50:
        return tex.copy()
    lab = cv2.cvtColor(tex, cv2.COLOR_RGB2LAB).astype(np.float64)
    light, chroma = lab[..., 0] * 100 / 255, np.hypot(lab[..., 1] - 128, lab[..., 2] - 128)
    l_skin, c_skin = np.median(light[skin]), np.median(chroma[skin])
    paint = region & ((light > l_skin + 15) | ((chroma < 0.55 * c_skin) & (light > l_skin - 25)))
    if not paint.any():
        return tex.copy()
    paint = cv2.dilate(paint.astype(np.uint8), np.ones((3, 3), np.uint8), iterations=2)
    return cv2.inpaint(tex, paint, 6, cv2.INPAINT_TELEA)
