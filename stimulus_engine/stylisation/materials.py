"""Material stylisation as arrays: albedo textures and their normal and specular maps.

Albedo stylisation (thesis ch. 5 & §6.3, material levels 1a …):

``original``  the albedo as is.
``blur25`` / ``blur50``  Gaussian blur with the thesis's 25 and 50 px kernels *at 4k*, scaled to
    the texture's size; skin and lips (and brows, hair) are blurred separately where masks exist
    (normalised convolution inside each region), so colours do not bleed across region borders.
``bilateral``  edge-preserving blur (OpenCV bilateral filter, repeated): skin detail goes,
    region borders stay.
``flat``  a "cartoon" albedo: every region becomes its mean colour.
``painted``  one continuous family from the original (``amount`` 0) to paint (1): detail removal
    (a region-wise Gaussian blur growing to :data:`PAINT_BLUR_AT_4K` px at 4k by ``amount``
    :data:`PAINT_BLUR_UNTIL`), then the blurred albedo blended into paint by amount 1: each region
    (skin, lips, hair, the skin's dark features — brows, lash lines, nostrils) one colour of the
    character's own, the borders softened (:data:`PAINT_FLAT_SHARE`). A grid spaces its levels by measured image distance
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
    "paint_masks",
]

#: Albedo stylisations.
MATERIAL_STYLES: tuple[str, ...] = ("original", "blur25", "blur50", "bilateral", "flat", "painted")
#: Material stylisation levels 0..4 (thesis: realistic → cartoon albedo).
MATERIAL_LEVELS: dict[int, str] = dict(enumerate(MATERIAL_STYLES[:5]))
#: ``painted``: the blur's kernel at full detail removal (px at 4k, as the thesis's blur25 and
#: blur50) and the amount where it is reached; from there on the colours flatten.
PAINT_BLUR_AT_4K, PAINT_BLUR_UNTIL = 100, 0.5
#: ... and at amount 1 each region is this share paint (its one colour, :func:`_paint`), the rest the
#: blurred albedo's gradients. Wholly (issue 48: "paint that is paint"; the thesis's m0 is flat colour):
#: at a half share the most painted level kept 0.54x and 0.57x of james's and Lee Perry-Smith's cheek
#: detail, a photograph's sockets and blotches. What keeps a face its own is then its colours and its
#: dark features (brows, lash lines), kept as a region of their own (:data:`FEATURE_DARKNESS`).
PAINT_FLAT_SHARE = 1.0
#: Paint keeps the dark features drawn in the skin (brows, lash lines, nostrils) as a region of their
#: own: lighter than this share of the skin's median luminance, in pieces of at least this share of the
#: texture (the thesis's m0 is flat colour; wholly flat over one skin region, a scan's brows went).
FEATURE_DARKNESS, FEATURE_MIN_AREA = 0.72, 2e-4
#: ... and of at least this share of the largest one (the brows): a photograph's moles and blotches go.
FEATURE_SHARE_OF_LARGEST = 0.25
#: The width (px at 4k) over which paint's region borders are softened.
PAINT_EDGE_AT_4K = 16
#: The mask of texels no triangle samples, left as they are (:func:`_regions`).
UNUSED = "unused"

def _gauss_sigma(kernel_at_4k: int, size: int) -> float:
    """σ of the thesis's kernel (px at 4096) scaled to ``size``, with OpenCV's kernel→σ rule."""
    k = kernel_at_4k * size / 4096.0
    return max(0.3 * ((k - 1) * 0.5 - 1) + 0.8, 0.3)


def _kernel(sigma: float) -> np.ndarray:
    """scipy's Gaussian kernel (truncated at 4 σ, normalised), float32."""
    r = int(4.0 * sigma + 0.5)
    k = np.exp(-0.5 * (np.arange(-r, r + 1, dtype=np.float64) / sigma) ** 2)
    return (k / k.sum()).astype(np.float32)


def _wrapped(img: np.ndarray, rows: slice, cols: slice, r: int) -> np.ndarray:
    """The window ``rows`` x ``cols`` of ``img`` with an ``r``-pixel margin, the image's borders periodic."""
    h, w = img.shape[:2]
    r0, r1, c0, c1 = rows.start - r, rows.stop + r, cols.start - r, cols.stop + r
    if r0 >= 0 and c0 >= 0 and r1 <= h and c1 <= w:  # inside: a view
        return img[r0:r1, c0:c1]
    return img[np.ix_(np.arange(r0, r1) % h, np.arange(c0, c1) % w)]


