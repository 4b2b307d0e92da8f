"""A soft oval vignette: the picture fades into the background outside an oval around the face.

The thesis's ERP study showed the face alone, filling the frame; a soft-edged oval keeps every
stimulus's outline the same (no shoulders, garment or hair ends that differ between characters
and stylisation levels) without a hard cut-out edge. :func:`face_oval` places the oval from the
framing (eye row and face length as fractions of the image height), :func:`oval_vignette`
applies it (a pure function on the image).
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.geometry.ramps import smoothstep

__all__ = ["face_oval", "oval_vignette"]

#: The oval around a framed face, in face lengths (forehead to chin): its centre below the eye
#: line, its half-height and half-width, and the width of its soft edge (a fraction of the radius).
OVAL_BELOW_EYES, OVAL_HALF_HEIGHT, OVAL_HALF_WIDTH, OVAL_FEATHER = 0.08, 0.72, 0.56, 0.22


def face_oval(width: int, height: int, eye_row: float, face_fraction: float) -> tuple[float, float, float, float, float]:
    """The oval (centre x, centre y, half-width, half-height in pixels, feather) around a face
    framed with its eyes ``eye_row`` of the height from the top and its length ``face_fraction``
    of the height (:class:`stimulus_engine.grid.schema.RenderSettings`)."""
    face = face_fraction * height
    return (width / 2, eye_row * height + OVAL_BELOW_EYES * face, OVAL_HALF_WIDTH * face, OVAL_HALF_HEIGHT * face,
            OVAL_FEATHER)


def oval_vignette(image: np.ndarray, oval: tuple[float, float, float, float, float],
                  background: tuple[float, float, float]) -> np.ndarray:
    """``image`` (H, W, 3 uint8) blended into ``background`` (0..1 RGB, the renderer's clear
    colour: 0.5 is grey 128) outside ``oval`` (see :func:`face_oval`): unchanged inside
    ``1 - feather`` of the radius, the background from the radius outwards, a smoothstep between."""
    cx, cy, rx, ry, feather = oval
    h, w = image.shape[:2]
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    r = np.hypot((x + 0.5 - cx) / rx, (y + 0.5 - cy) / ry)
    keep = 1 - smoothstep((r - (1 - feather)) / feather)
    bg = np.asarray(background, np.float64) * 255
    out = image.astype(np.float64) * keep[..., None] + bg * (1 - keep[..., None])
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
