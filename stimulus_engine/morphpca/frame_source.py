"""Frame sequences from image files, folders or video files, for the commands that take recordings.

Nagle et al. (§5) measure reconstructions and mimicries on video recordings. The ``mimicry``
and ``project`` commands take, for each sequence, image files and folders (frames in name
order) or video files (``.mp4``, ``.avi``, … read with OpenCV,
:func:`~.morph_video.read_video_frames`), or both: :func:`read_frames`. Each frame gets a name:
the image file's, or ``VIDEO-STEM_fNNNN`` for the NNNN-th frame of a video.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from appeal.errors import AppealInputError

__all__ = ["Frames", "is_video", "read_frames"]


def is_video(path: str | Path) -> bool:
    """Whether ``path`` names a video file (by its suffix)."""
    from stimulus_engine.morphpca.morph_video import VIDEO_SUFFIXES

    return Path(path).suffix.lower() in VIDEO_SUFFIXES


@dataclass
class Frames:
    """A frame sequence.

    Attributes
    ----------
    sources : list of Path
        The files read: frame images and video files, in order (for provenance).
    names : list of str
        One per frame: the image's file name, or ``VIDEO-STEM_fNNNN.png`` for a video frame.
    images : (n, h, w, 3) float32 array in [0, 1]
    """

    sources: list[Path]
    names: list[str]
    images: np.ndarray

    def __len__(self) -> int:
        return len(self.names)


def read_frames(paths: Sequence[str | Path], size: tuple[int, int] | None = None, what: str = "frames") -> Frames:
    """Read a frame sequence from image files, folders and video files.

    Parameters
    ----------
    paths : sequence of path-like
        In order; folders give their images in name order (:func:`~.io.list_images`).
    size : (h, w), optional
        Resize every frame to this size (area interpolation); without it all frames must have
        one size.
    what : str
        The option the paths came from, for error messages (e.g. ``--source``).

    Raises
    ------
    AppealInputError
        A missing or unreadable file or video, or frames of different sizes without ``size``.
    """
    from stimulus_engine.morphpca.io import list_images, read_images
    from stimulus_engine.morphpca.morph_video import read_video_frames

    sources, names, parts = [], [], []
    images: list[Path] = []

    def flush() -> None:  # consecutive image files are read together (one size check, one error list)
        if images:
            parts.append(read_images(images, size))
            names.extend(p.name for p in images)
            images.clear()

    for p in map(Path, paths):
        if not is_video(p):
            found = list_images([p])
            images.extend(found)
            sources.extend(found)
            continue
        flush()
        clip = read_video_frames(p)
        if size is not None and clip.shape[1:3] != tuple(size):
            clip = np.stack([cv2.resize(f, (size[1], size[0]), interpolation=cv2.INTER_AREA) for f in clip])
        parts.append(clip)
        names.extend(f"{p.stem}_f{k:04d}.png" for k in range(len(clip)))
        sources.append(p)
    flush()
    if not parts:
        raise AppealInputError(f"{what}: no frames (expected image files, folders of images or video files)")
    shapes = {part.shape[1:] for part in parts}
    if len(shapes) > 1:
        raise AppealInputError(f"{what}: frames of different sizes ({', '.join(sorted(f'{s[0]}x{s[1]}' for s in shapes))}"
                               f"; expected one size, or give the model's size)")
    return Frames(sources, names, np.concatenate(parts))
