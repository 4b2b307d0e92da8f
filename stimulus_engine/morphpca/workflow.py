"""The morph-model workflows: checked inputs in, files and metrics out.

Each ``appeal stimuli morphpca`` command reads and checks its inputs first (every problem is a
one-line error before an output folder exists) and calls one function here:

=============  ===============================  =======================
command        inputs                           workflow
=============  ===============================  =======================
build          :func:`read_morph_inputs`        :func:`build_morph_model`
pair           two photographs                  :func:`pair_expression_model`
project        :func:`read_projection_inputs`   :func:`project_images`
avatar         :func:`~.io.load_model` each     :func:`build_avatar_model`
reconstruct    :func:`read_loadings`            :func:`reconstruct_faces`
=============  ===============================  =======================

:func:`build_morph_model` writes ``model.npz``, ``mean.png`` and ``components.png`` and returns
the fit metrics (training and hold-out reconstruction PSNR/SSIM).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.morphpca.defaults import DEFAULT_TEXTURE_WEIGHT

__all__ = ["MorphInputs", "WARP_METHODS", "read_keypoints", "read_morph_inputs", "build_morph_model", "ProjectionInputs",
           "read_projection_inputs", "project_images", "build_avatar_model", "read_loadings", "reconstruct_faces",
           "PairModel", "pair_expression_model"]


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
    landmarks : (n, K, 2) array or None
        All keypoints per image (a .tem template, the 68 detected points, or the CSV's
        ``pK_x/pK_y`` columns): the warps are then landmark-guided.
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
    landmarks: np.ndarray | None = None

    @property
    def names(self) -> list[str]:
        return [f.name for f in self.files]


def read_keypoints(spec: str | None, files: list[Path], images: list[np.ndarray],
                   ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Faceframes ``(n, 3, 2)`` and dense landmarks ``(n, K, 2)`` (or None) for ``files``.

    ``spec``: a CSV path (faceframes; landmarks from its optional ``pK_x/pK_y`` columns), 'tem'
    (the 189-point templates beside the images) or 'detect' (dlib's 68 points). Every image must
    have the same template, and its points must lie on that image (one-line errors otherwise).
    """
    from stimulus_engine.morphpca.keypoints import (
        detect_landmarks,
        faceframe_from_68,
        faceframe_from_tem,
        read_keypoints_csv,
        read_landmarks_csv,
        read_tem,
    )
    from stimulus_engine.morphpca.landmark_warp import check_landmarks

    if spec is None:
        return None, None
    if spec == "tem":
        sources = [f.with_suffix(".tem") for f in files]
        points = [read_tem(t) for t in sources]
        frames = np.stack([faceframe_from_tem(p, t) for p, t in zip(points, sources)])
    elif spec == "detect":
        sources = files
        points = [detect_landmarks(img, str(f)) for f, img in zip(files, images)]
        frames = np.stack([faceframe_from_68(p) for p in points])
    else:
        frames = read_keypoints_csv(spec, files)
        dense = read_landmarks_csv(spec, files)
        if dense is None:
            return frames, None
        sources, points = [Path(spec)] * len(files), list(dense)
    for src, p, img in zip(sources, points, images):
        if len(p) != len(points[0]):
            raise AppealInputError(f"{src}: {len(p)} points where {sources[0].name} has {len(points[0])} "
                                   "(expected the same template for every image)")
        check_landmarks(p, np.shape(img)[:2], f"{src}", margin=0.1)
    return frames, np.stack(points)


