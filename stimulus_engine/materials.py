"""Materials as arrays: albedo textures, normal and specular maps, and their stylisation.

Albedo stylisation (thesis ch. 5 & §6.3, material levels 1a …):

``original``  the albedo as is.
``blur25`` / ``blur50``  Gaussian blur with the thesis's 25 and 50 px kernels *at 4k*, scaled to
    the texture's size; skin and lips (and brows, hair) are blurred separately where masks exist
    (normalised convolution inside each region), so colours do not bleed across region borders.
``bilateral``  edge-preserving blur (OpenCV bilateral filter, repeated): skin detail goes,
    region borders stay.
``flat``  a "cartoon" albedo: every region becomes its mean colour.

:data:`MATERIAL_LEVELS` orders them as a five-step material-stylisation axis (0 = original …
4 = flat). Shading models (:data:`SHADINGS`): ``pbr`` (metallic-roughness), ``phong``
(specular-glossiness, Blinn-Phong: the thesis's contrast to PBR) and ``skin`` (PBR with
scattering-softened skin, wet eyes and a filmic tone curve: :mod:`stimulus_engine.render.skin_shader`);
how an engine draws them: :mod:`stimulus_engine.render.rig_parts`.

Optional maps on the skin, in the albedo's UV layout (:data:`MAP_KINDS`):

``normal``  tangent-space normal map, RGB (OpenGL convention: R = +u, G = +v, B out of the
    surface; flat = (128, 128, 255)); pyrender builds the tangent frame per pixel from the UV
    derivatives, so no tangents are needed on the mesh.
``specular``  greyscale specularity ``s`` (white = shiny, mid-grey = the look without a map);
    it sets the roughness (``pbr``) or the specular level and glossiness (``phong``).

:func:`stylise_map` stylises the maps with the albedo's operator, so a blurred or flat material
is blurred or flat in every channel (:func:`stylise_material`: albedo and maps in one call);
:func:`rig_detail_maps` paints both maps by code. Everything here returns arrays; a render
engine turns them into its own materials (pyrender: :mod:`stimulus_engine.render.rig_parts`).
"""

from __future__ import annotations

import functools
import hashlib

import numpy as np
from stimulus_engine.rig import FaceRig

__all__ = [
    "FLAT_NORMAL",
    "MAP_KINDS",
    "MATERIAL_LEVELS",
    "MATERIAL_STYLES",
    "SHADINGS",
    "albedo_hash",
    "bake_surface_points",
    "check_map",
    "maps_hash",
    "rig_albedo",
    "rig_detail_maps",
    "stylise_albedo",
    "stylise_map",
    "stylise_material",
]

#: Albedo stylisations.
MATERIAL_STYLES: tuple[str, ...] = ("original", "blur25", "blur50", "bilateral", "flat")
#: Material stylisation levels 0..4 (thesis: realistic → cartoon albedo).
MATERIAL_LEVELS: dict[int, str] = dict(enumerate(MATERIAL_STYLES))
#: Shader models.
SHADINGS: tuple[str, ...] = ("pbr", "phong", "skin")
#: Texture maps a material may carry besides its albedo.
MAP_KINDS: tuple[str, ...] = ("normal", "specular")
#: The tangent-space normal map value of an unperturbed surface.
FLAT_NORMAL: tuple[int, int, int] = (128, 128, 255)

def _gauss_sigma(kernel_at_4k: int, size: int) -> float:
    """σ of the thesis's kernel (px at 4096) scaled to ``size``, with OpenCV's kernel→σ rule."""
    k = kernel_at_4k * size / 4096.0
    return max(0.3 * ((k - 1) * 0.5 - 1) + 0.8, 0.3)


