"""Prototype transforms: move a face along the difference between two prototypes (Rowland & Perrett
1995; Tiddeman, Burt & Perrett 2001), with separate weights for shape, colour and texture.

The classic use is feminising/masculinising a face with a female and a male composite (A = female,
B = male: positive weights masculinise), or ageing with young and old composites. What each weight does,
for an image ``I`` with template ``P`` and prototypes ``A``, ``B`` (images with templates ``PA``, ``PB``):

1. **Eye frame.** Both prototypes (images and templates) are moved by the similarity transform that puts
   their pupils on ``I``'s pupils (:func:`stimulus_engine.faces2d.align.align_face`), so the difference
   is measured in ``I``'s frame and at ``I``'s size; the prototypes may have any image size.
2. **Shape** (weight ``ws``): the new template is ``P' = P + ws (PB − PA)`` (aligned templates) and
   ``I`` is warped onto it (:func:`stimulus_engine.faces2d.warp.warp_to_points`).
3. **Colour** (weight ``wc``): both prototypes are warped onto ``P'`` (shape-normalised to the new
   face) and the difference of their *low-frequency* colour — each blurred with a heavy Gaussian,
   σ = ``colour_sigma`` × the eye distance (default 0.12, ≈ 8 px on a 600-px-wide face with 130 px
   between the pupils) — is added: ``I' += wc (blur(B) − blur(A))``. Skin tone, redness, the darker
   brows and lips and shading of one prototype relative to the other move; fine detail does not,
   so the blurry composites do not blur the face.
4. **Texture** (weight ``wt``): the detail finer than that blur, in a Laplacian pyramid of ``I'``
   (``levels`` bands, finest first, down to about the colour blur's scale). In each band, the local
   amplitude of the prototypes' luminance (smoothed ``|band|``, warped prototypes) gives a ratio
   ``amp(B) / amp(A)``; the band is multiplied by ``ratio ** wt`` (clipped to ×[1/3, 3]). This is
   Tiddeman et al.'s wavelet-amplitude idea: where B has more fine structure than A (stubble,
   rougher or older skin), the face gains some of it, scaled to its own detail; a smooth B smooths.
   It does not copy any texture from the prototypes, only rescales the face's own.
5. **Region.** By default colour and texture change only on the face (:func:`face_region`: cheeks,
   jaw, chin and forehead, soft edge); ``region="image"`` changes the whole image as Psychomorph does.

Weight 0 in all three returns the input (up to float rounding); negative weights move away from B
(``B → A``). :func:`caricature` in :mod:`stimulus_engine.faces2d.caricature` is a transform from an
average to the face itself.
"""

from __future__ import annotations

import cv2
import numpy as np

from stimulus_engine.faces2d.pyramid import band_amplitudes, collapse_pyramid, laplacian_pyramid

from appeal.errors import AppealInputError
from stimulus_engine.faces2d.warp import warp_to_points

__all__ = ["REGIONS", "face_region", "eye_distance", "align_prototype", "shape_difference", "low_frequency",
           "texture_levels", "transform"]


def _check_points(points: np.ndarray, other: np.ndarray, what: str) -> None:
    if np.shape(points) != np.shape(other):
        raise AppealInputError(f"{what}: template has {len(other)} points but the face's has {len(points)} "
                               "(transforms need one template type)")


def eye_distance(points: np.ndarray) -> float:
    """Distance between the pupils of a template (pixels)."""
    from stimulus_engine.faces2d.align import eye_points

    e = eye_points(points)
    return float(np.linalg.norm(e[1] - e[0]))