def read_morph_inputs(images: Sequence[str | Path], *, keypoints: str | None = None, register: bool = False,
                      size: str | None = None, reference: str = "0", holdout: int = 0,
                      holdout_every: int = 0) -> MorphInputs:
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
    holdout_every : int
        Leave every ``holdout_every``-th image out instead (the 5th, 10th, … for 5: a fifth,
        spread over the set); they are moved to the end, so ``files[n_train:]`` are the held out.

    Raises
    ------
    AppealInputError
        One line naming the option and what was expected.
    """
    from stimulus_engine.morphpca.io import list_images, parse_size, read_images, register_faces

    t0 = time.perf_counter()
    files = list_images(images)
    if holdout_every:
        if holdout:
            raise AppealInputError("--holdout-every: give either --holdout N (the last N) or --holdout-every K, not both")
        if holdout_every < 2:
            raise AppealInputError(f"--holdout-every: expected 2 or more (got {holdout_every})")
        held = files[holdout_every - 1::holdout_every]
        files = [f for i, f in enumerate(files) if (i + 1) % holdout_every] + held
        holdout = len(held)
    if len(files) < 2:
        raise AppealInputError(f"IMAGES: a model needs at least 2 images (got {len(files)}"
                               f"{': ' + files[0].name if files else ''})")
    shape = parse_size(size) if size else None
    if register and keypoints is None:
        raise AppealInputError("--register: needs --keypoints FILE, 'tem' or 'detect' (the eye centres to align)")
    imgs = read_images(files, None if register else shape)
    frames, landmarks = read_keypoints(keypoints, files, imgs)
    if register:
        if landmarks is None:
            imgs, frames = register_faces(imgs, frames, shape or (240, 200))
        else:
            imgs, frames, landmarks = register_faces(imgs, frames, shape or (240, 200), points=landmarks)
    elif landmarks is not None and shape is not None:
        raise AppealInputError("--size: resizing without --register would move the keypoints off the faces "
                               "(give --register, or images of one size)")
    names = [f.name for f in files]
    ref = int(reference) if reference.isdigit() else (names.index(reference) if reference in names else -1)
    if not 0 <= ref < len(files):
        raise AppealInputError(f"--reference: expected an index 0..{len(files) - 1} or one of the image names (got {reference!r})")
    n_train = len(files) - holdout
    if n_train < 2:
        raise AppealInputError(f"--holdout: leaves {n_train} training image(s) (expected at least 2)")
    return MorphInputs(files, imgs, frames, min(ref, n_train - 1), n_train, time.perf_counter() - t0, landmarks)


WARP_METHODS = ("guided", "flow", "landmarks")


def build_morph_model(inputs: MorphInputs, out: Path, *, components: int | None = None, variance: float | None = None,
                      backend: str = "dis", warp: str = "guided") -> tuple[object, dict]:
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
    warp : {"guided", "flow", "landmarks"}
        With dense landmarks (``inputs.landmarks``): a landmark spline refined by optical flow
        (default), optical flow alone, or the spline alone (Psychomorph-style). Without
        landmarks the warps are optical flow.

    Returns
    -------
    model : MorphModel
    metrics : dict
        n_images, n_components, explained variance (total and per component, first 20),
        train_psnr_db, train_ssim, seconds and, when images were held out, their PSNR/SSIM with
        loadings fitted as images (``holdout_psnr_db``, ``holdout_ssim``; :func:`~.fit.image_fit_loadings`)
        and the PSNR with the orthogonal projection (``holdout_psnr_projection_db``).
    """
    from stimulus_engine.morphpca.io import save_image, save_model
    from stimulus_engine.morphpca.metrics import psnr, ssim
    from stimulus_engine.morphpca.mimicry import save_contact_sheet
    from stimulus_engine.morphpca.pca import build_model

    if warp not in WARP_METHODS:
        raise AppealInputError(f"--warp: expected one of {', '.join(WARP_METHODS)} (got {warp!r})")
    t0 = time.perf_counter()
    n = inputs.n_train
    imgs = inputs.images
    lm = None if warp == "flow" else inputs.landmarks
    model = build_model(imgs[:n], n_components=components, variance=variance, reference_index=inputs.reference,
                        backend=backend, faceframes=None if inputs.faceframes is None else inputs.faceframes[:n],
                        names=inputs.names[:n], landmarks=None if lm is None else lm[:n], refine=warp == "guided")
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
               "train_psnr_db": _mean_scores(imgs[:n], train_rec, psnr),
               "train_ssim": _mean_scores(imgs[:n], train_rec, ssim),
               "warp": warp if lm is not None else "flow",
               "seconds_build": model.meta["seconds_total"]}
    if n < len(imgs):
        test = imgs[n:]
        enc = model.encode(test, None if lm is None else lm[n:])
        rec = model.reconstruct(model.project(enc, fit="image"))
        orth = model.reconstruct(model.project(enc))
        metrics.update(holdout_psnr_db=_mean_scores(test, rec, psnr), holdout_ssim=_mean_scores(test, rec, ssim),
                       holdout_psnr_projection_db=_mean_scores(test, orth, psnr))
    metrics["seconds"] = inputs.seconds + time.perf_counter() - t0
    return model, metrics


def _mean_scores(images, truth, score) -> float:
    return float(np.mean([score(a, b) for a, b in zip(images, truth)]))


