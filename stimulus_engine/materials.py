"""Materials: albedo textures, their stylisation, shaders, and render parts for a face rig.

Albedo stylisation (thesis ch. 5 & §6.3, material levels 1a …):

``original``  the albedo as is.
``blur25`` / ``blur50``  Gaussian blur with the thesis's 25 and 50 px kernels *at 4k*, scaled to
    the texture's size; skin and lips (and brows, hair) are blurred separately where masks exist
    (normalised convolution inside each region), so colours do not bleed across region borders.
``bilateral``  edge-preserving blur (OpenCV bilateral filter, repeated): skin detail goes,
    region borders stay.
``flat``  a "cartoon" albedo: every region becomes its mean colour.

:data:`MATERIAL_LEVELS` orders them as a five-step material-stylisation axis (0 = original …
4 = flat). Shaders: ``pbr`` (metallic-roughness) and ``phong`` (specular-glossiness, a
Phong-like look with a sharper highlight).
"""

from __future__ import annotations

import functools
import hashlib

import numpy as np
import trimesh

from stimulus_engine.expressions import FaceRig

__all__ = [
    "MATERIAL_LEVELS",
    "MATERIAL_STYLES",
    "SHADINGS",
    "bake_surface_points",
    "rig_albedo",
    "rig_render_parts",
    "stylise_albedo",
]

#: Albedo stylisations.
MATERIAL_STYLES: tuple[str, ...] = ("original", "blur25", "blur50", "bilateral", "flat")
#: Material stylisation levels 0..4 (thesis: realistic → cartoon albedo).
MATERIAL_LEVELS: dict[int, str] = dict(enumerate(MATERIAL_STYLES))
#: Shader models.
SHADINGS: tuple[str, ...] = ("pbr", "phong")

#: Colours of the untextured parts (linear RGB, alpha). ``mouth`` is the mouth socket (dark, it
#: is mostly in shadow inside a real mouth), ``tongue`` gums and tongue.
_PART_COLOURS = {
    "sclera": (0.85, 0.83, 0.80, 1.0), "iris": (0.18, 0.22, 0.30, 1.0), "teeth": (0.82, 0.79, 0.70, 1.0),
    "mouth": (0.10, 0.025, 0.03, 1.0), "tongue": (0.30, 0.08, 0.09, 1.0), "lashes": (0.05, 0.04, 0.04, 1.0),
    "skin": (0.8, 0.62, 0.52, 1.0), "eye": (0.9, 0.88, 0.85, 1.0),
}
#: PBR roughness per part (wet eyes and teeth are glossy; the default is the skin's).
_PART_ROUGHNESS = {"eye": 0.18, "sclera": 0.25, "iris": 0.3, "teeth": 0.35, "tongue": 0.6, "mouth": 0.8}


def _gauss_sigma(kernel_at_4k: int, size: int) -> float:
    """σ of the thesis's kernel (px at 4096) scaled to ``size``, with OpenCV's kernel→σ rule."""
    k = kernel_at_4k * size / 4096.0
    return max(0.3 * ((k - 1) * 0.5 - 1) + 0.8, 0.3)


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
    from scipy.ndimage import gaussian_filter

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
            num = gaussian_filter(f * w[..., None], sigma=(sigma, sigma, 0), mode="wrap")
            den = gaussian_filter(w, sigma=sigma, mode="wrap")[..., None]
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


_MATERIALS: dict[tuple, tuple[object, object]] = {}


def _material(shading: str, colour: tuple[float, ...], texture: np.ndarray | None, roughness: float = 0.62) -> object:
    """A pyrender material; cached per (shading, colour, texture array, roughness) in this process.

    Reusing the same material (and so the same ``pyrender.Texture``) for every image that wears
    the same albedo lets the renderer keep the texture on the GPU (pyrender uploads a texture,
    and builds its mipmaps, only when it first appears in a scene): the texture upload was most
    of the per-image time on llvmpipe. The key holds the array's id and the entry the array
    itself, so a new array that reuses a freed id never hits a stale material.
    """
    key = (shading, tuple(colour), None if texture is None else id(texture), float(roughness))
    hit = _MATERIALS.get(key)
    if hit is not None and hit[0] is texture:
        return hit[1]
    mat = _new_material(shading, colour, texture, roughness)
    if len(_MATERIALS) > 32:
        _MATERIALS.clear()
    _MATERIALS[key] = (texture, mat)
    return mat


