"""Expression sequences from two photographs, and frames from video files.

Nagle et al. build each person's expression space from video frames. Where a lab has only a
neutral and an expressive photograph of a person (the London set: a neutral and a smiling
photo per identity), :func:`morph_sequence` makes a short stand-in video: the landmarks move
linearly from one photo's to the other's, both photos are warped onto the in-between shape
(thin-plate splines, :func:`~.landmark_warp.tps_displacement`) and cross-dissolved. Frames of a
real video are read with :func:`read_video_frames` (OpenCV) and modelled the same way.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.morphpca.flow import grid, warp_image
from stimulus_engine.morphpca.landmark_warp import tps_displacement

__all__ = ["VIDEO_SUFFIXES", "morph_sequence", "read_video_frames"]

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm")


def morph_sequence(image_a: np.ndarray, points_a: np.ndarray, image_b: np.ndarray, points_b: np.ndarray,
                   n_frames: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Frames morphing ``image_a`` into ``image_b`` (same size, same K landmarks).

    Parameters
    ----------
    image_a, image_b : (h, w, 3) float32 in [0, 1]
    points_a, points_b : (K, 2) arrays
        Corresponding landmarks (e.g. dlib's 68) in each image.
    n_frames : int
        At least 2; the first frame is ``image_a``, the last ``image_b``.

    Returns
    -------
    frames : (n_frames, h, w, 3) float32
    points : (n_frames, K, 2)
        The landmarks of every frame (linearly interpolated).
    """
    if n_frames < 2:
        raise AppealInputError(f"frames: expected at least 2 (got {n_frames})")
    a, b = np.asarray(image_a, np.float32), np.asarray(image_b, np.float32)
    if a.shape != b.shape:
        raise AppealInputError(f"images: sizes {a.shape[:2]} and {b.shape[:2]} differ (expected two registered photos)")
    pa, pb = np.asarray(points_a, float), np.asarray(points_b, float)
    h, w = a.shape[:2]
    g = grid(h, w)
    frames = np.empty((n_frames, h, w, 3), np.float32)
    points = np.empty((n_frames, len(pa), 2))
    for k, t in enumerate(np.linspace(0.0, 1.0, n_frames)):
        pt = (1 - t) * pa + t * pb
        # frame(x) = (1 - t) a(x + d_a(x)) + t b(x + d_b(x)), the splines taking pt to each photo's points
        wa = warp_image(a, g + tps_displacement(pt, pa, (h, w))) if t < 1 else 0.0
        wb = warp_image(b, g + tps_displacement(pt, pb, (h, w))) if t > 0 else 0.0
        frames[k] = (1 - t) * wa + t * wb
        points[k] = pt
    return frames, points


def read_video_frames(path: str | Path, every: int = 1, max_frames: int | None = None) -> np.ndarray:
    """Frames ``(n, h, w, 3)`` float32 RGB in [0, 1] of a video file (every ``every``-th frame)."""
    path = Path(path)
    if not path.is_file():
        raise AppealInputError(f"{path}: video file not found")
    cap = cv2.VideoCapture(str(path))
    frames = []
    try:
        k = 0
        while max_frames is None or len(frames) < max_frames:
            ok, frame = cap.read()
            if not ok:
                break
            if k % every == 0:
                frames.append(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0)
            k += 1
    finally:
        cap.release()
    if not frames:
        raise AppealInputError(f"{path}: no frames could be read (expected a video OpenCV can decode: "
                               f"{', '.join(VIDEO_SUFFIXES)})")
    return np.stack(frames)
