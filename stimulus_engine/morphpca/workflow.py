"""The morph-model build as one workflow: validated inputs in, model files and metrics out.

``appeal stimuli morphpca build`` reads and checks its inputs with :func:`read_morph_inputs`
(every problem is a one-line error before an output folder exists) and calls
:func:`build_morph_model`, which writes ``model.npz``, ``mean.png`` and ``components.png`` and
returns the fit metrics (training and hold-out reconstruction PSNR/SSIM).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError

__all__ = ["MorphInputs", "read_morph_inputs", "build_morph_model"]


@dataclass
class MorphInputs:
    """The images of a morph model, read and checked.

    Attributes
    ----------
    files : list of Path
    images : list of (H, W, 3) arrays
        Registered to one size when asked.
    faceframes : (n, 3, 2) array or None
        Eye centres and philtrum per image.
    reference : int
        Index of the reference image (neutral, eyes open) among the training images.
    n_train : int
        Images used for the model; the rest are held out.
    seconds : float
        Time spent reading.
    """

    files: list[Path]
    images: list[np.ndarray]
    faceframes: np.ndarray | None
    reference: int
    n_train: int
    seconds: float = 0.0

    @property
    def names(self) -> list[str]:
        return [f.name for f in self.files]


def _faceframes(spec: str | None, files: list[Path], images: list[np.ndarray]) -> np.ndarray | None:
    """Faceframes for ``files``: a CSV path, 'tem' (templates beside the images) or 'detect'."""
    from stimulus_engine.morphpca.keypoints import detect_faceframe, faceframe_from_tem, read_keypoints_csv, read_tem

    if spec is None:
        return None
    if spec == "tem":
        return np.stack([faceframe_from_tem(read_tem(f.with_suffix(".tem")), f.with_suffix(".tem")) for f in files])
    if spec == "detect":
        return np.stack([detect_faceframe(img, str(f)) for f, img in zip(files, images)])
    return read_keypoints_csv(spec, files)


def read_morph_inputs(images: Sequence[str | Path], *, keypoints: str | None = None, register: bool = False,
                      size: str | None = None, reference: str = "0", holdout: int = 0) -> MorphInputs:
    """Read and check the images of a morph model.

    Parameters
    ----------
    images : sequence of path-like
        Image files or folders.
    keypoints : str, optional
        A keypoints CSV, ``"tem"`` (WebMorph templates beside the images) or ``"detect"`` (dlib).
    register : bool
        Similarity-align the faces on their eye centres (needs ``keypoints``).
    size : str, optional
        ``"HxW"``: resize (or, registering, crop) to this size.
    reference : str
        Index or file name of the reference image.
    holdout : int
        Leave the last ``holdout`` images out of the model.

    Raises
    ------
    AppealInputError
        One line naming the option and what was expected.
    """
    from stimulus_engine.morphpca.io import list_images, parse_size, read_images, register_faces

    t0 = time.perf_counter()
    files = list_images(images)
    if len(files) < 2:
        raise AppealInputError(f"IMAGES: a model needs at least 2 images (got {len(files)}"
                               f"{': ' + files[0].name if files else ''})")
    shape = parse_size(size) if size else None
    if register and keypoints is None:
        raise AppealInputError("--register: needs --keypoints FILE, 'tem' or 'detect' (the eye centres to align)")
    imgs = read_images(files, None if register else shape)
    frames = _faceframes(keypoints, files, imgs)
    if register:
        imgs, frames = register_faces(imgs, frames, shape or (240, 200))
    names = [f.name for f in files]
    ref = int(reference) if reference.isdigit() else (names.index(reference) if reference in names else -1)
    if not 0 <= ref < len(files):
        raise AppealInputError(f"--reference: expected an index 0..{len(files) - 1} or one of the image names (got {reference!r})")
    n_train = len(files) - holdout
    if n_train < 2:
        raise AppealInputError(f"--holdout: leaves {n_train} training image(s) (expected at least 2)")
    return MorphInputs(files, imgs, frames, min(ref, n_train - 1), n_train, time.perf_counter() - t0)


def build_morph_model(inputs: MorphInputs, out: Path, *, components: int | None = None, variance: float | None = None,
                      backend: str = "dis") -> tuple[object, dict]:
    """Build a PCA morph model and write ``model.npz``, ``mean.png`` and ``components.png`` into ``out``.

    Parameters
    ----------
    inputs : MorphInputs
        From :func:`read_morph_inputs`.
    out : Path
        An existing output folder.
    components, variance
        Components to keep, or the fraction of variance they must explain (default: all).
    backend : {"dis", "farneback"}
        Optical flow.

    Returns
    -------
    model : MorphModel
    metrics : dict
        n_images, n_components, explained variance (total and per component, first 20),
        train_psnr_db, train_ssim, hold-out PSNR/SSIM when images were held out, seconds.
    """
    from stimulus_engine.morphpca.io import save_image, save_model
    from stimulus_engine.morphpca.metrics import psnr, ssim
    from stimulus_engine.morphpca.mimicry import save_contact_sheet
    from stimulus_engine.morphpca.pca import build_model

    t0 = time.perf_counter()
    n = inputs.n_train
    imgs = inputs.images
    model = build_model(imgs[:n], n_components=components, variance=variance, reference_index=inputs.reference,
                        backend=backend, faceframes=None if inputs.faceframes is None else inputs.faceframes[:n],
                        names=inputs.names[:n])
    save_model(model, out / "model.npz")
    save_image(out / "mean.png", model.mean_image())
    sd = np.sqrt(model.variances[: min(4, model.n_components)])
    rows = []
    for j, s in enumerate(sd):
        lo = np.zeros((3, model.n_components), np.float32)
        lo[0, j], lo[2, j] = -2 * s, 2 * s
        rows.append(list(model.reconstruct(lo)))
    save_contact_sheet(out / "components.png", rows, [f"PC{j + 1}" for j in range(len(rows))], ["-2 SD", "mean", "+2 SD"])
    train_rec = model.reconstruct(model.loadings)
    metrics = {"n_images": n, "n_components": model.n_components,
               "explained_variance": float(model.explained_variance_ratio.sum()),
               "explained_variance_ratio": [float(v) for v in model.explained_variance_ratio[:20]],
               "train_psnr_db": float(np.mean([psnr(a, b) for a, b in zip(imgs[:n], train_rec)])),
               "train_ssim": float(np.mean([ssim(a, b) for a, b in zip(imgs[:n], train_rec)])),
               "seconds_build": model.meta["seconds_total"]}
    if n < len(imgs):
        test = imgs[n:]
        rec = model.reconstruct(model.project(model.encode(test)))
        metrics.update(holdout_psnr_db=float(np.mean([psnr(a, b) for a, b in zip(test, rec)])),
                       holdout_ssim=float(np.mean([ssim(a, b) for a, b in zip(test, rec)])))
    metrics["seconds"] = inputs.seconds + time.perf_counter() - t0
    return model, metrics