@dataclass
class ProjectionInputs:
    """Images of person A, the two models and, optionally, the true images in B.

    Attributes
    ----------
    files : list of Path
        The files read: frame images, or video files (:func:`~.frame_source.read_frames`).
    images : (n, H, W, 3) array
        At model A's size.
    source, target : MorphModel
        Models A and B.
    truth : (n, H, W, 3) array or None
        One true image per input image, at model B's size.
    seconds : float
        Time spent reading.
    landmarks : (n, K, 2) array or None
        The images' keypoints (for a source model built with landmark-guided warps).
    names : list of str or None
        One per image (default: the files' names).
    """

    files: list[Path]
    images: np.ndarray
    source: object
    target: object
    truth: np.ndarray | None
    seconds: float = 0.0
    landmarks: np.ndarray | None = None
    names: list[str] | None = None

    @property
    def image_names(self) -> list[str]:
        """One name per image: ``names``, else the files' names."""
        return self.names if self.names is not None else [f.name for f in self.files]


def read_projection_inputs(images: Sequence[str | Path], source: str | Path, target: str | Path,
                           truth: Sequence[str | Path] = (), keypoints: str | None = None) -> ProjectionInputs:
    """Read and check the inputs of an expression projection (``--truth``: one image per input;
    ``keypoints``: a CSV with the images' landmarks, for a source model built with them). Without
    keypoints the images may be video files too (:func:`~.frame_source.read_frames`)."""
    from stimulus_engine.morphpca.frame_source import read_frames
    from stimulus_engine.morphpca.io import list_images, load_model, read_images

    t0 = time.perf_counter()
    ma, mb = load_model(source), load_model(target)
    landmarks = names = None
    if keypoints is None:
        frames = read_frames([p for p in images if Path(p).suffix.lower() != ".csv"], ma.size, "IMAGES")
        files, names, imgs = frames.sources, frames.names, frames.images
    else:
        files = [f for f in list_images(images) if f.suffix.lower() != ".csv"]
        imgs = read_images(files)
        if imgs.shape[1:3] != tuple(ma.size):
            raise AppealInputError(f"--keypoints: the images are {imgs.shape[1]}x{imgs.shape[2]}, model A "
                                   f"{ma.size[0]}x{ma.size[1]} (expected images of the model's size, so that the "
                                   "keypoints stay on them)")
        landmarks = read_keypoints(keypoints, files, list(imgs))[1]
        if landmarks is None:
            raise AppealInputError(f"{keypoints}: no landmark columns p0_x, p0_y, … (expected the model's "
                                   "keypoints, e.g. frames/keypoints.csv written by 'appeal stimuli morphpca pair')")
    truth_imgs = None
    if truth:
        truth_imgs = read_frames(truth, mb.size, "--truth").images
        if len(truth_imgs) != len(imgs):
            raise AppealInputError(f"--truth: expected one true image per input image ({len(imgs)}), "
                                   f"got {len(truth_imgs)}")
    return ProjectionInputs(files, imgs, ma, mb, truth_imgs, time.perf_counter() - t0, landmarks, names)


def project_images(inputs: ProjectionInputs, out: Path, *, align: bool = True, caricature: float = 1.0,
                   texture_weight: float = DEFAULT_TEXTURE_WEIGHT, naive: bool = False) -> dict:
    """Project the expressions of A's images onto B's face; write ``projected/NAME.png``,
    ``loadings.csv`` (loadings in B), ``sheet.png`` (inputs beside projections) and, with
    ``naive``, ``naive/NAME.png``.

    Parameters
    ----------
    inputs : ProjectionInputs
        From :func:`read_projection_inputs`.
    out : Path
        An existing output folder.
    align : bool
        Faceframe affine transform between the models (False: models of equal size only).
    caricature : float
        Scale of the projected warp.
    texture_weight : float
        Weight of texture against shape in the projection.
    naive : bool
        Also write the naive loading-transfer baseline.

    Returns
    -------
    dict
        n_images, seconds and, with true images, SSIM and PSNR of projection and naive baseline.
    """
    import pandas as pd

    from stimulus_engine.morphpca.io import save_image
    from stimulus_engine.morphpca.metrics import psnr, ssim
    from stimulus_engine.morphpca.project import naive_transfer, project_expression

    t0 = time.perf_counter()
    names, imgs, truth = inputs.image_names, inputs.images, inputs.truth
    res = project_expression(imgs, inputs.source, inputs.target, align=align, warp_factor=caricature,
                             texture_weight=texture_weight, landmarks=inputs.landmarks)
    for name in ("projected", "naive") if naive else ("projected",):
        (out / name).mkdir(parents=True, exist_ok=True)
    for name, img in zip(names, res.images):
        save_image(out / "projected" / (Path(name).stem + ".png"), img)
    pd.DataFrame(res.loadings, columns=[f"pc{j + 1}" for j in range(res.loadings.shape[1])]).assign(
        image=names).to_csv(out / "loadings.csv", index=False)
    metrics: dict = {"n_images": len(names)}
    base = naive_transfer(imgs, inputs.source, inputs.target) if naive or truth is not None else None
    if base is not None and naive:
        for name, img in zip(names, base.images):
            save_image(out / "naive" / (Path(name).stem + ".png"), img)
    if truth is not None:
        metrics.update(ssim_projection=_mean_scores(res.images, truth, ssim),
                       ssim_naive=_mean_scores(base.images, truth, ssim),
                       psnr_projection_db=_mean_scores(res.images, truth, psnr),
                       psnr_naive_db=_mean_scores(base.images, truth, psnr))
    _projection_sheet(out / "sheet.png", imgs, res.images, None if base is None or not naive else base.images, truth)
    metrics["seconds"] = inputs.seconds + time.perf_counter() - t0
    return metrics


