"""Contact sheets of a rendered grid: its images side by side, one sheet per pair of factors; an
animated grid's clips as filmstrips (:func:`write_filmstrips`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from PIL import Image

from stimulus_engine.grid.schema import GridFile

__all__ = ["FILMSTRIP_FRAMES", "filmstrip_frames", "sheet_layout", "write_filmstrips", "write_sheets"]


def sheet_layout(cells: pd.DataFrame, rows: list[str], col: str) -> tuple[list[int | None], int, dict]:
    """Arrange the manifest rows ``cells`` (one per image) on a contact sheet.

    Rows are the distinct values of the columns ``rows``, columns those of ``col``. When every
    row × column combination has an image this is a table (row and column labels); when the grid
    does not have them all (e.g. materials paired with shapes) the images are laid out as a list
    with a caption each, so that no cell stands for an image the grid does not have.

    Returns
    -------
    order : list of int or None
        Index labels of ``cells`` in row-major order (None only pads the last row of a list).
    ncols : int
    labels : dict
        ``row_labels`` and ``col_labels`` (table) or ``labels`` (list), for :func:`contact_sheet`.
    """
    row_keys = list(dict.fromkeys(zip(*(cells[r] for r in rows))))
    cols = list(dict.fromkeys(cells[col]))
    where = {(*key, c): idx for idx, key, c in zip(cells.index, zip(*(cells[r] for r in rows)), cells[col])}
    if len(where) == len(row_keys) * len(cols):
        order: list[int | None] = [where[(*key, c)] for key in row_keys for c in cols]
        return order, len(cols), {"row_labels": [" ".join(map(str, k)) for k in row_keys],
                                  "col_labels": [str(c) for c in cols]}
    order = list(where.values())
    captions = [" ".join(map(str, k)) for k in where]
    ncols = min(len(order), max(len(cols), 1))
    return order, ncols, {"labels": captions}


def write_sheets(out: Path, manifest: pd.DataFrame, grid: GridFile) -> list[Path]:
    """Write the grid's contact sheets (see :mod:`stimulus_engine.grid`) from its manifest; returns their paths."""
    from stimulus_engine.render import contact_sheet, save_png

    planned = manifest[manifest["shape"] != "photograph"]
    ok = planned["status"].isin(["rendered", "up to date"])
    if not ok.any():
        return []
    first = planned[ok].iloc[0]
    paired = grid.pair_materials_with_shapes
    paths = []

    def sheet(sub: pd.DataFrame, rows: list[str], col: str, name: str, title: str) -> None:
        order, ncols, labels = sheet_layout(sub, rows, col)
        imgs = [None if i is None or not ok[i] else np.asarray(Image.open(out / sub.at[i, "file"]).convert("RGB"))
                for i in order]
        if all(im is None for im in imgs):
            return
        ident = [np.nan if i is None or "identity_to_realistic" not in sub else sub.at[i, "identity_to_realistic"]
                 for i in order]
        if any(pd.notna(d) for d in ident):  # each measured level's identity distance (dlib)
            said = [f"id {d:.2f}" if pd.notna(d) else "" for d in ident]
            labels = {**labels, "labels": [f"{c} · {t}" if c and t else c or t
                                           for c, t in zip(labels.get("labels", [""] * len(order)), said)]}
            title += "; id: dlib distance to realistic (same person <= 0.6)"
        arr = contact_sheet(imgs, ncols, thumb_width=220, title=title, **labels)
        paths.append(save_png(arr, out / name))

    def where(**eq: str) -> pd.DataFrame:
        sel = planned
        for k, v in eq.items():
            if not (paired and k == "material"):  # paired: each shape level has its own material
                sel = sel[sel[k] == v]
        return sel.copy()

    shape_rows = ["character", "shape_label"]
    sel = where(expression=first.expression, lighting=first.lighting, shading=first.shading)
    if paired:
        sel["shape_material"] = sel["shape_label"] + " / " + sel["material"]
        sheet(sel, ["character"], "shape_material", "contact_sheet.png",
              f"{grid.name}: character (rows) x shape / material pairs (columns), {first.emotion}, {first.lighting}, "
              f"{first.shading}")
    else:
        sheet(sel, shape_rows, "material", "contact_sheet.png",
              f"{grid.name}: shape (rows) x material (columns), {first.emotion}, {first.lighting}, {first.shading}")
    sel = where(material=first.material, lighting=first.lighting, shading=first.shading)
    sheet(sel, shape_rows, "emotion", "contact_sheet_expressions.png",
          f"{grid.name}: shape (rows) x expression (columns), {'paired material' if paired else first.material}, "
          f"{first.lighting}, {first.shading}")
    if len(grid.lighting) > 1 or len(grid.shading) > 1:
        sel = where(material=first.material, expression=first.expression)
        sel["light_shading"] = sel["lighting"] + "/" + sel["shading"]
        sheet(sel, shape_rows, "light_shading", "contact_sheet_lighting.png",
              f"{grid.name}: shape (rows) x lighting/shading (columns), "
              f"{'paired material' if paired else first.material}, {first.emotion}")
    return paths


#: Frames of a clip on its filmstrip.
FILMSTRIP_FRAMES = 6


def filmstrip_frames(onset_frame: int, apex_frame: int, n: int = FILMSTRIP_FRAMES) -> list[int]:
    """``n`` frames evenly spaced from the onset's start to the apex (fewer where the onset is shorter).

    Examples
    --------
    >>> filmstrip_frames(0, 30)
    [0, 6, 12, 18, 24, 30]
    >>> filmstrip_frames(3, 5)
    [3, 4, 5]
    """
    return list(dict.fromkeys(int(round(x)) for x in np.linspace(onset_frame, apex_frame, n)))


def write_filmstrips(out: Path, manifest: pd.DataFrame, grid: GridFile) -> list[Path]:
    """A filmstrip per character of an animated grid (``filmstrip_<character>.png``): rows = shape
    levels, columns = :func:`filmstrip_frames` of the first expression that moves (its first
    material, or each level's own when paired, lighting and shading), labelled with frame and
    weight; returns their paths."""
    from stimulus_engine.grid.animation import frame_file
    from stimulus_engine.render import contact_sheet, save_png

    ok = manifest[manifest["status"].isin(["rendered", "up to date"])]
    if ok.empty:
        return []
    moving = ok[ok["expression"] != "neutral"]
    first = (moving if len(moving) else ok).iloc[0]
    sel = ok[(ok["expression"] == first.expression) & (ok["lighting"] == first.lighting)
             & (ok["shading"] == first.shading)]
    if not grid.pair_materials_with_shapes:
        sel = sel[sel["material"] == first.material]
    paths = []
    for character, clips in sel.groupby("character", sort=False):
        picks = filmstrip_frames(int(first.onset_frame), int(first.apex_frame))
        weights = [float(x) for x in str(first.weight_curve).split(";")]
        imgs = [np.asarray(Image.open(out / folder / frame_file(k)).convert("RGB"))
                for folder in clips["frames"] for k in picks]
        arr = contact_sheet(imgs, len(picks), thumb_width=180, row_labels=[str(x) for x in clips["shape_label"]],
                            col_labels=[f"frame {k} · w {weights[k]:.2f}" for k in picks],
                            title=f"{grid.name}: {character}, {first.emotion} over time ({first.fps} fps), "
                                  f"shape (rows), {first.lighting}, {first.shading}")
        paths.append(save_png(arr, out / f"filmstrip_{character}.png"))
    return paths