def _gaussian_wrap(img: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur of (H, W[, C]) float64 with periodic borders, over rows and columns.

    The same kernel as ``scipy.ndimage.gaussian_filter(img, sigma, mode="wrap")`` (truncated at
    4 σ, normalised), applied as one separable OpenCV filter on a wrap-padded copy: equal to
    scipy's result up to floating-point summation order (~1e-13), 5–10 × faster.
    """
    import cv2

    r = int(4.0 * sigma + 0.5)
    x = np.arange(-r, r + 1, dtype=np.float64)
    k = np.exp(-0.5 * (x / sigma) ** 2)
    k /= k.sum()
    pad = ((r, r), (r, r)) + ((0, 0),) * (img.ndim - 2)
    big = np.pad(np.ascontiguousarray(img, np.float64), pad, mode="wrap")
    out = cv2.sepFilter2D(big, cv2.CV_64F, k, k, borderType=cv2.BORDER_CONSTANT)
    return out[r:-r, r:-r] if r else out


def _regions(masks: dict[str, np.ndarray], shape: tuple[int, int]) -> list[np.ndarray]:
    """Disjoint soft region weights that sum to 1: each mask, then skin (the rest)."""
    rest = np.ones(shape, np.float64)
    out = []
    for name in sorted(masks):
        m = np.clip(np.asarray(masks[name], np.float64), 0, 1) * rest
        out.append(m)
        rest = rest - m
    out.append(rest)
    return out


def stylise_albedo(albedo: np.ndarray, style: str, masks: dict[str, np.ndarray] | None = None) -> np.ndarray:
    """Stylise an albedo texture.

    Parameters
    ----------
    albedo : (H, W, 3) uint8 array
    style : str
        One of :data:`MATERIAL_STYLES`.
    masks : dict of str to (H, W) float arrays, optional
        Regions stylised separately (``lips``, ``brows``, ``hair``); the rest is skin.

    Returns
    -------
    (H, W, 3) uint8 array
    """
    import cv2

    if style not in MATERIAL_STYLES:
        raise ValueError(f"unknown material style '{style}' (expected one of: {', '.join(MATERIAL_STYLES)})")
    img = np.asarray(albedo, np.uint8)[..., :3]
    if style == "original":
        return img.copy()
    f = img.astype(np.float64)
    regions = _regions(masks or {}, img.shape[:2])
    if style in ("blur25", "blur50"):
        sigma = _gauss_sigma(25 if style == "blur25" else 50, img.shape[1])
        out = np.zeros_like(f)
        for w in regions:
            if not w.any():
                continue
            num = _gaussian_wrap(f * w[..., None], sigma)
            den = _gaussian_wrap(w, sigma)[..., None]
            out += w[..., None] * num / np.maximum(den, 1e-6)
    elif style == "bilateral":
        d = max(5, int(round(img.shape[1] / 128)) | 1)
        out8 = img.copy()
        for _ in range(4):
            out8 = cv2.bilateralFilter(out8, d, 35, d * 2)
        return out8
    else:  # flat
        out = np.zeros_like(f)
        for w in regions:
            if w.sum() > 0:
                mean = (f * w[..., None]).sum(axis=(0, 1)) / w.sum()
                out += w[..., None] * mean
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


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


def stylise_map(image: np.ndarray, kind: str, style: str, masks: dict[str, np.ndarray] | None = None) -> np.ndarray:
    """Stylise a normal or specular map with the albedo's operator (:func:`stylise_albedo`).

    Normal maps are stylised as vectors (the RGB codes are filtered, then renormalised), so a
    blurred material has softened pores and ``flat`` leaves one mean normal per region (≈ flat).
    """
    if style == "original":
        return np.asarray(image, np.uint8).copy()
    if kind == "specular":
        g = np.asarray(image, np.uint8)
        return stylise_albedo(np.repeat(g[..., None], 3, axis=2), style, masks)[..., 0].copy()
    out = stylise_albedo(image, style, masks).astype(np.float64) / 255 * 2 - 1
    out[..., 2] = np.maximum(out[..., 2], 1e-3)
    out /= np.linalg.norm(out, axis=-1, keepdims=True)
    return np.clip(np.rint((out + 1) / 2 * 255), 0, 255).astype(np.uint8)


def stylise_material(albedo: np.ndarray, style: str, masks: dict[str, np.ndarray] | None = None,
                     maps: dict[str, np.ndarray] | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A material's albedo and maps stylised with one operator (one call per material).

    Parameters
    ----------
    albedo, style, masks
        As for :func:`stylise_albedo`; the maps use ``masks`` only when every mask has the
        albedo's size.
    maps : dict, optional
        ``normal`` (H, W, 3) and/or ``specular`` (H, W) uint8 maps in the albedo's layout.

    Returns
    -------
    albedo : (H, W, 3) uint8 array
    maps : dict of str to uint8 array
        The maps given, stylised (:func:`stylise_map`), in the same order.
    """
    masks = masks or {}
    size = np.shape(albedo)[:2]
    map_masks = masks if all(np.shape(v) == size for v in masks.values()) else {}
    return (stylise_albedo(albedo, style, masks),
            {kind: stylise_map(a, kind, style, map_masks) for kind, a in (maps or {}).items()})


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
    from stimulus_engine.texture_transfer import rasterize_uv

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
    from stimulus_engine.procedural_head import paint_albedo_at

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
    from stimulus_engine.procedural_head import paint_detail_maps_at

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
    (:func:`stimulus_engine.procedural_head.paint_detail_maps_at`).

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


def maps_hash(normal: np.ndarray | None, specular: np.ndarray | None) -> str:
    """Short content hash of a material's normal and specular maps (``none`` without maps)."""
    if normal is None and specular is None:
        return "none"
    return f"{albedo_hash(normal)[:8]}{albedo_hash(specular)[:8]}"


def albedo_hash(albedo: np.ndarray | None) -> str:
    """Short content hash of an albedo (for manifests and up-to-date checks)."""
    if albedo is None:
        return "none"
    return hashlib.sha256(np.ascontiguousarray(albedo).tobytes()).hexdigest()[:16]
