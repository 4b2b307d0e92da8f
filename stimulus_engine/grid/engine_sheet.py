"""One character under every engine and lighting preset, beside a photograph (issue 15).

:func:`engine_sheet` renders one character of a grid file (the first) — its realistic level, first
material, neutral and happy, under ``direct_hard``, ``direct_soft`` and ``gi_soft`` with PBR
shading — once per render engine (the same scene description: only ``render.engine`` differs)
and lays the images out with a real photograph aligned on the eyes in the last column
(``appeal stimuli engine-sheet``): to judge whether the skin reads as skin, and which engine is
closer to a photograph.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image

from stimulus_engine.grid_schema import GridFile

__all__ = ["SHEET_LIGHTING", "SHEET_EXPRESSIONS", "engine_grid", "engine_sheet"]

SHEET_LIGHTING = ("direct_hard", "direct_soft", "gi_soft")
SHEET_EXPRESSIONS = ("neutral", "happiness")


def engine_grid(grid: GridFile, engine: str, character: str | None = None) -> GridFile:
    """``grid`` cut down to the sheet's images (one character — the first, or ``character`` —,
    realistic, first material) for ``engine``."""
    from appeal.errors import AppealInputError

    chars = [c for c in grid.characters if character is None or c.name == character][:1]
    if not chars:
        raise AppealInputError(f"--character: '{character}' is not in the grid (expected one of "
                               f"{', '.join(c.name for c in grid.characters)})")
    render = grid.render.model_copy(update={"engine": engine})
    return grid.model_copy(update={
        "characters": chars, "shapes": [0.0], "materials": grid.materials[:1],
        "pair_materials_with_shapes": False, "expressions": list(SHEET_EXPRESSIONS),
        "lighting": list(SHEET_LIGHTING), "shading": ["pbr"], "render": render, "photographs": [],
    })


def engine_sheet(grid: GridFile, out: Path, photo: str | Path, *, engines: Sequence[str] = ("pyrender", "cycles"),
                 character: str | None = None, n_jobs: int | None = None, thumb_width: int = 360) -> np.ndarray:
    """Render the sheet's images with each engine into ``out/ENGINE/`` and return the sheet.

    Rows: expression × lighting; columns: the engines, then ``photo`` aligned on the first
    engine's image (eye centres and philtrum, :func:`~.photo_sheet.photo_like_render`).
    """
    from stimulus_engine.grid.photo_sheet import photo_like_render
    from stimulus_engine.grid.run import run_grid
    from stimulus_engine.render.contact_sheet import contact_sheet

    grids = {e: engine_grid(grid, e, character) for e in engines}
    manifests = {e: run_grid(g, out / e, n_jobs=n_jobs)[0] for e, g in grids.items()}
    with Image.open(photo) as im:
        picture = np.asarray(im.convert("RGB"))
    cells, rows = [], []
    for expression in SHEET_EXPRESSIONS:
        for lighting in SHEET_LIGHTING:
            row = []
            for e in engines:
                m = manifests[e].set_index(["expression", "lighting"])
                with Image.open(out / e / m.loc[(expression, lighting), "file"]) as im:
                    row.append(np.asarray(im.convert("RGB")))
            reference = row[0]
            background = tuple(int(v) for v in reference[0, 0])
            cells += row + [photo_like_render(picture, reference, background, str(photo))]
            rows.append(f"{expression}, {lighting}")
    name = grids[engines[0]].characters[0].name
    return contact_sheet(cells, len(engines) + 1, thumb_width=thumb_width, row_labels=rows,
                         col_labels=[*engines, "photograph, eyes aligned"],
                         title=f"{name}: realistic level, PBR shading, by render engine")
