"""One character under every renderer and lighting preset, beside a photograph (issue 15).

:func:`engine_sheet` renders one character of a grid file (the first) — its realistic level, first
material, neutral and happy, under ``direct_hard``, ``direct_soft`` and ``gi_soft`` — once per
*variant* (engine and shading: today's pyrender ``pbr``, pyrender's ``skin`` shading, Cycles; the
same scene description, only ``render.engine`` and ``shading`` differ) and lays the images out
with a real photograph aligned on the eyes in the last column (``appeal stimuli engine-sheet``):
to judge whether the skin reads as skin, and which renderer is closer to a photograph.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image

from stimulus_engine.grid.schema import GridFile

__all__ = ["SHEET_LIGHTING", "SHEET_EXPRESSIONS", "VARIANTS", "engine_grid", "engine_sheet", "variants_for"]

SHEET_LIGHTING = ("direct_hard", "direct_soft", "gi_soft")
SHEET_EXPRESSIONS = ("neutral", "happiness")
#: (engine, shading, column label) of the sheet, in order.
VARIANTS = (("pyrender", "pbr", "pyrender, pbr"), ("pyrender", "skin", "pyrender, skin shading"),
            ("cycles", "pbr", "Cycles (path traced)"))


def variants_for(engines: Sequence[str]) -> list[tuple[str, str, str]]:
    """The sheet's columns for the chosen engines."""
    return [v for v in VARIANTS if v[0] in engines]


def engine_grid(grid: GridFile, engine: str, character: str | None = None, shading: str = "pbr") -> GridFile:
    """``grid`` cut down to the sheet's images (one character — the first, or ``character`` —,
    realistic, first material) for ``engine`` and ``shading``."""
    from appeal.errors import AppealInputError

    chars = [c for c in grid.characters if character is None or c.name == character][:1]
    if not chars:
        raise AppealInputError(f"--character: '{character}' is not in the grid (expected one of "
                               f"{', '.join(c.name for c in grid.characters)})")
    render = grid.render.model_copy(update={"engine": engine})
    return grid.model_copy(update={
        "characters": chars, "shapes": [0.0], "materials": grid.material_specs()[:1],
        "pair_materials_with_shapes": False, "expressions": list(SHEET_EXPRESSIONS),
        "lighting": list(SHEET_LIGHTING), "shading": [shading], "render": render, "photographs": [],
        "animation": None,  # still images (an animated grid's apexes)
    })


def engine_sheet(grid: GridFile, out: Path, photo: str | Path, *, engines: Sequence[str] = ("pyrender", "cycles"),
                 character: str | None = None, n_jobs: int | None = None, thumb_width: int = 360) -> np.ndarray:
    """Render the sheet's images for each variant of ``engines`` into ``out/ENGINE-SHADING/`` and
    return the sheet.

    Rows: expression × lighting; columns: the variants (:data:`VARIANTS`), then ``photo``
    aligned on the first column's image (eye centres and philtrum,
    :func:`~.photo_sheet.photo_like_render`).
    """
    from stimulus_engine.grid.photo_sheet import photo_like_render
    from stimulus_engine.grid.run import run_grid
    from stimulus_engine.render.contact_sheet import contact_sheet

    variants = variants_for(engines)
    grids = {(e, sh): engine_grid(grid, e, character, sh) for e, sh, _ in variants}
    folders = {key: out / f"{key[0]}-{key[1]}" for key in grids}
    manifests = {key: run_grid(g, folders[key], n_jobs=n_jobs)[0].set_index(["expression", "lighting"])
                 for key, g in grids.items()}
    with Image.open(photo) as im:
        picture = np.asarray(im.convert("RGB"))
    cells, rows = [], []
    for expression in SHEET_EXPRESSIONS:
        for lighting in SHEET_LIGHTING:
            row = []
            for key, m in manifests.items():
                with Image.open(folders[key] / m.loc[(expression, lighting), "file"]) as im:
                    row.append(np.asarray(im.convert("RGB")))
            background = tuple(int(v) for v in row[0][0, 0])
            cells += row + [photo_like_render(picture, row[0], background, str(photo))]
            rows.append(f"{expression}, {lighting}")
    name = next(iter(grids.values())).characters[0].name
    return contact_sheet(cells, len(variants) + 1, thumb_width=thumb_width, row_labels=rows,
                         col_labels=[label for *_, label in variants] + ["photograph, eyes aligned"],
                         title=f"{name}: realistic level by renderer")
