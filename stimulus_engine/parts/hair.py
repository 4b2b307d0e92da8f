"""Hair on any head: MakeHuman's CC0 hair styles carried onto a rig's head.

The shipped assets (``stimulus_engine/data/hair/``, one per style of :data:`HAIR_STYLES`, rebuilt
by ``scripts/make_hair_asset.py``) hold each hair mesh as *anchors* on MakeHuman's base head
plus a *lift* above each anchor and its whole *offset* from it, seven head points of that head
(:func:`head_points`: eye centres, top, back and sides of the cranium), and an alpha-tested
strand texture. :func:`fit_hair` maps the anchors onto a rig by the per-axis scale and shift
that best takes the seven points onto the rig's own, snaps each to the rig's skin (closest
point: triangle and barycentric weights) and places the hair vertex from there: near the scalp
by the scaled lift along the skin's normal, so the hair hugs that rig's scalp whatever its
proportions; further out (a bob's ends, long hair, a ponytail) by the scaled offset, so a lock
hangs as it does on the source head instead of following the normal of the skin it is nearest
(:data:`HANG_IOD`).

The result, :class:`Hair`, is bound to the skin: every pose of the rig (an identity of the same
topology, an expression, a stylised shape) moves each hair vertex with its skin point, so the
hair follows a growing cranium or a raised brow. :func:`stimulus_engine.characters.render_parts.rig_render_parts`
draws it as an alpha-blended ``hair`` part (its cards sorted back to front by the renderer).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from stimulus_engine.data import DATA_DIR
from stimulus_engine.parts.stored import part_arrays, part_from_arrays

__all__ = ["HAIR_STYLES", "Hair", "HairAsset", "fit_hair", "hair_arrays", "hair_asset", "hair_from_arrays", "head_points", "linear_rgb"]

_DATA = DATA_DIR / "hair"
#: Hair styles shipped with the package (name → asset file stem): MakeHuman's CC0 proxies, and
#: ``short`` (the default haircut, ``short02``).
HAIR_STYLES: dict[str, str] = {"short": "short02", **{s: s for s in (
    "short01", "short02", "short03", "short04", "bob02", "long01", "afro01", "ponytail01")}}
#: Default hair colour (linear RGB, multiplies the grey strand texture): dark brown.
DEFAULT_COLOUR: tuple[float, float, float] = (0.055, 0.036, 0.024)
#: Smallest lift above the skin, in inter-ocular distances (no hair inside the scalp).
MIN_LIFT_IOD = 0.02
#: Hair laid over a scan's own surface stands this far above it, where that surface is within
#: the reach (inter-ocular distances).
OVER_LIFT_IOD, OVER_REACH_IOD = 0.04, 1.0
#: Hair vertices up to the first distance from their anchor (source inter-ocular distances) are
#: placed along the skin's normal, beyond the second by their offset, blended in between.
HANG_IOD = (0.25, 0.6)


@dataclass(frozen=True)
class HairAsset:
    """A hair mesh described on a source head (see the module docstring).

    Attributes
    ----------
    anchors : (M, 3) array
        Closest point of the source head to each hair vertex.
    lift : (M,) array
        Height of each hair vertex above its anchor, along the head's normal (source units).
    offset : (M, 3) array
        Each hair vertex minus its anchor (source units).
    head : (7, 3) array
        :func:`head_points` of the source head.
    faces : (K, 3) int array
    uv : (M, 2) array
    texture : (H, W, 4) uint8 array
        Grey strands; alpha 255 where there is hair.
    """

    anchors: np.ndarray
    lift: np.ndarray
    offset: np.ndarray
    head: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    texture: np.ndarray


@dataclass(frozen=True)
class Hair:
    """Hair bound to a rig's skin.

    Attributes
    ----------
    corners : (M, 3) int array
        Rig vertices of each hair vertex's skin triangle.
    bary : (M, 3) array
        Barycentric weights in that triangle.
    offset : (M, 3) array
        Hair vertex minus its skin point, in the rig's frame.
    faces, uv, texture
        As in :class:`HairAsset`.
    colour : (3,) tuple of float
        Linear RGB multiplying the texture.
    massed : bool
        Drawn as painted masses (:mod:`stimulus_engine.stylisation.hair`): the path tracer draws
        its cards, not strand curves.
    """

    corners: np.ndarray
    bary: np.ndarray
    offset: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    texture: np.ndarray
    colour: tuple[float, float, float] = DEFAULT_COLOUR
    massed: bool = False

    def pose(self, rig_vertices: np.ndarray) -> np.ndarray:
        """(M, 3) hair vertices for a pose of the rig it was fitted to."""
        rv = np.asarray(rig_vertices, np.float64)
        return self.offset + np.einsum("mk,mkd->md", self.bary, rv[self.corners])


@functools.lru_cache(maxsize=4)
def hair_asset(style: str = "short") -> HairAsset:
    """The shipped hair ``style`` (a key of :data:`HAIR_STYLES`)."""
    from PIL import Image

    if style not in HAIR_STYLES:
        raise ValueError(f"unknown hair style '{style}' (expected one of: {', '.join(HAIR_STYLES)})")
    stem = _DATA / HAIR_STYLES[style]
    d = np.load(stem.with_suffix(".npz"))
    with Image.open(stem.with_suffix(".png")) as im:
        tex = np.asarray(im.convert("RGBA"))
    arrays = [d["anchors"].astype(np.float64), d["lift"].astype(np.float64), d["offset"].astype(np.float64),
              d["head"].astype(np.float64), d["faces"].astype(np.int64), d["uv"].astype(np.float64), tex]
    for a in arrays:
        a.setflags(write=False)
    return HairAsset(*arrays)


def head_points(vertices: np.ndarray, eye_right: np.ndarray, eye_left: np.ndarray) -> np.ndarray:
    """Seven points that place a head: the eye centres, the top, back and front (forehead) of the
    cranium, and its right and left sides, at 0.6 inter-ocular distances above the eyes.

    Parameters
    ----------
    vertices : (N, 3) array
        The head's surface vertices (+y up, +z forward).
    eye_right, eye_left : (3,) arrays
        Eye centres.

    Returns
    -------
    (7, 3) array
    """
    v = np.asarray(vertices, np.float64)
    eye_right, eye_left = np.asarray(eye_right, np.float64), np.asarray(eye_left, np.float64)
    mid, iod = (eye_right + eye_left) / 2, float(np.linalg.norm(eye_left - eye_right))
    midline = np.abs(v[:, 0] - mid[0]) < 0.3 * iod
    band = np.abs(v[:, 1] - (mid[1] + 0.6 * iod)) < 0.1 * iod
    back = midline & band
    if not midline.any() or not back.any():
        raise ValueError("head_points: no head surface above the eyes (is +y up and the mesh a whole head?)")
    top = v[midline][np.argmax(v[midline, 1])]
    return np.array([eye_right, eye_left, top, v[back][np.argmin(v[back, 2])], v[back][np.argmax(v[back, 2])],
                     v[band][np.argmin(v[band, 0])], v[band][np.argmax(v[band, 0])]])


def linear_rgb(hex_colour: str) -> tuple[float, float, float]:
    """An sRGB hex colour (``"#3a2a1f"``) as linear RGB in 0..1 (the renderer's colour factors)."""
    c = np.array([int(hex_colour[i:i + 2], 16) / 255 for i in (1, 3, 5)])
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return tuple(float(x) for x in lin)


def _axis_fit(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis scale and shift taking ``src`` points to ``dst`` (least squares)."""
    scale, shift = np.zeros(3), np.zeros(3)
    for i in range(3):
        a = np.stack([src[:, i], np.ones(len(src))], axis=1)
        (scale[i], shift[i]), *_ = np.linalg.lstsq(a, dst[:, i], rcond=None)
    return scale, shift


def fit_hair(rig, style: str = "short", colour: tuple[float, float, float] | None = None,
             over: tuple[np.ndarray, np.ndarray] | None = None) -> Hair:
    """Put the shipped hair ``style`` on ``rig``'s head (see the module docstring).

    Parameters
    ----------
    rig : FaceRig
        A whole-head rig with ``eye_right``/``eye_left`` landmarks (eyeball vertex sets),
        +y up and +z forward (ICT identities, procedural heads, meshes corresponded onto them).
    style : str
        A key of :data:`HAIR_STYLES`.
    colour : (3,) tuple of float, optional
        Linear RGB of the hair (default :data:`DEFAULT_COLOUR`).
    over : (vertices, faces), optional
        A surface in the rig's frame that the hair is laid over (:data:`OVER_LIFT_IOD` above it,
        where it is within :data:`OVER_REACH_IOD`): a scan's own sculpted hair, which the rig
        fitted to the scan lies under.

    Returns
    -------
    Hair
    """
    import trimesh

    from stimulus_engine.geometry.closest import SurfaceIndex, lift_out
    from stimulus_engine.geometry.ramps import smoothstep

    asset = hair_asset(style)
    lm = rig.landmark_points()
    skin_faces = rig.faces[rig.face_part == rig.part_names.index("skin")]
    v = np.asarray(rig.vertices, np.float64)
    scale, shift = _axis_fit(asset.head, head_points(v[np.unique(skin_faces)], lm["eye_right"], lm["eye_left"]))
    index = SurfaceIndex(v, skin_faces)
    hit = index.query(asset.anchors * scale + shift)
    corners = skin_faces[hit.face]
    normals = trimesh.Trimesh(v, skin_faces, process=False).vertex_normals
    n = np.einsum("mk,mkd->md", hit.bary, normals[corners])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    iod = float(np.linalg.norm(lm["eye_left"] - lm["eye_right"]))
    lift = np.maximum(asset.lift * float(np.mean(np.abs(scale))), MIN_LIFT_IOD * iod)
    source_iod = float(np.linalg.norm(asset.head[1] - asset.head[0]))
    hang = smoothstep((np.linalg.norm(asset.offset, axis=1) / source_iod - HANG_IOD[0]) / (HANG_IOD[1] - HANG_IOD[0]))[:, None]
    offset = (1 - hang) * lift[:, None] * n + hang * asset.offset * scale
    # a hanging lock placed by its offset can land inside a head shaped unlike the source (a
    # fringe on a steeper forehead): out to the smallest lift over the skin it is in; and over
    # an outer surface the hair must cover (a scan's own sculpted hair)
    base = np.einsum("mk,mkd->md", hit.bary, v[corners])
    pos = lift_out(base + offset, index, normals, MIN_LIFT_IOD * iod)
    if over is not None:
        ov, of = (np.asarray(a) for a in over)
        pos = lift_out(pos, SurfaceIndex(ov, of), trimesh.Trimesh(ov, of, process=False).vertex_normals,
                       OVER_LIFT_IOD * iod, OVER_REACH_IOD * iod)
    offset = pos - base
    return Hair(corners, hit.bary, offset, asset.faces, asset.uv, asset.texture,
                tuple(float(c) for c in (colour or DEFAULT_COLOUR)))


def hair_arrays(hair: Hair | None, prefix: str = "hair_") -> dict[str, np.ndarray]:
    """``hair`` as named arrays (for an ``.npz``; empty for none); see :func:`hair_from_arrays`."""
    return part_arrays(hair, prefix)


def hair_from_arrays(arrays, prefix: str = "hair_") -> Hair | None:
    """The :class:`Hair` stored by :func:`hair_arrays` in ``arrays`` (a mapping or an npz), or None."""
    return part_from_arrays(Hair, arrays, prefix)
