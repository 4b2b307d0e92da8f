"""A character's own skin maps, as arrays in its UV layout: albedo, pore normals, specularity.

:func:`rig_albedo` is the rig's texture, or one painted on its UVs by code (rigs without a
texture, such as the ICT model); :func:`rig_detail_maps` paints a skin-pore normal map and a
specular map the same way. Maps a user gives are checked by :func:`check_map`
(:data:`MAP_KINDS`):

``normal``  tangent-space normal map, RGB (OpenGL convention: R = +u, G = +v, B out of the
    surface; flat = :data:`FLAT_NORMAL`); pyrender builds the tangent frame per pixel from the
    UV derivatives, so no tangents are needed on the mesh.
``specular``  greyscale specularity ``s`` (white = shiny, mid-grey = the look without a map);
    it sets the roughness (``pbr``) or the specular level and glossiness (``phong``).

How a material level stylises them: :mod:`stimulus_engine.stylisation.materials`.
"""

from __future__ import annotations

import functools

import numpy as np

from stimulus_engine.characters.rig import FaceRig

__all__ = ["FLAT_NORMAL", "MAP_KINDS", "bake_surface_points", "check_map", "rig_albedo", "rig_detail_maps"]

#: Texture maps a material may carry besides its albedo.
MAP_KINDS: tuple[str, ...] = ("normal", "specular")
#: The tangent-space normal map value of an unperturbed surface.
FLAT_NORMAL: tuple[int, int, int] = (128, 128, 255)


def check_map(image: np.ndarray, kind: str, size: tuple[int, int] | None = None) -> np.ndarray:
    """Validate a normal or specular map and return it as uint8 (normal (H, W, 3), specular (H, W)).

    Parameters
    ----------
    image : array
        As read from the file: (H, W), (H, W, 1), (H, W, 3) or (H, W, 4).
    kind : {"normal", "specular"}
    size : (height, width), optional
        The albedo's size; the map must match it (it shares the albedo's UV layout).

    Raises
    ------
    ValueError
        One line saying what was expected (wrong channels, size, or an object-space normal map).
    """
    a = np.asarray(image)
    if a.dtype != np.uint8:
        if a.dtype.kind not in "ui" or a.max(initial=0) > 255:
            raise ValueError(f"expected an 8-bit image (got {a.dtype.name} values)")
        a = a.astype(np.uint8)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[..., 0]
    if kind == "normal":
        if a.ndim != 3 or a.shape[2] not in (3, 4):
            raise ValueError("expected an RGB tangent-space normal map (got "
                             f"{'a greyscale image' if a.ndim == 2 else f'{a.shape[2]} channels'})")
        a = a[..., :3]
        if a[..., 2].mean() < 160:
            raise ValueError(f"expected a tangent-space normal map, mostly blue (mean blue {a[..., 2].mean():.0f} "
                             "of 255; an object-space or height map?)")
    elif kind == "specular":
        if a.ndim == 3:
            if a.shape[2] == 4:
                a = a[..., :3]
            if a.shape[2] != 3 or not (np.array_equal(a[..., 0], a[..., 1]) and np.array_equal(a[..., 0], a[..., 2])):
                raise ValueError("expected a greyscale specular map (white = shiny; got colour channels that differ)")
            a = a[..., 0]
    else:
        raise ValueError(f"unknown map kind '{kind}' (expected one of: {', '.join(MAP_KINDS)})")
    if size is not None and tuple(a.shape[:2]) != tuple(size):
        raise ValueError(f"expected {size[1]} x {size[0]} pixels like the albedo it belongs to "
                         f"(got {a.shape[1]} x {a.shape[0]})")
    return np.ascontiguousarray(a)


def bake_surface_points(rig: FaceRig, size: int, part: str = "skin") -> tuple[np.ndarray, np.ndarray]:
    """The 3D neutral point under every texel of ``part`` (rasterising the UV layout).

    Returns
    -------
    points : (size, size, 3) array
        Texture row 0 is the top of the image (UV v = 1).
    valid : (size, size) bool array
        Texels covered by a triangle of the part.
    """
    if rig.uv is None or rig.face_uv is None:
        raise ValueError(f"rig '{rig.name}' has no UVs (a texture needs them)")
    from stimulus_engine.geometry.uv_raster import rasterize_uv

    sel = np.flatnonzero(rig.face_part == rig.part_names.index(part))
    # texel centres inside a UV triangle (row 0 = v 1; where UV islands overlap the later
    # triangle wins), vectorised by the texture transfer's rasteriser
    rows, cols, fid, bary = rasterize_uv(rig.uv, rig.face_uv[sel], size, size)
    pts = np.zeros((size, size, 3))
    valid = np.zeros((size, size), bool)
    pts[rows, cols] = np.einsum("ij,ijk->ik", bary, rig.vertices[rig.faces[sel][fid]])
    valid[rows, cols] = True
    return pts, valid