def _separable(padded: np.ndarray, k: np.ndarray) -> np.ndarray:
    """One separable OpenCV filter (float32) over a copy padded by the kernel's radius; the inside."""
    import cv2

    r = len(k) // 2
    out = cv2.sepFilter2D(np.ascontiguousarray(padded, np.float32), cv2.CV_32F, k, k,
                          borderType=cv2.BORDER_CONSTANT)
    return out[r:out.shape[0] - r, r:out.shape[1] - r] if r else out


def _regions(masks: dict[str, np.ndarray], shape: tuple[int, int]) -> list[np.ndarray]:
    """Disjoint soft region weights that sum to 1: each mask, then skin (the rest).

    A mask named ``unused`` (texels no triangle samples: :mod:`stimulus_engine.characters.scan_regions`)
    is taken out of the others but not returned: it is left as it is (filtering the empty part
    of a scan's texture was most of a material's time).
    """
    rest = np.ones(shape, np.float32)
    out = []
    for name in sorted(masks):
        m = np.clip(np.asarray(masks[name], np.float32), 0, 1) * rest
        if name != UNUSED:
            out.append(m)
        rest = rest - m
    out.append(rest)
    return out


def _left(f: np.ndarray, regions: list[np.ndarray]) -> np.ndarray:
    """``f`` where no region is (the unused texels), zero elsewhere."""
    return f * np.clip(1.0 - sum(regions), 0.0, 1.0)[..., None]


def _window(w: np.ndarray) -> tuple[slice, slice] | None:
    """The rows and columns spanned by a region's nonzero weights (None when it is empty)."""
    rows, cols = np.flatnonzero(w.any(axis=1)), np.flatnonzero(w.any(axis=0))
    if not len(rows):
        return None
    return slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)


