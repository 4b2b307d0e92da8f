"""Region masks for a scan's photographic texture: skin, lips, hair, and the rest.

The material styles paint regions separately where masks exist (``flat``: one colour per region,
blurs within a region; :func:`stimulus_engine.stylisation.materials.stylise_albedo`). A rig's painted albedo
comes with its masks; a scan's photograph does not, and one mean colour over skin, hair and
shirt makes its flat level a brown statue. Here the masks are found in the texture itself:

* **skin**: the colour statistics of the texels under the cheeks and nose (the triangles inside
  the quadrilateral between the outer eye corners and the mouth corners, iBUG 36, 45, 54, 48,
  seen from the front) — a texel is skin when its CIELAB chroma (a*, b*) is within 3 robust
  deviations of their median and it is no more than 25 lightness units darker;
* **lips**: the triangles inside the outer lip contour (iBUG 48–59), painted in UV space;
* **hair**: texels not skin and darker than it (hair, brows, beard);
* the rest (clothes) is ``other``; texels no triangle shows (the photograph's background) are
  ``unused``, a region of their own so that they colour no region's mean.

Skin is the regions' remainder, as for the painted rigs. The masks are softened by a small blur.
"""

from __future__ import annotations

import numpy as np

__all__ = ["scan_masks", "skin_texels"]


def _lab(rgb: np.ndarray) -> np.ndarray:
    from skimage.color import rgb2lab

    return rgb2lab(rgb.astype(np.float64) / 255.0)


def _triangle_mask(tri_uv: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The texels covered by the UV triangles ``tri_uv`` (n, 3, 2)."""
    from PIL import Image, ImageDraw

    h, w = shape
    img = Image.new("L", (w, h), 0)
    draw = ImageDraw.Draw(img)
    for t in tri_uv:
        draw.polygon([(u * (w - 1), (1 - v) * (h - 1)) for u, v in t], fill=255)
    return np.asarray(img) > 127


def _front_inside(vertices: np.ndarray, faces: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Triangles whose centre, seen along +z, is inside ``polygon`` and faces the viewer."""
    from stimulus_engine.geometry.polyline2d import inside_polygon

    c = vertices[faces].mean(axis=1)
    n = np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]])
    return inside_polygon(c[:, :2], polygon[:, :2]) & (n[:, 2] > 0)


def scan_masks(texture: np.ndarray, vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray, face_uv: np.ndarray,
               ibug: np.ndarray, *, size: int = 512) -> dict[str, np.ndarray]:
    """Soft region masks (``lips``, ``hair``, ``other``, ``unused``) of a scan's texture.

    Parameters
    ----------
    texture : (H, W, 3) uint8 array
        The scan's albedo.
    vertices, faces, uv, face_uv
        The scan's surface and UV layout (``vertices`` in the same frame as ``ibug``).
    ibug : (68, 3) array
        The 68 iBUG points on the scan's surface.
    size : int
        The masks are computed at most this large and returned at the texture's size.

    Returns
    -------
    dict of str to (H, W) float arrays in [0, 1] (empty when too little skin is seen)
    """
    from PIL import Image
    from scipy.ndimage import gaussian_filter

    h, w = texture.shape[:2]
    scale = min(1.0, size / max(h, w))
    sh, sw = max(1, round(h * scale)), max(1, round(w * scale))
    small = np.asarray(Image.fromarray(texture).resize((sw, sh), Image.BILINEAR)) if scale < 1 else texture
    lab = _lab(small)
    face = _triangle_mask(uv[face_uv[_front_inside(vertices, faces, ibug[[36, 45, 54, 48]])]], (sh, sw))
    lips = _triangle_mask(uv[face_uv[_front_inside(vertices, faces, ibug[48:60])]], (sh, sw))
    sample = lab[face & ~lips]
    if len(sample) < 50:  # too little skin seen to model it: no masks rather than wrong ones
        return {}
    centre = np.median(sample, axis=0)
    spread = 1.4826 * np.median(np.abs(sample[:, 1:] - centre[1:]), axis=0) + 1.0
    chroma = np.sqrt((((lab[..., 1:] - centre[1:]) / spread) ** 2).sum(axis=-1))
    skin = (chroma < 3.0) & (lab[..., 0] > centre[0] - 25)
    hair = ~skin & (lab[..., 0] < centre[0] - 10)
    other = ~skin & ~hair
    # texels no triangle shows (the photograph's background) are a region of their own, so they
    # colour no region's mean; a margin of used texels keeps the charts' edges (filtered into
    # the image) in their own regions
    from scipy.ndimage import binary_dilation

    unused = ~binary_dilation(_triangle_mask(uv[face_uv], (sh, sw)), iterations=4)
    soft = {name: gaussian_filter(m.astype(np.float64), 1.0) for name, m in
            (("lips", lips & ~unused), ("hair", hair & ~lips & ~unused),
                                                                   ("other", other & ~lips & ~unused), ("unused", unused))}
    if scale < 1:
        soft = {k: np.asarray(Image.fromarray((255 * v).astype(np.uint8)).resize((w, h), Image.BILINEAR),
                              np.float32) / 255.0 for k, v in soft.items()}
    return soft


def skin_texels(masks: dict[str, np.ndarray], shape: tuple[int, ...]) -> np.ndarray:
    """(H, W) float: how much each texel of an albedo of ``shape`` is skin, from its region masks
    (a scan's, :func:`scan_masks`, or a painted rig's): what no other region claims, each mask
    clipped to 0..1 (masks of another size, and a ``skin`` mask, are not counted)."""
    other = np.zeros(shape[:2])
    for name, m in masks.items():
        if name != "skin" and np.shape(m)[:2] == other.shape:
            other += np.clip(np.asarray(m, np.float64), 0.0, 1.0)
    return np.clip(1.0 - other, 0.0, 1.0)
