"""Simple drawn face images + a manifest, for sessions without rendered stimuli (demo, tests).

Each image is a schematic face whose features follow the factor levels: eye size shrinks and
the face narrows with the stylisation/shape level (neotenic -> realistic), skin shading
follows material, the mouth follows the expression/emotion, hue follows the character.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

__all__ = ["draw_face_grid"]

_MOUTH = {"happy": 1, "happiness": 1, "angry": -1, "anger": -1, "sad": -1, "sadness": -1,
          "surprise": 2, "surprised": 2, "neutral": 0}


def _level_fraction(levels: Sequence[str], level: str) -> float:
    return levels.index(level) / max(len(levels) - 1, 1)


def draw_face_grid(out_dir: str | Path, factors: Mapping[str, Sequence[object]], *, size: tuple[int, int] = (320, 240),
                   background: int = 128) -> Path:
    """Draw one face per combination of factor levels and write ``out_dir/manifest.csv``.

    Parameters
    ----------
    out_dir : str | Path
        Folder for the PNGs and the manifest.
    factors : mapping
        factor -> levels (e.g. ``{"character": ["c1", "c2"], "stylisation": [0, 1, 2]}``).
    size : (int, int)
        Image width and height in pixels.
    background : int
        Grey level of the background (128 = 50% grey).

    Returns
    -------
    Path
        The manifest (``file`` + one column per factor).
    """
    from PIL import Image, ImageDraw

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    names = list(factors)
    levels = {f: [str(v) for v in vs] for f, vs in factors.items()}
    rows = []
    w, h = size
    for combo in itertools.product(*(levels[f] for f in names)):
        lv = dict(zip(names, combo))
        real = [_level_fraction(levels[f], lv[f]) for f in ("stylisation", "shape") if f in lv]
        realism = sum(real) / len(real) if real else 0.5
        mat = _level_fraction(levels["material"], lv["material"]) if "material" in lv else realism
        char = _level_fraction(levels["character"], lv["character"]) if "character" in lv else 0.0
        im = Image.new("RGB", size, (background,) * 3)
        d = ImageDraw.Draw(im)
        fw = w * (0.42 - 0.1 * realism)
        fh = h * 0.8
        cx, cy = w / 2, h / 2
        skin = (int(230 - 40 * char - 30 * mat), int(190 - 30 * mat), int(160 - 20 * char))
        d.ellipse([cx - fw / 2, cy - fh / 2, cx + fw / 2, cy + fh / 2], fill=skin, outline=(60, 40, 30), width=2)
        er = h * (0.085 - 0.05 * realism)
        for sx in (-1, 1):
            ex, ey = cx + sx * fw * 0.22, cy - fh * 0.1
            d.ellipse([ex - er, ey - er * 0.8, ex + er, ey + er * 0.8], fill=(250, 250, 250), outline=(30, 30, 30))
            d.ellipse([ex - er * 0.45, ey - er * 0.45, ex + er * 0.45, ey + er * 0.45], fill=(40, 60, 90))
        d.line([cx, cy - fh * 0.02, cx - fw * 0.04, cy + fh * 0.12, cx, cy + fh * 0.13], fill=(120, 80, 60), width=2)
        emo = next((lv[f] for f in ("emotion", "expression") if f in lv), "neutral")
        kind = _MOUTH.get(emo.lower(), 0)
        mx, my, mw = cx, cy + fh * 0.25, fw * 0.22
        if kind == 2:
            d.ellipse([mx - mw * 0.35, my - mw * 0.35, mx + mw * 0.35, my + mw * 0.35], fill=(90, 30, 30))
        elif kind == 0:
            d.line([mx - mw, my, mx + mw, my], fill=(120, 40, 40), width=3)
        else:
            box = [mx - mw, my - mw * 0.5, mx + mw, my + mw * 0.5]
            d.arc(box, 20, 160, fill=(120, 40, 40), width=3) if kind > 0 else d.arc(box, 200, 340, fill=(120, 40, 40), width=3)
        if emo.lower() in ("angry", "anger"):
            for sx in (-1, 1):
                ex = cx + sx * fw * 0.22
                d.line([ex - sx * er, cy - fh * 0.2, ex + sx * er, cy - fh * 0.16], fill=(50, 30, 20), width=3)
        name = "_".join(f"{f}-{lv[f]}" for f in names) + ".png"
        im.save(out_dir / name)
        rows.append({"file": name, **lv})
    manifest = out_dir / "manifest.csv"
    pd.DataFrame(rows).to_csv(manifest, index=False)
    return manifest