def _region_blur(f: np.ndarray, regions: list[np.ndarray], sigma: float) -> np.ndarray:
    """Each region blurred on its own (normalised convolution, over the region's window only,
    in float32), the regions put back together; texels of no region kept."""
    out = _left(f, regions).astype(np.float32)
    f32 = np.asarray(f, np.float32)
    k = _kernel(sigma)
    for w in regions:
        span = _window(w)
        if span is None:
            continue
        pw = _wrapped(w, *span, len(k) // 2)[..., None]
        both = _separable(np.concatenate([_wrapped(f32, *span, len(k) // 2) * pw, pw], axis=2), k)
        out[span] += w[span][..., None] * both[..., :-1] / np.maximum(both[..., -1:], 1e-6)
    return out


def _region_means(f: np.ndarray, regions: list[np.ndarray]) -> np.ndarray:
    """Every region its mean colour; texels of no region kept."""
    out = _left(f, regions)
    for w in regions:
        span = _window(w)
        if span is not None:
            out[span] += w[span][..., None] * _mean(f[span], w[span]).astype(out.dtype)
    return out


def _dark_features(f: np.ndarray, skin: np.ndarray) -> np.ndarray:
    """Soft weights of the dark features drawn in the skin (brows, lash lines): skin texels whose lightly
    blurred luminance is below :data:`FEATURE_DARKNESS` of the skin's median, in pieces of at least
    :data:`FEATURE_MIN_AREA` of the texture and :data:`FEATURE_SHARE_OF_LARGEST` of the largest piece
    (speckle — stubble, pores — and a photograph's moles are no features)."""
    from scipy import ndimage

    lum = f[..., :3] @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    size = f.shape[1]
    core = skin > 0.5
    if core.sum() < 100:
        return np.zeros(skin.shape, np.float32)
    blurred = ndimage.gaussian_filter(lum, 0.002 * size)
    dark = core & (blurred < FEATURE_DARKNESS * float(np.median(lum[core])))
    labels, n = ndimage.label(dark)
    if n:
        area = ndimage.sum(dark, labels, np.arange(1, n + 1))
        keep = (area >= FEATURE_MIN_AREA * dark.size) & (area >= FEATURE_SHARE_OF_LARGEST * area.max())
        dark = np.isin(labels, 1 + np.flatnonzero(keep))
    return np.minimum(ndimage.gaussian_filter(dark.astype(np.float32), 0.0015 * size), skin)


def _paint(f: np.ndarray, regions: list[np.ndarray]) -> np.ndarray:
    """Paint: each region one colour (its mean), every border softened (:data:`PAINT_EDGE_AT_4K`), so no
    speckle of a photograph's regions shows (the skin's dark features are a region of their own:
    :func:`paint_masks`)."""
    from scipy import ndimage

    edge = PAINT_EDGE_AT_4K * f.shape[1] / 4096.0
    soft = [ndimage.gaussian_filter(r, edge) for r in regions]
    total = np.maximum(sum(soft), 1e-6)
    inside = sum(regions)  # texels of no region (unused) stay as they are
    return _left(f, regions) + sum((w * inside / total)[..., None] * _mean(f, r) for w, r in zip(soft, regions))


def _mean(f: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The colour of ``f`` weighted by ``w`` (zeros for an empty region; one BLAS product)."""
    total = float(w.sum(dtype=np.float64))
    if total <= 0:
        return np.zeros(f.shape[-1], np.float32)
    return (w.reshape(-1) @ f.reshape(w.size, -1) / total).astype(np.float32)


def _painted(f: np.ndarray, regions: list[np.ndarray], amount: float) -> np.ndarray:
    """The ``painted`` family at ``amount`` (see the module docstring)."""
    if amount <= 0:
        return f
    sigma = _gauss_sigma(PAINT_BLUR_AT_4K, f.shape[1]) * min(amount / PAINT_BLUR_UNTIL, 1.0)
    blurred = _region_blur(f, regions, max(sigma, 0.3))
    if amount <= PAINT_BLUR_UNTIL:
        return blurred
    w = PAINT_FLAT_SHARE * (amount - PAINT_BLUR_UNTIL) / (1.0 - PAINT_BLUR_UNTIL)
    return (1 - w) * blurred + w * _paint(f, regions)


def _operated(img: np.ndarray, style: str, masks: dict[str, np.ndarray], amount: float) -> np.ndarray:
    """The style's operator on (H, W, C) uint8 channels, each on its own (module docstring)."""
    import cv2

    if style == "original":
        return img.copy()
    if style == "bilateral":  # on colour triples (a single channel as a grey triple)
        d = max(5, int(round(img.shape[1] / 128)) | 1)
        out8 = np.ascontiguousarray(img if img.shape[2] == 3 else np.repeat(img[..., :1], 3, axis=2))
        for _ in range(4):
            out8 = cv2.bilateralFilter(out8, d, 35, d * 2)
        return out8[..., :img.shape[2]].copy()
    f = img.astype(np.float32)
    regions = _regions(masks, img.shape[:2])
    if style in ("blur25", "blur50"):
        out = _region_blur(f, regions, _gauss_sigma(25 if style == "blur25" else 50, img.shape[1]))
    elif style == "painted":
        out = _painted(f, regions, amount)
    else:  # flat
        out = _region_means(f, regions)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def _checked(style: str, amount: float) -> None:
    if style not in MATERIAL_STYLES:
        raise ValueError(f"unknown material style '{style}' (expected one of: {', '.join(MATERIAL_STYLES)})")
    if not 0.0 <= amount <= 1.0:
        raise ValueError(f"material amount must be within 0..1 (got {amount})")


def paint_masks(albedo: np.ndarray, masks: dict[str, np.ndarray] | None, style: str,
                amount: float) -> dict[str, np.ndarray]:
    """``masks`` with the skin's dark features (brows, lash lines; :func:`_dark_features`) as a region of
    their own, ``features``, where the ``painted`` family paints (amount above :data:`PAINT_BLUR_UNTIL`);
    ``masks`` as they are otherwise. The albedo's features are its maps' too (:func:`stylise_material`)."""
    masks = dict(masks or {})
    if style != "painted" or amount <= PAINT_BLUR_UNTIL or "features" in masks:
        return masks
    img = np.asarray(albedo)
    if any(np.shape(m) != img.shape[:2] for m in masks.values()):
        return masks
    skin = _regions(masks, img.shape[:2])[-1]
    masks["features"] = _dark_features(img[..., :3].astype(np.float32), skin)
    return masks


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
    _checked(style, amount)
    img = np.asarray(albedo, np.uint8)[..., :3]
    return _operated(img, style, paint_masks(img, masks, style, amount), amount)


def stylise_photograph(image: np.ndarray, style: str, amount: float = 1.0) -> np.ndarray:
    """A photograph (a photo character's head and shoulders behind it) stylised as its face's
    material ``style`` is.

    The albedo operators work on a face's texture, in regions its masks give; a photograph has no
    such regions (hair, clothes and background meet anywhere), and the region-flattening of
    ``painted`` and ``flat`` left a single blob of it. So ``painted`` (by ``amount``) and ``flat``
    (fully) blend toward OpenCV's edge-preserving stylisation (Gastal & Oliveira's domain
    transform: flat colour areas with their edges kept, as a painted background is); ``blur*`` and
    ``bilateral`` run as on the albedo; ``original`` is the photograph.
    """
    import cv2

    _checked(style, amount)
    img = np.asarray(image, np.uint8)[..., :3]
    if style == "original" or (style == "painted" and amount == 0.0):
        return img
    if style in ("painted", "flat"):
        a = 1.0 if style == "flat" else float(amount)
        side = max(img.shape[:2])
        painted = cv2.stylization(np.ascontiguousarray(img), sigma_s=min(200.0, 0.05 * side), sigma_r=0.35)
        painted = cv2.edgePreservingFilter(painted, flags=cv2.RECURS_FILTER, sigma_s=min(200.0, 0.03 * side),
                                           sigma_r=0.5)
        return np.clip(np.rint((1 - a) * img + a * painted), 0, 255).astype(np.uint8)
    return stylise_albedo(img, style, {}, amount)


def _unit_normals(code: np.ndarray) -> np.ndarray:
    """Normal-map RGB codes whose vectors were filtered, made unit vectors again (facing out)."""
    out = code.astype(np.float64) / 255 * 2 - 1
    out[..., 2] = np.maximum(out[..., 2], 1e-3)
    out /= np.linalg.norm(out, axis=-1, keepdims=True)
    return np.clip(np.rint((out + 1) / 2 * 255), 0, 255).astype(np.uint8)


def stylise_map(image: np.ndarray, kind: str, style: str, masks: dict[str, np.ndarray] | None = None,
                amount: float = 1.0) -> np.ndarray:
    """Stylise a normal or specular map with the albedo's operator (:func:`stylise_albedo`).

    Normal maps are stylised as vectors (the RGB codes are filtered, then renormalised), so a
    blurred material has softened pores and ``flat`` leaves one mean normal per region (≈ flat).
    """
    _checked(style, amount)
    img = np.asarray(image, np.uint8)
    if kind == "specular":
        return _operated(img[..., None], style, masks or {}, amount)[..., 0]
    out = _operated(img, style, masks or {}, amount)
    return out if style == "original" else _unit_normals(out)


def stylise_material(albedo: np.ndarray, style: str, masks: dict[str, np.ndarray] | None = None,
                     maps: dict[str, np.ndarray] | None = None,
                     amount: float = 1.0) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A material's albedo and maps stylised with one operator (one call per material).

    The filters work on each channel alone, so the albedo's and the maps' channels (in the
    albedo's layout) are filtered together, as one stack: the regions, their windows and their
    weights' blur are found once, not once per texture (the bilateral filter, which compares
    colours, keeps each texture apart).

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
    _checked(style, amount)
    maps = maps or {}
    img = np.asarray(albedo, np.uint8)[..., :3]
    masks = paint_masks(img, masks, style, amount)
    size = img.shape[:2]
    map_masks = masks if all(np.shape(v) == size for v in masks.values()) else {}
    if style in ("original", "bilateral") or map_masks is not masks or any(np.shape(a)[:2] != size for a in maps.values()):
        return (stylise_albedo(img, style, masks, amount),
                {kind: stylise_map(a, kind, style, map_masks, amount) for kind, a in maps.items()})
    layers = [img] + [np.asarray(a, np.uint8).reshape(*size, -1) for a in maps.values()]
    out = np.split(_operated(np.concatenate(layers, axis=2), style, masks, amount),
                   np.cumsum([x.shape[2] for x in layers])[:-1], axis=2)
    return out[0], {kind: _unit_normals(o) if kind == "normal" else o[..., 0]
                    for kind, o in zip(maps, out[1:])}


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
