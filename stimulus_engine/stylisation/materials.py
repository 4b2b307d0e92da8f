"""Material stylisation as arrays: albedo textures and their normal and specular maps.

Albedo stylisation (thesis ch. 5 & §6.3, material levels 1a …):

``original``  the albedo as is.
``blur25`` / ``blur50``  Gaussian blur with the thesis's 25 and 50 px kernels *at 4k*, scaled to
    the texture's size; skin and lips (and brows, hair) are blurred separately where masks exist
    (normalised convolution inside each region), so colours do not bleed across region borders.
``bilateral``  edge-preserving blur (OpenCV bilateral filter, repeated): skin detail goes,
    region borders stay.
``flat``  a "cartoon" albedo: every region becomes its mean colour.
``painted``  one continuous family from the original (``amount`` 0) to painted regions (1):
    detail removal (a region-wise Gaussian blur growing to :data:`PAINT_BLUR_AT_4K` px at 4k
    by ``amount`` :data:`PAINT_BLUR_UNTIL`), then colour flattening (the blurred albedo blended
    half-way into each region's mean colour by amount 1: gradient regions, :data:`PAINT_FLAT_SHARE`). A grid spaces its levels by measured image distance
    (:mod:`stimulus_engine.grid.continuum`), not by ``amount``.

:data:`MATERIAL_LEVELS` orders them as a five-step material-stylisation axis (0 = original …
4 = flat). :func:`stylise_map` stylises a character's normal and specular maps
(:mod:`stimulus_engine.characters.skin_maps`) with the albedo's operator, so a blurred or flat
material is blurred or flat in every channel (:func:`stylise_material`: albedo and maps in one
call). Everything here returns arrays; a render engine turns them into its own materials
(pyrender: :mod:`stimulus_engine.characters.render_parts`, with its shading models).
"""

from __future__ import annotations

import hashlib

import numpy as np

__all__ = [
    "MATERIAL_LEVELS",
    "MATERIAL_STYLES",
    "albedo_hash",
    "maps_hash",
    "stylise_albedo",
    "stylise_map",
    "stylise_material",
]

#: Albedo stylisations.
MATERIAL_STYLES: tuple[str, ...] = ("original", "blur25", "blur50", "bilateral", "flat", "painted")
#: Material stylisation levels 0..4 (thesis: realistic → cartoon albedo).
MATERIAL_LEVELS: dict[int, str] = dict(enumerate(MATERIAL_STYLES[:5]))
#: ``painted``: the blur's kernel at full detail removal (px at 4k, as the thesis's blur25 and
#: blur50) and the amount where it is reached; from there on the colours flatten.
PAINT_BLUR_AT_4K, PAINT_BLUR_UNTIL = 100, 0.5
#: ... and at amount 1 each region is this share its mean colour, the rest the blurred albedo's
#: gradients (painted regions that keep the brows and the face's shading in the paint: wholly
#: flat, the ERP grid's most stylised Lee Perry-Smith lost his brows and lay 0.756 from his
#: realistic face, farther than from james's, 0.746; at a half share 0.72, and james 0.70 -> 0.58).
PAINT_FLAT_SHARE = 0.5

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


def _region_blur(f: np.ndarray, regions: list[np.ndarray], sigma: float) -> np.ndarray:
    """Each region blurred on its own (normalised convolution), the regions put back together."""
    out = np.zeros_like(f)
    for w in regions:
        if not w.any():
            continue
        num = _gaussian_wrap(f * w[..., None], sigma)
        den = _gaussian_wrap(w, sigma)[..., None]
        out += w[..., None] * num / np.maximum(den, 1e-6)
    return out


def _region_means(f: np.ndarray, regions: list[np.ndarray]) -> np.ndarray:
    """Every region its mean colour."""
    out = np.zeros_like(f)
    for w in regions:
        if w.sum() > 0:
            out += w[..., None] * ((f * w[..., None]).sum(axis=(0, 1)) / w.sum())
    return out


def _painted(f: np.ndarray, regions: list[np.ndarray], amount: float) -> np.ndarray:
    """The ``painted`` family at ``amount`` (see the module docstring)."""
    if amount <= 0:
        return f
    sigma = _gauss_sigma(PAINT_BLUR_AT_4K, f.shape[1]) * min(amount / PAINT_BLUR_UNTIL, 1.0)
    blurred = _region_blur(f, regions, max(sigma, 0.3))
    if amount <= PAINT_BLUR_UNTIL:
        return blurred
    w = PAINT_FLAT_SHARE * (amount - PAINT_BLUR_UNTIL) / (1.0 - PAINT_BLUR_UNTIL)
    return (1 - w) * blurred + w * _region_means(f, regions)


def stylise_albedo(albedo: np.ndarray, style: str, masks: dict[str, np.ndarray] | None = None,
                   amount: float = 1.0) -> np.ndarray:
    """Stylise an albedo texture.

    Parameters
    ----------
    albedo : (H, W, 3) uint8 array
    style : str
        One of :data:`MATERIAL_STYLES`.
    masks : dict of str to (H, W) float arrays, optional
        Regions stylised separately (``lips``, ``brows``, ``hair``); the rest is skin.
    amount : float
        How far along the ``painted`` family (0 the original .. 1 painted regions); other
        styles ignore it.

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
    if not 0.0 <= amount <= 1.0:
        raise ValueError(f"material amount must be within 0..1 (got {amount})")
    if style in ("blur25", "blur50"):
        out = _region_blur(f, regions, _gauss_sigma(25 if style == "blur25" else 50, img.shape[1]))
    elif style == "painted":
        out = _painted(f, regions, amount)
    elif style == "bilateral":
        d = max(5, int(round(img.shape[1] / 128)) | 1)
        out8 = img.copy()
        for _ in range(4):
            out8 = cv2.bilateralFilter(out8, d, 35, d * 2)
        return out8
    else:  # flat
        out = _region_means(f, regions)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def stylise_map(image: np.ndarray, kind: str, style: str, masks: dict[str, np.ndarray] | None = None,
                amount: float = 1.0) -> np.ndarray:
    """Stylise a normal or specular map with the albedo's operator (:func:`stylise_albedo`).

    Normal maps are stylised as vectors (the RGB codes are filtered, then renormalised), so a
    blurred material has softened pores and ``flat`` leaves one mean normal per region (≈ flat).
    """
    if style == "original":
        return np.asarray(image, np.uint8).copy()
    if kind == "specular":
        g = np.asarray(image, np.uint8)
        return stylise_albedo(np.repeat(g[..., None], 3, axis=2), style, masks, amount)[..., 0].copy()
    out = stylise_albedo(image, style, masks, amount).astype(np.float64) / 255 * 2 - 1
    out[..., 2] = np.maximum(out[..., 2], 1e-3)
    out /= np.linalg.norm(out, axis=-1, keepdims=True)
    return np.clip(np.rint((out + 1) / 2 * 255), 0, 255).astype(np.uint8)


def stylise_material(albedo: np.ndarray, style: str, masks: dict[str, np.ndarray] | None = None,
                     maps: dict[str, np.ndarray] | None = None,
                     amount: float = 1.0) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A material's albedo and maps stylised with one operator (one call per material).

    Parameters
    ----------
    albedo, style, masks, amount
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
    return (stylise_albedo(albedo, style, masks, amount),
            {kind: stylise_map(a, kind, style, map_masks, amount) for kind, a in (maps or {}).items()})


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
