"""Thin I/O: reading and normalising face images, saving and loading models (.npz + JSON).

A model is saved as ``NAME.npz`` (arrays) with its metadata as JSON both inside the archive
(key ``metadata_json``) and beside it (``NAME.json``). The metadata carry ``format`` and
``format_version``; :func:`load_model` reads every version up to the current one and fills
arrays that older versions lacked.
"""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from appeal.atomic import atomic_write_bytes, atomic_write_text
from appeal.errors import AppealInputError
from stimulus_engine.morphpca.faceframe import similarity_from_eyes, transform_points
from stimulus_engine.morphpca.pca import FORMAT, FORMAT_VERSION, MorphModel

__all__ = ["IMAGE_SUFFIXES", "list_images", "read_images", "register_faces", "canonical_eyes", "save_model",
           "load_model", "save_image", "parse_size"]

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff")


def parse_size(text: str) -> tuple[int, int]:
    """``"240x200"`` → ``(240, 200)`` (height × width)."""
    try:
        h, w = (int(v) for v in str(text).lower().replace("×", "x").split("x"))
        if h < 16 or w < 16:
            raise ValueError
    except ValueError:
        raise AppealInputError(f"--size: expected HEIGHTxWIDTH in pixels, each at least 16, e.g. 240x200 (got {text!r})") from None
    return h, w


def list_images(paths: Sequence[str | Path]) -> list[Path]:
    """Image files from files and folders (folders: their images, sorted by name).

    An entry may be a ``data:`` reference (a dataset group names one folder per member, e.g.
    ``data:london-frl-all/neutral_front``) or a glob pattern (:func:`appeal.datasets.expand_inputs`).
    """
    from appeal.datasets import expand_inputs

    out: list[Path] = []
    for p in expand_inputs(paths):
        if p.is_dir():
            out.extend(sorted(q for q in p.iterdir() if q.suffix.lower() in IMAGE_SUFFIXES))
        elif p.is_file():
            out.append(p)
        else:
            raise AppealInputError(f"{p}: image file or folder not found")
    return out


def read_images(paths: Sequence[str | Path], size: tuple[int, int] | None = None) -> np.ndarray:
    """Read colour images as ``(n, h, w, 3)`` float32 RGB in [0, 1].

    Parameters
    ----------
    paths : sequence of path
    size : (h, w), optional
        Resize every image to this size (area interpolation). Without it all images must
        already have the same size.

    Raises
    ------
    AppealInputError
        A file that is not an image, images of different sizes (without ``size``), or
        greyscale images mixed with colour ones (one line per problem).
    """
    imgs, kinds, problems = [], [], []
    for p in map(Path, paths):
        raw = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        if raw is None:
            problems.append(f"{p}: not a readable image (expected JPEG, PNG, BMP or TIFF)")
            continue
        grey = raw.ndim == 2 or raw.shape[2] == 1
        kinds.append((p, grey))
        if raw.dtype == np.uint16:
            raw = (raw / 257.0).astype(np.uint8)
        if grey:
            rgb = np.dstack([raw.reshape(raw.shape[:2])] * 3)
        else:
            rgb = cv2.cvtColor(raw[..., :3], cv2.COLOR_BGR2RGB)
        imgs.append((p, rgb))
    if kinds and len({g for _, g in kinds}) > 1:
        n_grey = sum(g for _, g in kinds)
        minority = n_grey <= len(kinds) - n_grey
        for p, g in kinds:
            if g == minority:
                problems.append(f"{p}: {'greyscale' if g else 'colour'} image among {'colour' if g else 'greyscale'} "
                                f"ones (expected all images colour, or all greyscale)")
    if size is None and imgs:
        first_p, first = imgs[0]
        for p, im in imgs[1:]:
            if im.shape[:2] != first.shape[:2]:
                problems.append(f"{p}: image size {im.shape[0]}x{im.shape[1]} differs from {first_p.name}'s "
                                f"{first.shape[0]}x{first.shape[1]} (expected all the same size; "
                                f"use --size HxW or register by keypoints)")
    if problems:
        raise AppealInputError(problems)
    out = []
    for _, im in imgs:
        if size is not None and im.shape[:2] != tuple(size):
            im = cv2.resize(im, (size[1], size[0]), interpolation=cv2.INTER_AREA)
        out.append(im.astype(np.float32) / 255.0)
    return np.stack(out) if out else np.zeros((0, 1, 1, 3), np.float32)


def canonical_eyes(size: tuple[int, int], eye_y: float = 0.40, eye_distance: float = 0.30) -> np.ndarray:
    """Eye positions ``(2, 2)`` of registered faces: at ``eye_y`` of the height, ``eye_distance`` of the width apart."""
    h, w = size
    return np.array([[w / 2 - eye_distance * w / 2, eye_y * h], [w / 2 + eye_distance * w / 2, eye_y * h]])


