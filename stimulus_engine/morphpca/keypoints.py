"""Keypoints: from a CSV file, from WebMorph/Psychomorph ``.tem`` templates, or detected.

All three give per-image *faceframes* ``(3, 2)``: left eye centre, right eye centre, philtrum.

* CSV: one row per image, columns ``image, left_eye_x, left_eye_y, right_eye_x, right_eye_y,
  philtrum_x, philtrum_y`` (``image`` is the file name).
* ``.tem``: the first line is the number of points, then one ``x y`` line per point (then
  line definitions, ignored). In the 189-point FRL/WebMorph template points 0 and 1 are the
  pupils, 55 the base of the nose (subnasale) and 90 the top of the upper lip; the philtrum
  centre is the midpoint of 55 and 90.
* Automatic: dlib's HOG face detector and 68-point shape predictor, whose weights ship in
  the ``face-recognition-models`` wheel (no download; works offline). Eye centres are the
  means of points 36–41 and 42–47, the philtrum the midpoint of 33 and 51. The 68-point
  model was trained on iBUG 300-W, whose licence excludes commercial use.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from appeal.cells import write_table
from appeal.errors import AppealInputError

__all__ = ["FRAME_COLUMNS", "read_tem", "faceframe_from_tem", "faceframe_from_68", "read_keypoints_csv",
           "read_landmarks_csv", "write_keypoints_csv", "detect_landmarks", "detect_landmarks_scored", "detect_faceframe"]

FRAME_COLUMNS = ("left_eye_x", "left_eye_y", "right_eye_x", "right_eye_y", "philtrum_x", "philtrum_y")
_TEM_PUPILS = (0, 1)
_TEM_PHILTRUM = (55, 90)


def read_tem(path: str | Path) -> np.ndarray:
    """Points ``(n, 2)`` of a WebMorph/Psychomorph template file."""
    path = Path(path)
    if not path.is_file():
        raise AppealInputError(f"{path}: template file not found (expected a .tem file beside the image)")
    lines = path.read_text(errors="replace").split("\n")
    try:
        n = int(lines[0].strip())
        pts = np.array([[float(v) for v in lines[1 + i].split()[:2]] for i in range(n)])
    except (ValueError, IndexError):
        raise AppealInputError(f"{path}: not a .tem template (expected a point count, then one 'x y' line per point)") from None
    if pts.shape != (n, 2):
        raise AppealInputError(f"{path}: expected {n} 'x y' lines after the point count")
    return pts


def faceframe_from_tem(points: np.ndarray, path: str | Path = "template") -> np.ndarray:
    """Faceframe from the 189-point FRL/WebMorph template (pupils 0, 1; philtrum = mean of 55, 90)."""
    if len(points) < 189:
        raise AppealInputError(f"{path}: expected the 189-point WebMorph/FRL template (got {len(points)} points)")
    eyes = points[list(_TEM_PUPILS)]
    eyes = eyes[np.argsort(eyes[:, 0])]
    return np.vstack([eyes, points[list(_TEM_PHILTRUM)].mean(axis=0)])


def read_keypoints_csv(path: str | Path, images: Sequence[str | Path]) -> np.ndarray:
    """Faceframes ``(n, 3, 2)`` for ``images`` (matched by file name) from a CSV file."""
    import pandas as pd

    path = Path(path)
    if not path.is_file():
        raise AppealInputError(f"{path}: keypoints file not found")
    try:
        df = pd.read_csv(path)
    except Exception as exc:  # noqa: BLE001 - any parse failure is bad input
        raise AppealInputError(f"{path}: cannot read as CSV ({exc})".splitlines()[0]) from None
    missing_cols = [c for c in ("image", *FRAME_COLUMNS) if c not in df.columns]
    if missing_cols:
        raise AppealInputError(f"{path}: missing column(s) {', '.join(missing_cols)} (expected image, "
                               f"{', '.join(FRAME_COLUMNS)})")
    df["image"] = df["image"].astype(str).map(lambda s: Path(s).name)
    by_name = df.set_index("image")
    problems, frames = [], []
    for img in images:
        name = Path(img).name
        if name not in by_name.index:
            problems.append(f"{path}: image: no keypoints for '{name}' (expected one row per image)")
            continue
        row = by_name.loc[name]
        if isinstance(row, pd.DataFrame):
            problems.append(f"{path}: image: '{name}' has {len(row)} rows (expected one)")
            continue
        vals = pd.to_numeric(row[list(FRAME_COLUMNS)], errors="coerce").to_numpy(float)
        if not np.all(np.isfinite(vals)):
            bad = [c for c, v in zip(FRAME_COLUMNS, vals) if not np.isfinite(v)]
            problems.append(f"{path}: {', '.join(bad)}: missing or non-numeric for '{name}' (expected pixel coordinates)")
            continue
        frames.append(vals.reshape(3, 2))
    if problems:
        raise AppealInputError(problems)
    return np.stack(frames)


def write_keypoints_csv(path: str | Path, images: Sequence[str | Path], frames: np.ndarray,
                        landmarks: np.ndarray | None = None) -> Path:
    """Write faceframes ``(n, 3, 2)`` (and dense ``landmarks`` ``(n, K, 2)`` as ``pK_x/pK_y``
    columns) in the CSV format :func:`read_keypoints_csv` / :func:`read_landmarks_csv` read."""
    import pandas as pd


    df = pd.DataFrame(np.asarray(frames).reshape(len(images), 6), columns=list(FRAME_COLUMNS))
    df.insert(0, "image", [Path(p).name for p in images])
    if landmarks is not None:
        lm = np.asarray(landmarks, float)
        cols = [c for j in range(lm.shape[1]) for c in (f"p{j}_x", f"p{j}_y")]
        df = pd.concat([df, pd.DataFrame(lm.reshape(len(images), -1), columns=cols)], axis=1)
    return write_table(df, path, float_format="%.3f")


_DLIB: dict = {}


def _dlib_models():
    if not _DLIB:
        try:
            import dlib
            import face_recognition_models
        except ImportError as exc:  # pragma: no cover - both are dependencies
            raise AppealInputError(f"automatic keypoints need dlib-bin and face-recognition-models ({exc})") from None
        _DLIB["detector"] = dlib.get_frontal_face_detector()
        _DLIB["predictor"] = dlib.shape_predictor(face_recognition_models.pose_predictor_model_location())
        _DLIB["rect"] = dlib.rectangle
    return _DLIB


def detect_landmarks(image: np.ndarray, name: str = "image", max_side: int = 480) -> np.ndarray:
    """The 68 dlib landmarks ``(68, 2)`` of the largest face in ``image`` (float [0, 1] or uint8 RGB).

    The image is shrunk to at most ``max_side`` pixels for the detector; the shape predictor
    then runs at full resolution inside the (scaled-back) face box.
    """
    return detect_landmarks_scored(image, name, max_side)[0]


def detect_landmarks_scored(image: np.ndarray, name: str = "image", max_side: int = 480) -> tuple[np.ndarray, float]:
    """:func:`detect_landmarks` and the detector's score for that face (higher: more face-like;
    dlib reports faces from score 0 up)."""
    import cv2

    m = _dlib_models()
    img = np.asarray(image)
    if img.dtype != np.uint8:
        img = np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)
    if img.ndim == 2:
        img = np.dstack([img] * 3)
    img = np.ascontiguousarray(img[..., :3])
    scale = min(1.0, max_side / max(img.shape[:2]))
    small = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA) if scale < 1 else img
    rects, scores, _ = m["detector"].run(small, 1, 0.0)
    if len(rects) == 0 and small.shape[0] < 400:
        up = cv2.resize(small, None, fx=2, fy=2, interpolation=cv2.INTER_CUBIC)
        (rects, scores, _), scale = m["detector"].run(up, 1, 0.0), scale * 2
    if len(rects) == 0:
        raise AppealInputError(f"{name}: no face found by the landmark detector (expected a frontal face; "
                               "give --keypoints FILE or .tem templates instead)")
    k = max(range(len(rects)), key=lambda i: rects[i].width() * rects[i].height())
    r = rects[k]
    box = m["rect"](int(r.left() / scale), int(r.top() / scale), int(r.right() / scale), int(r.bottom() / scale))
    shape = m["predictor"](img, box)
    return np.array([[p.x, p.y] for p in shape.parts()], dtype=np.float64), float(scores[k])


def faceframe_from_68(points: np.ndarray) -> np.ndarray:
    """Faceframe ``(3, 2)`` from the 68 iBUG/dlib landmarks (eye means, midpoint of 33 and 51)."""
    lm = np.asarray(points, float)
    eyes = np.array([lm[36:42].mean(axis=0), lm[42:48].mean(axis=0)])
    eyes = eyes[np.argsort(eyes[:, 0])]
    return np.vstack([eyes, (lm[33] + lm[51]) / 2.0])


def detect_faceframe(image: np.ndarray, name: str = "image") -> np.ndarray:
    """Faceframe ``(3, 2)`` of ``image`` from the detected 68 landmarks."""
    return faceframe_from_68(detect_landmarks(image, name))


def read_landmarks_csv(path: str | Path, images: Sequence[str | Path]) -> np.ndarray | None:
    """Dense landmarks ``(n, K, 2)`` from the optional ``p0_x, p0_y, p1_x, …`` columns of a keypoints
    CSV (matched by image name, as :func:`read_keypoints_csv`), or None when it has none."""
    import pandas as pd

    df = pd.read_csv(path)
    k = 0
    while f"p{k}_x" in df.columns and f"p{k}_y" in df.columns:
        k += 1
    if k == 0:
        return None
    cols = [c for j in range(k) for c in (f"p{j}_x", f"p{j}_y")]
    by_name = df.assign(image=df["image"].astype(str).map(lambda s: Path(s).name)).set_index("image")
    out = np.empty((len(images), k, 2))
    for i, img in enumerate(images):
        vals = pd.to_numeric(by_name.loc[Path(img).name, cols], errors="coerce").to_numpy(float)
        if not np.all(np.isfinite(vals)):
            raise AppealInputError(f"{path}: p0_x..p{k - 1}_y: missing or non-numeric for '{Path(img).name}' "
                                   "(expected every landmark of every image)")
        out[i] = vals.reshape(k, 2)
    return out
