"""Face composites (averages) the way WebMorph and Psychomorph make them.

The composite's shape is the mean of the templates; every image is warped so that its template
lands on that mean shape (:func:`stimulus_engine.faces2d.warp.warp_to_points`), and the warped
images' colours are averaged pixel by pixel. Because every face's eyes, nostrils and lips sit on
the same positions before averaging, the composite keeps single, sharp features (checked by
:func:`composite_ghosting`); a plain pixel average of the same images (:func:`pixel_average`)
doubles and smears them.

Colours are averaged in **sRGB** values by default, as WebMorph and Psychomorph do, so composites
match theirs; ``colour_space="linear"`` averages linear light instead (physically the mean of the
light, slightly brighter in mixed dark/light regions such as hair against background).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from stimulus_engine.faces2d.pyramid import band_amplitudes, collapse_pyramid, laplacian_pyramid

from stimulus_engine.faces2d.warp import warp_to_points

__all__ = ["COLOUR_SPACES", "srgb_to_linear", "linear_to_srgb", "average_faces", "pixel_average",
           "composite_ghosting", "faceframe"]

COLOUR_SPACES = ("srgb", "linear")


def srgb_to_linear(image: np.ndarray) -> np.ndarray:
    """sRGB values in [0, 1] → linear light (IEC 61966-2-1)."""
    c = np.clip(np.asarray(image, np.float32), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(image: np.ndarray) -> np.ndarray:
    """Linear light in [0, 1] → sRGB values."""
    c = np.clip(np.asarray(image, np.float32), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055).astype(np.float32)


def _check_space(colour_space: str) -> None:
    if colour_space not in COLOUR_SPACES:
        raise ValueError(f"colour_space must be one of {COLOUR_SPACES} (got {colour_space!r})")


def blend(images: Sequence[np.ndarray], weights: Sequence[float], colour_space: str = "srgb") -> np.ndarray:
    """Weighted sum of same-size float images in ``colour_space`` (weights should sum to 1)."""
    _check_space(colour_space)
    acc = None
    for img, w in zip(images, weights):
        x = srgb_to_linear(img) if colour_space == "linear" else np.asarray(img, np.float32)
        acc = w * x if acc is None else acc + w * x
    assert acc is not None
    return linear_to_srgb(acc) if colour_space == "linear" else np.clip(acc, 0.0, 1.0).astype(np.float32)


def texture_levels(size: tuple[int, int]) -> int:
    """Pyramid levels the texture step adjusts: down to bands about 1/32 of the shorter side."""
    return int(max(1, min(6, np.floor(np.log2(max(8, min(size)) / 32)) + 1)))


def restore_texture(composite: np.ndarray, target: list[np.ndarray], *, max_gain: float = 4.0) -> np.ndarray:
    """Scale each band of ``composite`` so its local contrast matches ``target`` (the inputs' mean
    :func:`_amplitudes`); gains are kept within [1, ``max_gain``] (averaging only lowers contrast)."""
    levels = len(target)
    bands = laplacian_pyramid(composite, levels)
    have = band_amplitudes(composite, levels)
    for k in range(levels):
        gain = np.clip(target[k] / np.maximum(have[k], 1e-4), 1.0, max_gain)
        bands[k] = bands[k] * gain[..., None]
    return np.clip(collapse_pyramid(bands), 0.0, 1.0).astype(np.float32)


def average_faces(images: Sequence[np.ndarray], points: Sequence[np.ndarray], *, colour_space: str = "srgb",
                  weights: Sequence[float] | None = None, texture: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The composite of ``images`` (shape = mean template, colour = mean of the shape-normalised images).

    Parameters
    ----------
    images : sequence of (h, w, 3) float arrays
        Same size (align them first); RGB in [0, 1].
    points : sequence of (n, 2) arrays
        Each image's template points (same n).
    colour_space : {"srgb", "linear"}
        Where colours are averaged (see the module docstring).
    weights : sequence of float, optional
        Weights of the faces in both shape and colour (normalised to sum 1); default equal.
    texture : bool
        Restore the inputs' mean local contrast in every band of a Laplacian pyramid (Tiddeman,
        Burt & Perrett 2001, as WebMorph's *texture* option): averaging cancels skin and hair
        detail that does not line up; this puts back its amount, not any one face's detail.

    Returns
    -------
    (image, points)
        The composite ``(h, w, 3)`` float32 and its template points ``(n, 2)`` (the weighted mean).
    """
    _check_space(colour_space)
    n = len(images)
    if n == 0 or n != len(points):
        raise ValueError(f"need the same number (>= 1) of images and templates (got {n} and {len(points)})")
    w = np.full(n, 1.0 / n) if weights is None else np.asarray(weights, np.float64) / float(np.sum(weights))
    pts = np.asarray([np.asarray(p, np.float64) for p in points])
    mean = np.tensordot(w, pts, axes=1)
    acc, amp = None, None
    levels = texture_levels(np.shape(images[0])[:2])
    for img, p, wi in zip(images, pts, w):
        warped = warp_to_points(img, p, mean)
        x = srgb_to_linear(warped) if colour_space == "linear" else warped
        acc = wi * x if acc is None else acc + wi * x
        if texture:
            a = band_amplitudes(warped, levels)
            amp = [wi * b for b in a] if amp is None else [s + wi * b for s, b in zip(amp, a)]
    assert acc is not None
    out = linear_to_srgb(acc) if colour_space == "linear" else np.clip(acc, 0.0, 1.0).astype(np.float32)
    if texture and amp is not None:
        out = restore_texture(out, amp)
    return out, mean


def pixel_average(images: Sequence[np.ndarray]) -> np.ndarray:
    """The plain pixel average (no warping): the ghosted baseline a composite is compared with."""
    return np.mean([np.asarray(i, np.float32) for i in images], axis=0).astype(np.float32)


def faceframe(points: np.ndarray) -> np.ndarray:
    """Eyes + philtrum ``(3, 2)`` of a template (189-point FRL: pupils and the mean of 55, 90; 68 dlib
    points: eye centres and the midpoint of 33, 51; other templates: pupils 0, 1 and the point
    below their midpoint at one eye distance)."""
    from stimulus_engine.faces2d.align import eye_points

    p = np.asarray(points, np.float64)
    eyes = eye_points(p)
    if len(p) == 189:
        phil = p[[55, 90]].mean(0)
    elif len(p) == 68:
        phil = p[[33, 51]].mean(0)
    else:
        d = eyes[1] - eyes[0]
        phil = eyes.mean(0) + np.array([-d[1], d[0]])
    return np.vstack([eyes, phil])


def composite_ghosting(composite: np.ndarray, composite_points: np.ndarray, images: Sequence[np.ndarray],
                       points: Sequence[np.ndarray]) -> float:
    """:func:`stimulus_engine.morphpca.ghosting.ghosting_index` of a composite against its input faces
    (each measured around its own feature landmarks): 0 = features as crisp as the inputs',
    ~0.5 = doubled edges, 1 = blank."""
    from stimulus_engine.morphpca.ghosting import ghosting_index

    return ghosting_index(composite, composite_points, images, points, faceframe(composite_points))
