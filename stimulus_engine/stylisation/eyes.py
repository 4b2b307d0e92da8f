"""Stylised eyes: a larger iris and painted, simplified eyes along the stylisation scale.

An animated-film character's eyes are not a photograph's: the iris is larger against the eye's
opening, its colour is painted flat with a dark rim, and the white is plain white (thesis ch. 5,
Exp. 2's stylised levels after *Pocoyo* and *Tangled*; Fig. 7.10's neoteny: larger eyes). The
shape operator (:mod:`stimulus_engine.stylisation.shape`) already enlarges the eyes; here the
eyeball's texture follows, in the texture of whichever layout the eye has (the rigs' equal-area
layout about the gaze axis, :func:`stimulus_engine.parts.eyes.eyeball_uv`, or the two-eyed
photograph of a scan's eyeball asset):

* :func:`iris_circles` finds each iris in an eye texture: the pupils painted in it
  (:func:`~stimulus_engine.parts.eyes.painted_pupils`), about each the pupil's edge (where the
  black ends) and the limbus, the sharpest rise of brightness from 1.8 to 5 pupil radii out (the
  iris is darker than the ring and the white around it, whatever its colour: a scan's painted
  iris colour can be a dark, nearly grey brown);
* :func:`bold_lash_texture` gives the lash cards a bold lid line by ``paint``: a solid dark band
  along their roots (:data:`LID_LINE` of the card's height, soft-edged), the lid line an animated
  film draws where a photograph shows lashes;
* :func:`stylised_eye_texture` enlarges each iris ``iris_scale`` times about its pupil (the
  grey ring and the white beyond it squeezed into one iris radius, the rest untouched) and
  paints it by ``paint`` (0 photographic .. 1 painted): the iris blended into its mean colour
  with a dark rim, the white into a plain white.

The grid asks for it per image (:mod:`stimulus_engine.grid.prepare`: the iris scale grows with
the shape level, :data:`IRIS_SCALE_AT_CARTOON`, the paint with a ``painted`` material's amount).
"""

from __future__ import annotations

import numpy as np

__all__ = ["IRIS_SCALE_AT_CARTOON", "LID_LINE", "PAINTED_WHITE", "bold_lash_texture", "iris_circles",
           "stylised_eye_texture"]

#: The iris's size at the cartoon end of the shape scale, against the realistic one (a cartoon
#: iris fills most of the opening: about 0.6 of the eye's width where a photograph's is 0.45).
IRIS_SCALE_AT_CARTOON = 1.3
#: The painted white of a stylised eye (sRGB grey; the photographic sclera is lit to 200 with
#: veins and shading, :data:`stimulus_engine.parts.eyes.SCLERA_LEVEL`).
PAINTED_WHITE = 225.0
#: The least mean grey of a painted iris (sRGB): a dark iris is lifted to it, hue kept, so that an
#: enlarged iris reads as its colour and not as a black disc (james's painted iris averages 50).
PAINTED_IRIS_LEVEL = 85.0
#: The rim of a painted iris: its width (a share of the iris's radius) and how dark (a factor).
RIM_WIDTH, RIM_DARK = 0.14, 0.45
#: The bold lid line of painted lashes: the share of a lash card's height (from the root) it
#: covers, and its colour (sRGB).
LID_LINE, LID_LINE_COLOUR = 0.22, (22, 15, 12)
#: Grey level (0-255) below which a texel is the pupil's black.
PUPIL_BLACK = 25.0


def iris_circles(texture: np.ndarray) -> list[tuple[float, float, float, float]]:
    """Every iris in an eye texture: ``(x, y, radius, pupil_radius)`` in pixels (x to the right,
    y down), found about the painted pupils (module docstring).

    Examples
    --------
    >>> from stimulus_engine.parts.eyes import IRIS_ANGLE, photographic_eye_texture
    >>> (x, y, r, p), = iris_circles(photographic_eye_texture(256))
    >>> round(x), round(y), bool(abs(r / (128 * np.sin(np.radians(IRIS_ANGLE) / 2)) - 1) < 0.1)  # the rig's iris
    (128, 128, True)
    """
    from stimulus_engine.parts.eyes import painted_pupils

    h, w = texture.shape[:2]
    grey = np.asarray(texture, np.float64)[..., :3].mean(axis=-1)
    yy, xx = np.mgrid[0:h, 0:w]
    out: list[tuple[float, float, float, float]] = []
    for u, v in painted_pupils(texture):
        x, y = u * w - 0.5, (1.0 - v) * h - 0.5
        if any(np.hypot(x - a, y - b) < r for a, b, r, _ in out):
            continue  # the same eye again (the dark back of an equal-area layout is centred on its pupil)
        ring = np.rint(np.hypot(xx - x, yy - y)).astype(int)
        near = ring < min(h, w) // 3
        g = np.bincount(ring[near], grey[near]) / np.maximum(np.bincount(ring[near]), 1)
        pupil = int(np.argmax(g > PUPIL_BLACK))
        lo, hi = int(np.ceil(1.8 * pupil)), min(int(5 * pupil), len(g) - 3)
        if pupil == 0 or hi <= lo:
            continue
        rise = g[lo + 2:hi + 3] - g[lo - 2:hi - 1]
        out.append((float(x), float(y), float(lo + int(np.argmax(rise))), float(pupil)))
    return out