def _new_material(shading: str, colour: tuple[float, ...], texture: np.ndarray | None, roughness: float) -> object:
    from stimulus_engine.render._pyrender import pyrender

    tex = None if texture is None else pyrender.Texture(source=np.ascontiguousarray(texture), source_channels="RGB")
    if shading == "pbr":
        return pyrender.MetallicRoughnessMaterial(baseColorFactor=colour if tex is None else (1.0, 1.0, 1.0, 1.0),
                                                  baseColorTexture=tex, metallicFactor=0.0, roughnessFactor=roughness)
    if shading == "phong":
        return pyrender.SpecularGlossinessMaterial(diffuseFactor=colour if tex is None else (1.0, 1.0, 1.0, 1.0),
                                                   diffuseTexture=tex, specularFactor=(0.22, 0.22, 0.22),
                                                   glossinessFactor=min(0.95, 1.17 - roughness))
    raise ValueError(f"unknown shading '{shading}' (expected one of: {', '.join(SHADINGS)})")


_SPLITS: dict[tuple, tuple[object, list]] = {}


def _split_parts(rig: FaceRig, textured_skin: bool) -> list:
    """Per part: (name, (vertex, uv) index pairs, triangles, textured); cached per rig topology."""
    key = (id(rig.faces), id(rig.face_part), textured_skin, tuple(sorted(rig.part_textures)))
    hit = _SPLITS.get(key)
    if hit is not None and hit[0][0] is rig.faces and hit[0][1] is rig.face_part:
        return hit[1]
    out = []
    for k, name in enumerate(rig.part_names):
        sel = rig.face_part == k
        if name == "hidden" or not sel.any():
            continue
        f = rig.faces[sel]
        textured = (name == "skin" and textured_skin) or (name in rig.part_textures and rig.face_uv is not None)
        second = rig.face_uv[sel].ravel() if textured else np.zeros(f.size, np.int64)
        uniq, inv = np.unique(np.stack([f.ravel(), second], axis=1), axis=0, return_inverse=True)
        out.append((name, uniq, inv.reshape(-1, 3), textured))
    if len(_SPLITS) > 16:
        _SPLITS.clear()
    _SPLITS[key] = ((rig.faces, rig.face_part), out)
    return out


def rig_render_parts(rig: FaceRig, vertices: np.ndarray, albedo: np.ndarray | None, *,
                     shading: str = "pbr") -> list:
    """Render parts (skin with texture, eyes, teeth, mouth, lashes) for ``vertices`` of ``rig``.

    Skin vertices are split where the UV layout has seams (normals are computed on the welded
    mesh first, so the shading stays smooth across seams). Parts named ``hidden`` are left out.

    Parameters
    ----------
    rig : FaceRig
    vertices : (N, 3) array
        The shape to draw (expression and stylisation applied).
    albedo : (H, W, 3) uint8 array or None
        Skin texture (None = plain skin colour).
    shading : {"pbr", "phong"}
    """
    from stimulus_engine.render import RenderPart

    v = np.asarray(vertices, np.float64)
    if albedo is not None and (rig.uv is None or rig.face_uv is None):
        raise ValueError(f"rig '{rig.name}' has no UVs but a texture was asked for")
    normals = trimesh.Trimesh(v, rig.faces, process=False).vertex_normals
    parts = []
    for name, uniq, tri, textured in _split_parts(rig, albedo is not None):
        mesh = trimesh.Trimesh(v[uniq[:, 0]], tri, vertex_normals=normals[uniq[:, 0]], process=False)
        if textured:
            mesh.visual = trimesh.visual.TextureVisuals(uv=rig.uv[uniq[:, 1]])
        tex = (albedo if name == "skin" else rig.part_textures[name]) if textured else None
        mat = _material(shading, _PART_COLOURS.get(name, (0.7, 0.7, 0.7, 1.0)), tex,
                        _PART_ROUGHNESS.get(name, 0.62))
        parts.append(RenderPart(mesh, material=mat, smooth=True, name=name))
    return parts


def albedo_hash(albedo: np.ndarray | None) -> str:
    """Short content hash of an albedo (for manifests and up-to-date checks)."""
    if albedo is None:
        return "none"
    return hashlib.sha256(np.ascontiguousarray(albedo).tobytes()).hexdigest()[:16]
