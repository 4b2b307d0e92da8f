"""Small animated grids for the clip tests, in the grid's manifest format.

Each clip is a folder ``clips/<stem>/`` of lossless PNG frames ``frame_00000.png`` ... (a grey
64x64 frame with a white bar that moves 6 pixels right per frame, and the frame number as a dark
square's height in the top-left corner, so a screenshot says which frame was up), an H.264
``clips/<stem>.mp4`` of the same frames, and one ``manifest.csv`` row: ``file``, ``frames``,
``n_frames``, ``fps``, ``onset_frame``, ``apex_frame``, ``weight_curve``, ``frames_sha256``,
``mp4_sha256`` and one column per factor (paths relative to the manifest's folder).
"""

from __future__ import annotations

import hashlib
import itertools
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from PIL import Image

BAR_STEP = 6
SIZE = 64


def frame_image(k: int, grey: int = 128, size: int = SIZE) -> np.ndarray:
    """Frame ``k``: grey, a white bar at x = 4 + 6k, a dark square k+1 pixels tall top-left."""
    im = np.full((size, size, 3), grey, np.uint8)
    x = 4 + BAR_STEP * k
    im[8:size - 8, x:x + 4] = 255
    im[:k + 1, :3] = 20
    return im


def bar_x(k: int) -> int:
    """The bar's left edge in frame ``k`` (image pixels)."""
    return 4 + BAR_STEP * k


def _write_mp4(path: Path, frames: Sequence[np.ndarray], fps: float) -> None:
    import av
    from fractions import Fraction

    with av.open(str(path), "w") as container:
        stream = container.add_stream("libx264", rate=Fraction(fps).limit_denominator(1001))
        stream.width, stream.height, stream.pix_fmt = frames[0].shape[1], frames[0].shape[0], "yuv420p"
        for im in frames:
            for packet in stream.encode(av.VideoFrame.from_ndarray(im, format="rgb24")):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _frames_digest(paths: Sequence[Path]) -> str:
    """The grid's ``frames_sha256``: SHA-256 of the frames' SHA-256 hex digests concatenated in order."""
    return hashlib.sha256("".join(_sha256(p) for p in paths).encode("ascii")).hexdigest()


def make_clip_grid(folder: Path, factors: Mapping[str, Sequence[object]], *, n_frames: int = 6, fps: float = 30,
                   onset_frame: int = 1, apex_frame: int | None = None, size: int = SIZE) -> Path:
    """Write one clip per factor-level combination and the manifest; returns ``manifest.csv``.

    Clips differ in their grey level (72-112, darker than a 50% grey background, so a
    screenshot finds the clip's box); every clip has ``n_frames`` frames at ``fps``.
    """
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "clips").mkdir(exist_ok=True)
    apex = n_frames - 1 if apex_frame is None else apex_frame
    rows = []
    for i, levels in enumerate(itertools.product(*factors.values())):
        cell = dict(zip(factors, levels))
        stem = "_".join(f"{k}-{v}" for k, v in cell.items())
        frames_dir = folder / "clips" / stem
        frames_dir.mkdir()
        images = [frame_image(k, grey=72 + 10 * (i % 5), size=size) for k in range(n_frames)]
        paths = []
        for k, im in enumerate(images):
            p = frames_dir / f"frame_{k:05d}.png"
            Image.fromarray(im).save(p)
            paths.append(p)
        mp4 = folder / "clips" / f"{stem}.mp4"
        _write_mp4(mp4, images, fps)
        curve = [0.0 if k < onset_frame else min(1.0, (k - onset_frame + 1) / max(1, apex - onset_frame + 1))
                 for k in range(n_frames)]
        rows.append({"file": f"clips/{stem}.mp4", "frames": f"clips/{stem}", "n_frames": n_frames, "fps": fps,
                     "onset_frame": onset_frame, "apex_frame": apex,
                     "weight_curve": ";".join(f"{w:.4f}" for w in curve), "frames_sha256": _frames_digest(paths),
                     "mp4_sha256": _sha256(mp4), **cell})
    manifest = folder / "manifest.csv"
    pd.DataFrame(rows).to_csv(manifest, index=False)
    return manifest