def _projection_sheet(path: Path, source, projected, naive, truth, max_rows: int = 8) -> None:
    """A contact sheet: up to ``max_rows`` inputs (evenly spread) beside their projections (and baseline, truth)."""
    from stimulus_engine.morphpca.mimicry import save_contact_sheet

    rows_at = np.linspace(0, len(source) - 1, min(max_rows, len(source))).round().astype(int)
    cols = [("source (A)", source), ("projected on B", projected), ("naive transfer", naive), ("B's true image", truth)]
    cols = [(name, imgs) for name, imgs in cols if imgs is not None]
    save_contact_sheet(path, [[imgs[j] for _, imgs in cols] for j in rows_at], [f"#{j}" for j in rows_at],
                       [name for name, _ in cols])


def build_avatar_model(models: Sequence, out: Path, *, reference: int = 0, weights: Sequence[float] | None = None,
                       components: int | None = None, texture_weight: float = DEFAULT_TEXTURE_WEIGHT) -> tuple[object, dict]:
    """Blend identity models into an avatar model; write ``model.npz``, ``mean.png``,
    ``frames/frameNNN.png`` and ``blend.png`` (projections and blends side by side).

    Parameters
    ----------
    models : sequence of MorphModel
        The identities (:func:`stimulus_engine.morphpca.io.load_model`).
    out : Path
        An existing output folder.
    reference : int
        The model whose faceframe the avatar uses.
    weights : sequence of float, optional
        Identity weights (default equal).
    components : int, optional
        Components of the avatar model.
    texture_weight : float
        Weight of texture against shape in the projections.

    Returns
    -------
    avatar : Avatar
    metrics : dict
        identities, frames, n_components, explained_variance, weights, seconds.
    """
    from stimulus_engine.morphpca.avatar import build_avatar
    from stimulus_engine.morphpca.io import save_image, save_model
    from stimulus_engine.morphpca.mimicry import save_contact_sheet

    t0 = time.perf_counter()
    av = build_avatar(list(models), reference_model=reference, weights=weights, n_components=components,
                      texture_weight=texture_weight)
    save_model(av.model, out / "model.npz")
    save_image(out / "mean.png", av.model.mean_image())
    (out / "frames").mkdir(exist_ok=True)
    for j, fr in enumerate(av.frames):
        save_image(out / "frames" / f"frame{j:03d}.png", fr)
    show = np.linspace(0, len(av.frames) - 1, min(8, len(av.frames))).round().astype(int)
    save_contact_sheet(out / "blend.png", [list(av.projections[j]) + [av.frames[j]] for j in show],
                       [f"expr {j}" for j in show], [f"id {i}" for i in range(len(models))] + ["blend"])
    metrics = {"identities": len(models), "frames": len(av.frames), "n_components": av.model.n_components,
               "explained_variance": float(av.model.explained_variance_ratio.sum()),
               "weights": [float(v) for v in av.weights], "seconds": time.perf_counter() - t0}
    return av, metrics


