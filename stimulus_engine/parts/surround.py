"""A photograph's head and shoulders behind a character made from it (issue 49).

A character from one photograph (:mod:`stimulus_engine.characters.photo_character`) draws its face
as the fitted mesh; its hair, ears, neck, clothes and background come from the photograph itself,
as a :class:`Surround`: a plane behind the head, at the photograph's camera, showing the
photograph with the face filled in from around it
(:func:`stimulus_engine.characters.photo_texture.surround_image`). From the photograph's own
viewpoint the plane and the face together give back the photograph; the plane is drawn unlit (its
light is the photograph's), and its image is stylised with the skin's material at painted levels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stimulus_engine.parts.stored import part_arrays, part_from_arrays

__all__ = ["Surround", "surround_arrays", "surround_from_arrays", "surround_mesh", "surround_view"]


@dataclass(frozen=True, eq=False)
class Surround:
    """A photograph on a plane in the character's frame.

    Attributes
    ----------
    corners : (4, 3) float array
        The plane's corners (the photograph's top-left, top-right, bottom-right, bottom-left).
    image : (H, W, 3) uint8 array
        The photograph, its face filled in.
    """

    corners: np.ndarray
    image: np.ndarray


def surround_mesh(surround: Surround) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The plane as two triangles: vertices ``(4, 3)``, faces ``(2, 3)`` (facing the camera) and
    texture coordinates ``(4, 2)`` (OBJ convention, v up)."""
    uv = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]])
    faces = np.array([[0, 3, 2], [0, 2, 1]])
    return np.asarray(surround.corners, np.float64), faces, uv


def surround_view(surround: Surround) -> tuple[np.ndarray, np.ndarray]:
    """The photograph's viewing direction (unit, from the face toward its camera) and up, in the
    character's frame: the plane's normal and its left edge, bottom to top."""
    c = np.asarray(surround.corners, np.float64)
    right, up = c[1] - c[0], c[0] - c[3]
    view = np.cross(right, up)
    return view / np.linalg.norm(view), up / np.linalg.norm(up)


def surround_arrays(surround: Surround | None, prefix: str = "surround_") -> dict[str, np.ndarray]:
    """``surround`` as named arrays (for an ``.npz``; empty for none)."""
    return part_arrays(surround, prefix)


def surround_from_arrays(arrays, prefix: str = "surround_") -> Surround | None:
    """The :class:`Surround` stored by :func:`surround_arrays`, or None."""
    return part_from_arrays(Surround, arrays, prefix)
