"""Image files a grid reads (textures, normal and specular maps), checked before any rendering."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from appeal.errors import AppealInputError

__all__ = ["load_map", "load_texture"]


def load_texture(path: Path) -> np.ndarray:
    """An albedo image as (H, W, 3) uint8; an unreadable file is a one-line error."""
    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"))
    except OSError as exc:
        raise AppealInputError(f"{path}: cannot read the texture image ({exc})".splitlines()[0]) from None


def load_map(path: Path, kind: str, size: tuple[int, int] | None, where: str) -> np.ndarray:
    """A normal or specular map file, checked (channels, size, tangent space) before any rendering.

    Parameters
    ----------
    path : Path
    kind : {"normal", "specular"}
    size : (height, width), optional
        The albedo's size the map must have.
    where : str
        Prefix of error messages (e.g. ``grid.yaml: materials.m.normal_map``).
    """
    from stimulus_engine.characters.skin_maps import check_map

    try:
        with Image.open(path) as im:
            arr = np.asarray(im if im.mode in ("L", "RGB", "RGBA", "LA", "I;16") else im.convert("RGB"))
    except OSError as exc:
        raise AppealInputError(f"{where}: {path}: cannot read the image ({exc})".splitlines()[0]) from None
    if arr.ndim == 3 and arr.shape[2] == 2:  # LA
        arr = arr[..., 0]
    try:
        return check_map(arr, kind, size)
    except ValueError as exc:
        raise AppealInputError(f"{where}: {path.name}: {exc}") from None