def read_loadings(path: Path, n_components: int) -> tuple[np.ndarray, list[str]]:
    """Read a loadings CSV: one row per face, columns pc1..pcK (missing ones are zeros), an
    optional ``image`` column naming the outputs.

    Returns
    -------
    loadings : (n, n_components) float32 array
    names : list of str
        Output names (the ``image`` column's stems, else face0000, face0001, ...).
    """
    import pandas as pd

    if not path.is_file():
        raise AppealInputError(f"{path}: loadings file not found")
    df = pd.read_csv(path)
    cols = [c for c in df.columns if c.lower().startswith("pc") and c[2:].isdigit()]
    if not cols:
        raise AppealInputError(f"{path}: no pc1..pcK columns (expected one column per component, e.g. pc1,pc2)")
    cols.sort(key=lambda c: int(c[2:]))
    if int(cols[-1][2:]) > n_components:
        raise AppealInputError(f"{path}: {cols[-1]}: the model has only {n_components} components")
    lo = np.zeros((len(df), n_components), np.float32)
    vals = df[cols].apply(pd.to_numeric, errors="coerce").to_numpy(np.float32)
    if not np.all(np.isfinite(vals)):
        raise AppealInputError(f"{path}: non-numeric or missing loadings (expected numbers in every pc column)")
    for c, v in zip(cols, vals.T):
        lo[:, int(c[2:]) - 1] = v
    names = [Path(str(n)).stem for n in df["image"]] if "image" in df.columns else [f"face{i:04d}" for i in range(len(df))]
    return lo, names


def reconstruct_faces(model, loadings: np.ndarray, names: Sequence[str], out: Path) -> dict:
    """Render one face per row of ``loadings`` into ``out/NAME.png``.

    Returns
    -------
    dict
        faces, seconds_reconstruct, faces_per_second.
    """
    from stimulus_engine.morphpca.io import save_image
    from stimulus_engine.morphpca.reconstruct import Reconstructor

    t0 = time.perf_counter()
    imgs = Reconstructor(model)(loadings)
    dt = time.perf_counter() - t0
    for name, img in zip(names, imgs):
        save_image(out / (name + ".png"), img)
    return {"faces": len(names), "seconds_reconstruct": dt, "faces_per_second": len(names) / max(dt, 1e-9)}


class PairModel(NamedTuple):
    """A person's expression space from two photographs (:func:`pair_expression_model`).

    Attributes
    ----------
    model : MorphModel
        Reference = the neutral photo; faceframe and landmarks on the mean.
    frames : (n_frames, h, w, 3)
        The morph sequence the model was built from.
    photos : (2, h, w, 3)
        The two registered photographs (the expressive one is the last frame's truth).
    points : (n_frames, 68, 2)
        The landmarks of every frame (to encode them as the model's training images).
    """

    model: object
    frames: np.ndarray
    photos: np.ndarray
    points: np.ndarray


def pair_expression_model(neutral: str | Path, expressive: str | Path, out: Path | None = None, *,
                          size: tuple[int, int] = (240, 200), n_frames: int = 10, backend: str = "dis",
                          ) -> PairModel:
    """A person's expression space from a neutral and an expressive photograph.

    Both photos get dlib's 68 landmarks, are similarity-registered on the eyes to ``size``, and
    a morph sequence between them (:func:`~.morph_video.morph_sequence`, ``n_frames``) stands in
    for the video frames of Nagle et al.; the model is built from the frames with
    landmark-guided warps (the frames' landmarks are known exactly). With ``out`` the model,
    its mean, the frames and their keypoints (``frames/keypoints.csv``, the CSV format
    ``--keypoints`` reads, with the 68 points as ``pK_x/pK_y``) are written there.
    """
    from stimulus_engine.morphpca.io import read_images, register_faces, save_image, save_model
    from stimulus_engine.morphpca.keypoints import faceframe_from_68, write_keypoints_csv
    from stimulus_engine.morphpca.morph_video import morph_sequence
    from stimulus_engine.morphpca.pca import build_model

    files = [Path(neutral), Path(expressive)]
    imgs = read_images(files)
    boxes, lms = read_keypoints("detect", files, list(imgs))
    photos, _, pts = register_faces(imgs, boxes, size, points=lms)
    frames, frame_pts = morph_sequence(photos[0], pts[0], photos[1], pts[1], n_frames)
    frame_boxes = np.stack([faceframe_from_68(p) for p in frame_pts])
    model = build_model(frames, faceframes=frame_boxes, backend=backend, landmarks=frame_pts,
                        names=[f"{files[0].stem}-{files[1].stem}-{k:02d}" for k in range(n_frames)])
    if out is not None:
        save_model(model, out / "model.npz")
        save_image(out / "mean.png", model.mean_image())
        (out / "frames").mkdir(exist_ok=True)
        names = [out / "frames" / f"frame{k:03d}.png" for k in range(n_frames)]
        for name, fr in zip(names, frames):
            save_image(name, fr)
        write_keypoints_csv(out / "frames" / "keypoints.csv", names, frame_boxes, frame_pts)
    return PairModel(model, frames, photos, frame_pts)
