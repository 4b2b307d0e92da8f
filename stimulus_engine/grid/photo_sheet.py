"""A rendered grid's realistic level beside real photographs, framed alike (issue 14).

The studies measure how realism changes perception, so a grid's most realistic level has to read
as a photograph. :func:`realism_sheet` puts, per character, that level's neutral image beside a
photograph warped so that its eye centres and philtrum land on the rendered ones (both found by
dlib: the same face size, the same eye row) on the grid's background, for a person to judge side by
side (``appeal stimuli photo-sheet``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from PIL import Image

from appeal.errors import AppealInputError
from stimulus_engine.grid.photo_framing import photo_like_render

__all__ = ["realistic_images", "photo_like_render", "realism_sheet"]


#: Manifest columns the sheet reads.
MANIFEST_COLUMNS = ("file", "character", "shape", "shape_label", "stylisation", "material", "material_style", "expression")


def _read_image(path: Path, where: str) -> np.ndarray:
    from PIL import UnidentifiedImageError

    if not path.is_file():
        raise AppealInputError(f"{where}: {path}: image not found")
    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"))
    except (UnidentifiedImageError, OSError) as exc:
        raise AppealInputError(f"{where}: {path}: not an image ({exc})") from None


def realistic_images(manifest: pd.DataFrame) -> pd.DataFrame:
    """One row per character: its most realistic rendered image (neutral when there is one,
    the original material, the first lighting and shading)."""
    rendered = manifest[manifest["shape"].astype(str) != "photograph"].copy()
    if rendered.empty:
        raise AppealInputError("manifest: no rendered images (expected a grid's manifest.csv)")
    rows = []
    for _, sub in rendered.groupby("character", sort=False):
        sub = sub[sub["stylisation"] == sub["stylisation"].max()]
        for col, want in (("expression", "neutral"), ("material_style", "original")):
            if (sub[col] == want).any():
                sub = sub[sub[col] == want]
        rows.append(sub.iloc[0])
    return pd.DataFrame(rows)


def realism_sheet(manifest_path: str | Path, photos: Sequence[str | Path], *, thumb_width: int = 400) -> np.ndarray:
    """Per character (rows): the realistic level beside a photograph (photos cycle over characters).

    Parameters
    ----------
    manifest_path : path-like
        A rendered grid's ``manifest.csv`` (image paths are relative to its folder).
    photos : sequence of path-like
        Frontal photographs of real people (e.g. ``neutral_front/`` of the ``london-frl`` dataset: ``appeal data path london-frl``).
    thumb_width : int
        Width of each cell.
    """
    from stimulus_engine.render.contact_sheet import contact_sheet

    manifest_path = Path(manifest_path)
    if not manifest_path.is_file():
        raise AppealInputError(f"{manifest_path}: manifest not found (expected DIR/manifest.csv of a rendered grid)")
    if not photos:
        raise AppealInputError("--photo: expected at least one photograph")
    try:
        manifest = pd.read_csv(manifest_path)
    except (UnicodeDecodeError, ValueError, pd.errors.ParserError) as exc:
        raise AppealInputError(f"{manifest_path}: not a grid manifest ({str(exc).splitlines()[0]}; expected the "
                               "manifest.csv 'appeal stimuli grid' writes)") from None
    missing = [c for c in MANIFEST_COLUMNS if c not in manifest.columns]
    if missing:
        raise AppealInputError(f"{manifest_path}: {', '.join(missing)}: column(s) missing (expected the manifest.csv "
                               "'appeal stimuli grid' writes)")
    from stimulus_engine.grid.animation import apex_view

    best = realistic_images(apex_view(manifest))  # an animated grid's clips by their apex frames
    cells, rows = [], []
    for k, (_, r) in enumerate(best.iterrows()):
        render = _read_image(manifest_path.parent / r["file"], f"{manifest_path}: file")
        photo_path = Path(photos[k % len(photos)])
        photo = _read_image(photo_path, "--photo")
        background = tuple(int(v) for v in render[0, 0])
        cells += [render, photo_like_render(photo, render, background, str(photo_path))]
        rows.append(f"{r['character']} ({r['shape_label']}, {r['material']})")
    return contact_sheet(cells, 2, thumb_width=thumb_width, row_labels=rows,
                         col_labels=["rendered: most realistic level", "photograph, eyes aligned"],
                         title=f"{manifest_path.parent.name}: realistic level beside a photograph")