def _enlarged(texture: np.ndarray, circles: list, scale: float) -> np.ndarray:
    """Each iris ``scale`` times larger about its centre; the next iris radius squeezed in."""
    import cv2

    h, w = texture.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    map_x, map_y = xx.copy(), yy.copy()
    for x, y, r, _ in circles:
        dx, dy = xx - x, yy - y
        d = np.hypot(dx, dy)
        outer = r * scale + r  # the enlarged iris, then its ring and white, then untouched
        src = np.where(d < r * scale, d / scale, r + (d - r * scale) * (outer - r) / r)
        inside = d < outer
        k = np.where(d > 0, src / np.maximum(d, 1e-6), 1.0 / scale)
        map_x = np.where(inside, x + dx * k, map_x)
        map_y = np.where(inside, y + dy * k, map_y)
    return cv2.remap(np.ascontiguousarray(texture), map_x.astype(np.float32), map_y.astype(np.float32),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def _painted(texture: np.ndarray, circles: list, paint: float) -> np.ndarray:
    """Irises blended into their mean colour with a dark rim, the white about them into plain
    white, by ``paint``."""
    from stimulus_engine.geometry.ramps import smoothstep

    out = np.asarray(texture, np.float64).copy()
    h, w = out.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w]
    for x, y, r, p in circles:
        d = np.hypot(xx - x, yy - y)
        iris = (d > p) & (d < r)
        mean = out[iris].mean(axis=0)
        mean *= max(PAINTED_IRIS_LEVEL / max(float(mean.mean()), 1.0), 1.0)  # a dark iris lifted: its colour shows
        flat = mean * (1.0 - (1.0 - RIM_DARK) * smoothstep(d / r, 1.0 - RIM_WIDTH, 1.0))[..., None]
        white = np.full(3, PAINTED_WHITE)
        target = np.where((d < r)[..., None], flat, white)
        weight = paint * np.where(d < p, 0.0, 1.0 - smoothstep(d / r, 1.6, 2.0))  # the pupil, and past the white
        out += weight[..., None] * (target - out)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def stylised_eye_texture(texture: np.ndarray, iris_scale: float = 1.0, paint: float = 0.0) -> np.ndarray:
    """An eye texture stylised (module docstring): each iris ``iris_scale`` times larger and the
    eye painted by ``paint`` (0..1); the texture itself when neither asks for a change.

    Parameters
    ----------
    texture : (H, W, 3) uint8 array
        An eyeball texture with painted pupils (either of the layouts of the module docstring).
    iris_scale : float
        At least 1.
    paint : float
        0 (photographic) .. 1 (painted).

    Returns
    -------
    (H, W, 3) uint8 array
    """
    if iris_scale < 1.0 or not 0.0 <= paint <= 1.0:
        raise ValueError(f"stylised eyes: iris_scale must be at least 1 and paint within 0..1 (got {iris_scale}, {paint})")
    if iris_scale == 1.0 and paint == 0.0:
        return texture
    circles = iris_circles(texture)
    out = _enlarged(texture, circles, iris_scale) if iris_scale != 1.0 else np.asarray(texture)
    scaled = [(x, y, r * iris_scale, p * iris_scale) for x, y, r, p in circles]
    return _painted(out, scaled, paint) if paint > 0 else out


def bold_lash_texture(texture: np.ndarray, paint: float) -> np.ndarray:
    """A lash card texture (RGBA, the roots along the bottom row: :func:`stimulus_engine.parts.eyelashes.lash_texture`)
    with a solid dark band along the roots, :data:`LID_LINE` of its height, as opaque as
    ``paint`` (0..1) makes it; the texture itself at 0."""
    from stimulus_engine.geometry.ramps import smoothstep

    if not 0.0 <= paint <= 1.0:
        raise ValueError(f"bold lashes: paint must be within 0..1 (got {paint})")
    if paint == 0.0:
        return texture
    out = np.asarray(texture, np.float64).copy()
    h = out.shape[0]
    v = 1.0 - (np.arange(h) + 0.5) / h  # 0 at the roots (the bottom row)
    band = paint * (1.0 - smoothstep(v, 0.6 * LID_LINE, LID_LINE))[:, None]
    out[..., :3] += band[..., None] * (np.asarray(LID_LINE_COLOUR, np.float64) - out[..., :3])
    out[..., 3] = np.maximum(out[..., 3], 255.0 * band)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