@functools.lru_cache(maxsize=16)
def _painted(rig_key: str, rig_id: int, size: int, seed: int, rig_ref: tuple) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    from stimulus_engine.characters.procedural_head import paint_albedo_at

    rig = rig_ref[0]
    pts, valid = bake_surface_points(rig, size)
    lm = rig.landmark_points()
    anchors = {
        "mouth": (lm["mouth_right"] + lm["mouth_left"]) / 2,
        "mouth_half": float(np.linalg.norm(lm["mouth_left"] - lm["mouth_right"])) / 2,
        "brow_right": lm["brow_right"], "brow_left": lm["brow_left"],
        "eye_right": lm["eye_right"], "eye_left": lm["eye_left"], "hairline": float(lm["forehead_top"][1]) - 0.3,
    }
    rng = np.random.default_rng(seed)
    j = lambda s: 1 + s * rng.uniform(-1, 1)  # noqa: E731
    colours = {"skin": tuple(np.array([0.80, 0.60, 0.50]) * j(0.12)), "lips": (0.62, 0.30, 0.30),
               "hair": tuple(np.array([0.22, 0.14, 0.09]) * j(0.3))}
    return paint_albedo_at(pts, anchors, colours, rng, valid)


class _Ref(tuple):
    """Hashes by identity (lets a rig ride through ``lru_cache`` without hashing arrays)."""

    def __hash__(self) -> int:  # noqa: D105
        return id(self[0])

    def __eq__(self, other: object) -> bool:  # noqa: D105
        return isinstance(other, tuple) and len(other) == 1 and other[0] is self[0]


def rig_albedo(rig: FaceRig, *, size: int = 1024, seed: int = 0) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The rig's albedo and region masks: its own texture, else one painted on its UVs by code.

    Rigs without a texture (the ICT model ships none) get a procedural skin texture painted at
    the 3D point of every texel (skin tone with noise, lips, brows, blush, hair) from ``seed``.
    """
    if rig.texture is not None:
        return rig.texture, rig.texture_masks
    if rig.uv is None:
        raise ValueError(f"rig '{rig.name}' has neither a texture nor UVs to paint one on")
    return _painted(rig.name, id(rig), int(size), int(seed), _Ref((rig,)))


@functools.lru_cache(maxsize=8)
def _detail(rig_id: int, size: int, seed: int, rig_ref: tuple) -> tuple[np.ndarray, np.ndarray]:
    from stimulus_engine.characters.procedural_head import paint_detail_maps_at

    rig = rig_ref[0]
    pts, valid = bake_surface_points(rig, size)
    albedo, masks = rig_albedo(rig, size=size, seed=seed)
    masks = masks if all(np.shape(m) == (size, size) for m in masks.values()) else {}
    return paint_detail_maps_at(pts, valid, rig.landmark_points(), masks, seed)


def rig_detail_maps(rig: FaceRig, *, size: int | None = None, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A skin-pore normal map and a specular map painted by code in the rig's UV layout.

    Pores are small pits of 3D noise at the 3D point of every texel (mild: about 3° RMS tilt),
    so they have the same size everywhere on the face whatever the UV stretch; the specular
    map makes forehead, nose, chin and lips shinier than the cheeks, and hair and brows matt
    (:func:`stimulus_engine.characters.procedural_head.paint_detail_maps_at`).

    Parameters
    ----------
    rig : FaceRig
        Needs UVs.
    size : int, optional
        Map size (default: the rig's texture size, else 1024).
    seed : int
        Pore pattern (and the painted albedo's seed where the rig has no texture, for the masks).

    Returns
    -------
    normal : (size, size, 3) uint8
    specular : (size, size) uint8
    """
    if rig.uv is None or rig.face_uv is None:
        raise ValueError(f"rig '{rig.name}' has no UVs (normal and specular maps need them)")
    if size is None:
        size = rig.texture.shape[0] if rig.texture is not None else 1024
    return _detail(id(rig), int(size), int(seed), _Ref((rig,)))
