"""Contact sheets: many stimuli on one labelled PNG (laid out like thesis Fig. 6.11)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from appeal.atomic import atomic_write_bytes

__all__ = ["contact_sheet", "save_png"]


def _font(size: int) -> ImageFont.ImageFont:
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1 has no size argument
        return ImageFont.load_default()


def contact_sheet(images: Sequence[np.ndarray | None], ncols: int, *, thumb_width: int = 240,
                  row_labels: Sequence[str] | None = None, col_labels: Sequence[str] | None = None,
                  labels: Sequence[str] | None = None, title: str | None = None,
                  background: tuple[int, int, int] = (255, 255, 255)) -> np.ndarray:
    """Lay images out in a grid with row, column and per-image labels.

    Parameters
    ----------
    images : sequence of (H, W, 3) uint8 arrays or None
        In row-major order; ``None`` leaves a cell empty (e.g. a failed render).
    ncols : int
        Images per row.
    thumb_width : int
        Width of each cell; heights keep the first image's aspect ratio.
    row_labels, col_labels : sequence of str, optional
        Written left of each row and above each column.
    labels : sequence of str, optional
        One small caption under each image.
    title : str, optional
        A heading line.

    Returns
    -------
    (H, W, 3) uint8 array
    """
    imgs = list(images)
    first = next((im for im in imgs if im is not None), None)
    if first is None:
        raise ValueError("contact_sheet: no images")
    if ncols < 1:
        raise ValueError(f"contact_sheet: ncols must be >= 1 (got {ncols})")
    nrows = (len(imgs) + ncols - 1) // ncols
    tw = int(thumb_width)
    th = int(round(tw * first.shape[0] / first.shape[1]))
    font = _font(max(10, tw // 14))
    cap_h = (tw // 14 + 6) if labels else 0
    left = (max(len(s) for s in row_labels) * (tw // 24) + 16) if row_labels else 0
    top = (tw // 14 + 10 if col_labels else 0) + (tw // 10 + 10 if title else 0)
    pad = 4
    W = left + ncols * (tw + pad) + pad
    if title:  # the heading is never cut off: a narrow sheet widens to it
        W = max(W, int(ImageDraw.Draw(Image.new("RGB", (1, 1))).textlength(title, font=_font(max(12, tw // 10)))) + 2 * pad)
    H = top + nrows * (th + cap_h + pad) + pad
    sheet = Image.new("RGB", (W, H), background)
    draw = ImageDraw.Draw(sheet)
    y0 = 4
    if title:
        draw.text((pad, y0), title, fill=(0, 0, 0), font=_font(max(12, tw // 10)))
        y0 += tw // 10 + 10
    if col_labels:
        for c, s in enumerate(col_labels[:ncols]):
            draw.text((left + pad + c * (tw + pad) + 2, y0), str(s), fill=(0, 0, 0), font=font)
    for i, im in enumerate(imgs):
        r, c = divmod(i, ncols)
        x = left + pad + c * (tw + pad)
        y = top + pad + r * (th + cap_h + pad)
        if im is not None:
            thumb = Image.fromarray(np.asarray(im, dtype=np.uint8)[..., :3]).resize((tw, th), Image.LANCZOS)
            sheet.paste(thumb, (x, y))
        else:
            draw.rectangle([x, y, x + tw - 1, y + th - 1], outline=(200, 0, 0))
        if labels and i < len(labels):
            draw.text((x + 2, y + th + 2), str(labels[i]), fill=(0, 0, 0), font=font)
    if row_labels:
        for r, s in enumerate(row_labels[:nrows]):
            draw.text((pad, top + pad + r * (th + cap_h + pad) + th // 2 - 6), str(s), fill=(0, 0, 0), font=font)
    return np.asarray(sheet)


def save_png(image: np.ndarray, path: str | Path) -> Path:
    """Write an RGB uint8 array as a PNG, atomically (no half-written files); deterministic bytes."""
    import io

    buf = io.BytesIO()
    Image.fromarray(np.asarray(image, dtype=np.uint8)).save(buf, format="PNG", optimize=False, compress_level=1)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())
    return path