def register_faces(images: Sequence[np.ndarray] | np.ndarray, frames: np.ndarray, size: tuple[int, int],
                   eye_y: float = 0.40, eye_distance: float = 0.30, points: np.ndarray | None = None,
                   ) -> tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Similarity-align faces on their eye centres and crop to ``size`` (h, w).

    Large images are first shrunk by area averaging so the final resampling does not alias.

    Returns
    -------
    images : (n, h, w, 3) float32
    frames : (n, 3, 2) the faceframes in the registered images
    points : (n, K, 2)
        Only when ``points`` (landmarks of the input images) are given: moved with them.
    """
    dst = canonical_eyes(size, eye_y, eye_distance)
    out_imgs, out_frames, out_points = [], [], []
    for i, (img, fr) in enumerate(zip(images, frames)):
        img = np.asarray(img, np.float32)
        fr = np.asarray(fr, float)
        m = similarity_from_eyes(fr[:2], dst)
        scale = float(np.hypot(*m[:, 0]))
        pre = 1.0
        if scale < 0.5:
            pre = 2.0 * scale
            img = cv2.resize(img, None, fx=pre, fy=pre, interpolation=cv2.INTER_AREA)
            m = similarity_from_eyes(fr[:2] * pre, dst)
        warped = cv2.warpAffine(np.ascontiguousarray(img), m, (size[1], size[0]), flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_REPLICATE)
        out_imgs.append(warped)
        out_frames.append(transform_points(m, fr * pre))
        if points is not None:
            out_points.append(transform_points(m, np.asarray(points[i], float) * pre))
    if points is not None:
        return np.stack(out_imgs), np.stack(out_frames), np.stack(out_points)
    return np.stack(out_imgs), np.stack(out_frames)


def save_image(path: str | Path, image: np.ndarray) -> Path:
    """Write a float [0, 1] or uint8 RGB image (PNG/JPEG by suffix), atomically."""
    path = Path(path)
    img = np.asarray(image)
    if img.dtype != np.uint8:
        img = np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)
    ok, buf = cv2.imencode(path.suffix or ".png", cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    if not ok:
        raise AppealInputError(f"{path}: cannot encode an image with this suffix (expected .png or .jpg)")
    return atomic_write_bytes(path, buf.tobytes())


def _meta_json(model: MorphModel) -> dict:
    meta = dict(model.meta)
    meta.update(format=FORMAT, format_version=FORMAT_VERSION, size=list(model.size),
                n_components=model.n_components, total_variance=model.total_variance,
                explained_variance_ratio=[float(v) for v in model.explained_variance_ratio],
                faceframe=None if model.faceframe is None else np.asarray(model.faceframe).tolist())
    return meta


def save_model(model: MorphModel, path: str | Path) -> Path:
    """Save ``model`` as ``path`` (.npz) and its metadata as ``path`` with suffix .json."""
    path = Path(path)
    meta = _meta_json(model)
    arrays = dict(components=model.components, mean=model.mean, variances=model.variances,
                  reference=np.clip(model.reference * 255 + 0.5, 0, 255).astype(np.uint8),
                  ref_positions=model.ref_positions, loadings=model.loadings,
                  metadata_json=np.array(json.dumps(meta)))
    for name in ("faceframe", "ref_landmarks", "landmarks"):
        if getattr(model, name) is not None:
            arrays[name] = np.asarray(getattr(model, name), float)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())
    atomic_write_text(path.with_suffix(".json"), json.dumps(meta, indent=2) + "\n")
    return path


def load_model(path: str | Path) -> MorphModel:
    """Load a model saved by :func:`save_model` (any format version up to the current)."""
    path = Path(path)
    if not path.is_file():
        raise AppealInputError(f"{path}: model file not found (expected a .npz written by 'appeal stimuli morphpca build')")
    try:
        z = np.load(path, allow_pickle=False)
        meta = json.loads(str(z["metadata_json"]))
    except Exception:  # noqa: BLE001 - anything unreadable is bad input
        raise AppealInputError(f"{path}: not a morph-space PCA model (expected a .npz written by 'appeal stimuli morphpca build')") from None
    if meta.get("format") != FORMAT:
        raise AppealInputError(f"{path}: format: expected '{FORMAT}' (got {meta.get('format')!r})")
    version = int(meta.get("format_version", 0))
    if version > FORMAT_VERSION:
        raise AppealInputError(f"{path}: format_version: {version} is newer than this appeal-lab reads ({FORMAT_VERSION}); update appeal-lab")
    missing = [k for k in ("components", "mean", "variances", "reference", "ref_positions") if k not in z.files]
    if missing:
        raise AppealInputError(f"{path}: missing array(s) {', '.join(missing)}")
    components = z["components"].astype(np.float32)
    size = tuple(int(v) for v in meta["size"])
    loadings = z["loadings"].astype(np.float32) if "loadings" in z.files else np.zeros((0, components.shape[0]), np.float32)
    frame = z["faceframe"] if "faceframe" in z.files else None
    known = {"size", "n_components", "total_variance", "explained_variance_ratio", "faceframe"}
    return MorphModel(components=components, mean=z["mean"].astype(np.float32), variances=z["variances"].astype(float),
                      size=size, reference=z["reference"].astype(np.float32) / 255.0,
                      ref_positions=z["ref_positions"].astype(np.float32), loadings=loadings, faceframe=frame,
                      total_variance=float(meta.get("total_variance", 0.0)),
                      meta={k: v for k, v in meta.items() if k not in known},
                      ref_landmarks=z["ref_landmarks"] if "ref_landmarks" in z.files else None,
                      landmarks=z["landmarks"] if "landmarks" in z.files else None)
