"""What every ``appeal faces`` call writes: images with their ``.tem``, ``manifest.csv`` and a contact sheet.

``manifest.csv`` has one row per output image: ``file`` (relative to the manifest, as ``appeal
stimuli audit`` and the grid tools read it), ``tem`` (its template, blank for none), ``operation``,
``inputs`` (the input images, ``;``-separated), ``parameters`` (JSON) and any per-output columns an
operation adds (e.g. a continuum's ``step`` and ``weight``). ``contact_sheet.png`` shows every
output, labelled with its file name.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from appeal.cells import write_table
from appeal.errors import AppealInputError
from stimulus_engine.faces2d.template import Template, write_template

__all__ = ["NAMED_COLOURS", "parse_colour", "to_uint8", "FaceOutput", "write_outputs"]

NAMED_COLOURS = {"white": (255, 255, 255), "black": (0, 0, 0), "grey": (128, 128, 128), "gray": (128, 128, 128),
                 "mid-grey": (128, 128, 128)}


def parse_colour(text: str, what: str = "--fill") -> tuple[float, float, float]:
    """A colour as RGB floats in [0, 1] from ``white``/``black``/``grey``, ``#RRGGBB`` or ``R,G,B`` (0–255)."""
    s = str(text).strip().lower()
    try:
        if s in NAMED_COLOURS:
            rgb = NAMED_COLOURS[s]
        elif s.startswith("#") and len(s) == 7:
            rgb = tuple(int(s[i : i + 2], 16) for i in (1, 3, 5))
        else:
            rgb = tuple(int(float(v)) for v in s.split(","))
            if len(rgb) != 3 or not all(0 <= v <= 255 for v in rgb):
                raise ValueError
    except ValueError:
        raise AppealInputError(f"{what}: cannot read colour '{text}' (expected white, black, grey, #RRGGBB "
                               "or R,G,B with values 0-255)") from None
    return tuple(v / 255.0 for v in rgb)  # type: ignore[return-value]


def to_uint8(image: np.ndarray) -> np.ndarray:
    """Float [0, 1] image → uint8 (rounded)."""
    return np.clip(np.asarray(image, np.float32) * 255.0 + 0.5, 0, 255).astype(np.uint8)


@dataclass
class FaceOutput:
    """One output image: its file name, pixels (float RGB or RGBA), template (or None) and manifest extras."""

    name: str
    image: np.ndarray
    template: Template | None
    inputs: Sequence[str | Path]
    columns: dict[str, Any] = field(default_factory=dict)


def _sheet_thumb(image: np.ndarray) -> np.ndarray:
    img = np.asarray(image, np.float32)
    if img.shape[-1] == 4:  # transparent: shown over white
        img = img[..., :3] * img[..., 3:] + (1.0 - img[..., 3:])
    return to_uint8(img)


def write_outputs(folder: str | Path, outputs: Sequence[FaceOutput], operation: str, parameters: dict[str, Any],
                  *, title: str | None = None, ncols: int | None = None) -> Path:
    """Write each output's PNG (and ``.tem``), ``manifest.csv`` and ``contact_sheet.png`` into ``folder``.

    Returns
    -------
    Path
        The manifest.
    """
    import pandas as pd

    from stimulus_engine.render.contact_sheet import contact_sheet, save_png

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for o in outputs:
        png = folder / o.name
        save_png(to_uint8(o.image), png)
        tem = ""
        if o.template is not None:
            tem = png.with_suffix(".tem").name
            write_template(folder / tem, o.template)
        rows.append({"file": o.name, "tem": tem, "operation": operation,
                     "inputs": ";".join(str(p) for p in o.inputs),
                     "parameters": json.dumps(parameters, sort_keys=True), **o.columns})
    manifest = folder / "manifest.csv"

    write_table(pd.DataFrame(rows), manifest)
    n = len(outputs)
    cols = ncols or min(n, 6)
    sheet = contact_sheet([_sheet_thumb(o.image) for o in outputs], cols, thumb_width=200,
                          labels=[Path(o.name).stem[:24] for o in outputs], title=title or operation)
    save_png(sheet, folder / "contact_sheet.png")
    return manifest