def align_prototype(image: np.ndarray, points: np.ndarray, target_points: np.ndarray,
                    size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """A prototype image and template moved (similarity) so its pupils sit on ``target_points``' pupils,
    in an image of ``size`` ``(w, h)`` (uncovered pixels repeat the nearest edge colour)."""
    from stimulus_engine.faces2d.align import align_matrix, eye_points

    m = align_matrix(eye_points(points), eye_points(target_points))
    img = cv2.warpAffine(np.asarray(image, np.float32), m, (int(size[0]), int(size[1])), flags=cv2.INTER_CUBIC,
                         borderMode=cv2.BORDER_REPLICATE)
    return np.clip(img, 0.0, 1.0), np.asarray(points, np.float64) @ m[:, :2].T + m[:, 2]


def shape_difference(points: np.ndarray, points_a: np.ndarray, points_b: np.ndarray) -> np.ndarray:
    """``PB − PA`` with both prototype templates first moved to the face's eye frame ``(n, 2)``."""
    from stimulus_engine.faces2d.align import align_matrix, eye_points

    out = []
    for q in (points_a, points_b):
        m = align_matrix(eye_points(q), eye_points(points))
        out.append(np.asarray(q, np.float64) @ m[:, :2].T + m[:, 2])
    return out[1] - out[0]


def low_frequency(image: np.ndarray, sigma: float) -> np.ndarray:
    """The image's colour blurred with a Gaussian of ``sigma`` pixels (edges reflected)."""
    return cv2.GaussianBlur(np.asarray(image, np.float32), (0, 0), float(sigma), borderType=cv2.BORDER_REFLECT)


def texture_levels(sigma: float) -> int:
    """Laplacian-pyramid bands finer than a Gaussian blur of ``sigma`` pixels (1–6)."""
    return int(np.clip(np.floor(np.log2(max(float(sigma), 1.0))) + 1, 1, 6))


def _retexture(image: np.ndarray, amp_a: list[np.ndarray], amp_b: list[np.ndarray], weight: float,
               max_gain: float = 3.0) -> np.ndarray:
    bands = laplacian_pyramid(image, len(amp_a))
    for k, (a, b) in enumerate(zip(amp_a, amp_b)):
        floor = max(1e-4, 0.05 * float(np.median(a) + np.median(b)))  # flat areas: no wild ratios
        ratio = (b + floor) / (a + floor)
        gain = np.clip(ratio ** weight, 1.0 / max_gain, max_gain).astype(np.float32)
        bands[k] = bands[k] * (gain[..., None] if bands[k].ndim == 3 else gain)
    return collapse_pyramid(bands)


REGIONS = ("face", "image")


def face_region(shape: tuple[int, int], points: np.ndarray, feather: float | None = None) -> np.ndarray:
    """Where colour and texture change with ``region="face"``: the face without hair, ears and neck,
    soft-edged (``(h, w)`` float32 in [0, 1]).

    The outline is the convex hull of the cheeks, jaw and chin (189-point FRL: 109–114, 125–133;
    dlib 68: 0–16) and the brows (FRL 71–82, dlib 17–26) lifted by 0.6 eye distances to cover the
    forehead (other templates: all points); the soft edge is ``feather`` pixels wide (default 0.3
    eye distances), centred on the outline.
    """
    from stimulus_engine.faces2d.align import eye_points
    from stimulus_engine.faces2d.mask import face_mask

    p = np.asarray(points, np.float64)
    e = eye_points(p)
    d = e[1] - e[0]
    up = np.array([d[1], -d[0]]) * 0.6  # perpendicular to the eye line, towards the top of the head
    if len(p) == 189:
        outline, brows = p[list(range(109, 115)) + list(range(125, 134))], p[71:83]
    elif len(p) == 68:
        outline, brows = p[:17], p[17:27]
    else:
        outline, brows = p, p[:0]
    q = np.vstack([outline, brows, brows + up])
    f = 0.3 * float(np.linalg.norm(d)) if feather is None else float(feather)
    return face_mask(shape, q, kind="hull", feather=f, subset=range(len(q)))


def transform(image: np.ndarray, points: np.ndarray, image_a: np.ndarray, points_a: np.ndarray,
              image_b: np.ndarray, points_b: np.ndarray, *, shape: float = 0.0, colour: float = 0.0,
              texture: float = 0.0, colour_sigma: float = 0.12, region: str = "face",
              levels: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Move a face by the shape, colour and texture difference between prototypes A and B.

    Parameters
    ----------
    image : (h, w, 3) float array
        The face, RGB in [0, 1].
    points : (n, 2) array
        Its template.
    image_a, points_a, image_b, points_b
        The prototypes (e.g. composites) and their templates (same ``n``; any image size).
    shape, colour, texture : float
        Weights (1 = the whole A→B difference; negative = towards A; see the module docstring).
    colour_sigma : float
        The colour blur as a fraction of the face's eye distance; the texture bands are the finer detail.
    region : {"face", "image"}
        Where colour and texture change: the face (cheeks, jaw, chin, forehead up to above the
        brows, soft edge: :func:`face_region`) or the whole image (as Psychomorph; hair, neck and
        background then take on the prototypes' differences there too, e.g. a light halo where one
        prototype's hair is the other's background). Shape always moves the whole image.
    levels : int, optional
        Texture bands (default: :func:`texture_levels` of the colour blur).

    Returns
    -------
    (image, points)
        The transformed float32 image (same size) and its template.

    Raises
    ------
    AppealInputError
        The templates' point counts differ.
    """
    if region not in REGIONS:
        raise ValueError(f"region must be one of {REGIONS} (got {region!r})")
    p = np.asarray(points, np.float64)
    _check_points(p, np.asarray(points_a), "prototype A")
    _check_points(p, np.asarray(points_b), "prototype B")
    img = np.asarray(image, np.float32)
    target = p + shape * shape_difference(p, points_a, points_b) if shape else p.copy()
    out = warp_to_points(img, p, target) if shape else img.copy()
    if colour or texture:
        h, w = img.shape[:2]
        a_img, a_pts = align_prototype(image_a, points_a, p, (w, h))
        b_img, b_pts = align_prototype(image_b, points_b, p, (w, h))
        a_w = warp_to_points(a_img, a_pts, target)
        b_w = warp_to_points(b_img, b_pts, target)
        sigma = max(1.0, colour_sigma * eye_distance(target))
        before = out
        if colour:
            out = out + colour * (low_frequency(b_w, sigma) - low_frequency(a_w, sigma))
        if texture:
            n = texture_levels(sigma) if levels is None else int(levels)
            out = _retexture(out, band_amplitudes(a_w, n), band_amplitudes(b_w, n), texture)
        if region == "face":
            m = face_region((h, w), target)[..., None]
            out = before + m * (out - before)
    return np.clip(out, 0.0, 1.0).astype(np.float32), target
