"""PCA face models in morph space (Nagle et al. §2): build, encode, loadings.

A model holds the expression-space matrix ``P`` (here as rows: ``components``, ``(k, D)``), the
morph mean ``M_m``, the variance of every component, the image size, the reference image,
the inverse mean warp (to encode new images), the faceframe keypoints on the mean image and
the training loadings.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.morphpca.flow import grey_u8, grid, sample_field
from stimulus_engine.morphpca.landmark_warp import check_landmarks, reference_flow
from stimulus_engine.morphpca.morphvec import decompose, deserialise, encode_with_reference, serialise

__all__ = ["MorphModel", "pca", "pca_with_loadings", "gram", "build_model", "check_image_stack"]

FORMAT = "appeal-morphpca"
FORMAT_VERSION = 1


def gram(x: np.ndarray) -> np.ndarray:
    """The Gram matrix ``x xᵀ`` (float64) of rows ``(n, D)``, accumulated in float32 by BLAS ``ssyrk``.

    ``ssyrk`` on the transposed view needs no copy and is ~5× faster here than ``x @ x.T``
    (OpenBLAS handles GEMM with a tiny output and a huge inner dimension poorly).
    """
    from scipy.linalg.blas import ssyrk

    x = np.ascontiguousarray(x, np.float32)
    upper = ssyrk(1.0, x.T, trans=1).astype(np.float64)  # x.T is Fortran-ordered (D, n): x xᵀ, upper part
    return np.triu(upper) + np.triu(upper, 1).T


def pca_with_loadings(relative: np.ndarray, n_components: int | None = None, variance: float | None = None,
                      ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """:func:`pca` that also returns the rows' loadings ``(n, k)`` (from the Gram eigenvectors, no extra product)."""
    n = relative.shape[0]
    evals, evecs = np.linalg.eigh(gram(relative))
    order = np.argsort(evals)[::-1]
    evals, evecs = np.clip(evals[order], 0, None), evecs[:, order]
    total = float(evals.sum()) / max(n - 1, 1)
    rank = int(np.sum(evals > evals[0] * 1e-10)) if evals[0] > 0 else 0
    k = min(rank, n - 1)
    if variance is not None:
        frac = np.cumsum(evals) / max(evals.sum(), 1e-300)
        k = min(k, int(np.searchsorted(frac, variance - 1e-12) + 1))
    if n_components is not None:
        k = min(k, int(n_components))
    k = max(k, 1)
    sd = np.sqrt(np.maximum(evals[:k], 1e-300))
    u = evecs[:, :k] / sd
    components = u.T.astype(np.float32) @ np.asarray(relative, np.float32)
    # re-normalise in float32 precision and fix signs (largest |value| positive); row by row, so
    # no temporaries of the matrix's size
    signs = np.empty(k)
    for j, row in enumerate(components):
        hi, lo = int(np.argmax(row)), int(np.argmin(row))
        signs[j] = 1.0 if row[hi] >= -row[lo] else -1.0
        row *= np.float32(signs[j] / max(float(np.sqrt(np.dot(row, row))), 1e-30))
    loadings = (evecs[:, :k] * (sd * signs)).astype(np.float32)  # = relative @ components.T
    return components, evals[:k] / max(n - 1, 1), total, loadings


def pca(relative: np.ndarray, n_components: int | None = None, variance: float | None = None,
        ) -> tuple[np.ndarray, np.ndarray, float]:
    """PCA of mean-relative rows ``(n, D)`` with ``n ≪ D`` (eigen-decomposition of the Gram matrix).

    Parameters
    ----------
    relative : (n, D) float32
        Mean-subtracted morph vectors.
    n_components : int, optional
        Components to keep (at most ``n - 1``; default all).
    variance : float, optional
        Keep the fewest components explaining at least this fraction of the variance.

    Returns
    -------
    components : (k, D) float32, orthonormal rows
    variances : (k,) float64, the variance of each component (``eigenvalue / (n - 1)``)
    total_variance : float, summed variance of all dimensions
    """
    return pca_with_loadings(relative, n_components, variance)[:3]


def check_image_stack(images: Any, what: str = "images", min_images: int = 2) -> np.ndarray:
    """An ``(n, h, w, 3)`` float32 stack in [0, 1], or :class:`AppealInputError` saying what is wrong."""
    if isinstance(images, np.ndarray) and images.ndim == 4:
        arr = images
    else:
        seq = list(images)
        if len(seq) < min_images:
            raise AppealInputError(f"{what}: a model needs at least {min_images} images (got {len(seq)})")
        shapes = {np.shape(a) for a in seq}
        if len(shapes) > 1:
            first = np.shape(seq[0])
            bad = next(i for i, a in enumerate(seq) if np.shape(a) != first)
            raise AppealInputError(f"{what}[{bad}]: image shape {np.shape(seq[bad])} differs from image 0's "
                                   f"{first} (expected all images the same size and colour)")
        arr = np.stack(seq)
    if arr.shape[0] < min_images:
        raise AppealInputError(f"{what}: a model needs at least {min_images} images (got {arr.shape[0]})")
    if arr.ndim != 4 or arr.shape[-1] != 3:
        raise AppealInputError(f"{what}: expected colour images (n, h, w, 3) (got shape {arr.shape})")
    if arr.dtype == np.uint8:
        arr = arr.astype(np.float32) / 255.0
    return np.ascontiguousarray(arr, dtype=np.float32)


@dataclass
class MorphModel:
    """A PCA face model in morph space.

    Attributes
    ----------
    components : (k, D) float32
        Orthonormal rows; the paper's expression-space matrix ``P`` is ``components.T``.
    mean : (D,) float32
        The morph mean ``M_m``.
    variances : (k,) float64
        Variance of each component (for drawing realistic random faces).
    size : (h, w)
    reference : (h, w, 3) float32
        The reference image ``I_r`` new images are compared with.
    ref_positions : (h, w, 2) float32
        Inverse mean warp: for each mean-shape pixel, its position in the reference image.
    loadings : (n, k) float32
        The training images' loadings.
    faceframe : (3, 2) float64 or None
        Left eye centre, right eye centre and philtrum on the mean image (x, y).
    total_variance : float
    meta : dict
        Names of the training images, flow backend, timings, format version …
    ref_landmarks : (K, 2) float64 or None
        The keypoints of the reference image when the warps were landmark-guided: new images
        with the same K keypoints are encoded the same way (:meth:`encode`).
    landmarks : (K, 2) float64 or None
        Their average position on the mean image.
    """

    components: np.ndarray
    mean: np.ndarray
    variances: np.ndarray
    size: tuple[int, int]
    reference: np.ndarray
    ref_positions: np.ndarray
    loadings: np.ndarray
    faceframe: np.ndarray | None = None
    total_variance: float = 0.0
    meta: dict = field(default_factory=dict)
    ref_landmarks: np.ndarray | None = None
    landmarks: np.ndarray | None = None

    @property
    def n_components(self) -> int:
        return int(self.components.shape[0])

    @property
    def explained_variance_ratio(self) -> np.ndarray:
        return self.variances / self.total_variance if self.total_variance > 0 else np.zeros_like(self.variances)

    def encode(self, images: np.ndarray, landmarks: np.ndarray | None = None) -> np.ndarray:
        """Absolute morph vectors ``(n, D)`` of new images (flow from the reference).

        ``landmarks`` ``(n, K, 2)``: the images' keypoints (the model's K) for landmark-guided
        warps; a model built with landmarks encodes images without them by optical flow alone.
        """
        imgs = check_image_stack(images if np.ndim(images) == 4 else [images], "image", min_images=1)
        if imgs.shape[1:3] != tuple(self.size):
            raise AppealInputError(f"image: size {imgs.shape[1]}x{imgs.shape[2]} differs from the model's "
                                   f"{self.size[0]}x{self.size[1]} (expected images of the model's size)")
        if landmarks is not None:
            landmarks = np.asarray(landmarks, float).reshape(len(imgs), -1, 2)
            if self.ref_landmarks is None or landmarks.shape[1] != len(self.ref_landmarks):
                k = "none" if self.ref_landmarks is None else len(self.ref_landmarks)
                raise AppealInputError(f"landmarks: {landmarks.shape[1]} points per image, but the model was built "
                                       f"with {k} (expected the template the model was built with)")
        backend, levels = self.meta.get("backend", "dis"), int(self.meta.get("levels", 1))
        refine = bool(self.meta.get("landmark_refine", True))
        ref = grey_u8(self.reference)  # converted once for all images
        out = np.empty((len(imgs), self.mean.shape[0]), np.float32)
        for i, img in enumerate(imgs):
            flow = reference_flow(ref, img, self.ref_landmarks, None if landmarks is None else landmarks[i],
                                  backend=backend, levels=levels, refine=refine)
            out[i] = serialise(*encode_with_reference(img, ref, self.ref_positions, flow=flow))
        return out

    def relative(self, vectors: np.ndarray) -> np.ndarray:
        """Mean-relative morph vectors ``R = M - M_m``."""
        return np.atleast_2d(vectors).astype(np.float32) - self.mean

    def project(self, vectors: np.ndarray, fit: str = "orthogonal") -> np.ndarray:
        """Loadings ``(n, k)`` of absolute morph vectors.

        ``fit``: ``"orthogonal"`` (the paper's ``L = Pᵀ R``, nearest in morph space) or
        ``"image"`` (nearest as an image, :func:`~.fit.image_fit_loadings`: better for faces of
        people not in the model).
        """
        if fit == "image":
            from stimulus_engine.morphpca.fit import image_fit_loadings

            return image_fit_loadings(self, vectors)
        if fit != "orthogonal":
            raise AppealInputError(f"fit: expected 'orthogonal' or 'image' (got {fit!r})")
        return self.relative(vectors) @ self.components.T

    def vectors(self, loadings: np.ndarray) -> np.ndarray:
        """Absolute morph vectors from loadings (``M = P l + M_m``)."""
        lo = np.atleast_2d(np.asarray(loadings, np.float32))
        return lo @ self.components[: lo.shape[1]] + self.mean

    def mean_texture_warp(self) -> tuple[np.ndarray, np.ndarray]:
        return deserialise(self.mean, self.size)

    def mean_image(self) -> np.ndarray:
        """The morph mean image (the mean texture displaced by the mean warp)."""
        from stimulus_engine.morphpca.reconstruct import render_morph

        return render_morph(*self.mean_texture_warp())

    def reconstruct(self, loadings: np.ndarray) -> np.ndarray:
        """Images ``(n, h, w, 3)`` from loadings ``(n, k)``."""
        from stimulus_engine.morphpca.reconstruct import Reconstructor

        return Reconstructor(self, as_uint8=False)(np.atleast_2d(loadings))


def faceframe_on_mean(warps: np.ndarray, frames: np.ndarray, iterations: int = 12) -> np.ndarray:
    """Average position on the mean shape of per-image faceframe points ``(n, 3, 2)``.

    Each image's warp (mean-shape pixel → image position) is inverted only at its 3 points:
    the fixed point ``q = p - d(q)`` of the displacement ``d = warp - grid``.
    """
    g = grid(*warps.shape[1:3])
    pts = []
    for warp, fr in zip(warps, frames):
        d = warp - g
        p = np.asarray(fr, np.float32).reshape(1, -1, 2)
        q = p.copy()
        for _ in range(iterations):
            q = p - sample_field(d, q)
        pts.append(q.reshape(-1, 2).astype(np.float64))
    return np.mean(pts, axis=0)


def build_model(images: Any, *, n_components: int | None = None, variance: float | None = None,
                reference_index: int = 0, backend: str = "dis", levels: int = 1,
                faceframes: np.ndarray | None = None, names: Sequence[str] | None = None,
                weights: Sequence[float] | None = None, landmarks: np.ndarray | None = None,
                refine: bool = True) -> MorphModel:
    """Build a PCA morph model from aligned images of one face (or of many faces: a face space).

    Parameters
    ----------
    images : (n, h, w, 3) array or sequence of (h, w, 3) arrays, n ≥ 2
    n_components, variance : see :func:`pca` (the paper keeps 50–100 components)
    reference_index : int
        Which image is the reference ``I_r``.
    backend, levels : optical flow (see :func:`stimulus_engine.morphpca.flow.compute_flow`)
    faceframes : (n, 3, 2), optional
        Per-image eye centres and philtrum; their average position on the mean shape becomes
        the model's faceframe.
    names : sequence of str, optional
        Image names kept in the metadata.
    weights : sequence of float, optional
        Weights of the mean (default equal).
    landmarks : (n, K, 2), optional
        The same K keypoints in every image (a .tem template, the 68 detected points):
        landmark-guided warps (:mod:`~.landmark_warp`) instead of optical flow alone.
    refine : bool
        With landmarks: refine the landmark spline by optical flow inside the face (False:
        the spline alone, as Psychomorph).

    Returns
    -------
    MorphModel
    """
    t0 = time.perf_counter()
    imgs = check_image_stack(images)
    n, h, w = imgs.shape[:3]
    if not 0 <= reference_index < n:
        raise AppealInputError(f"reference: expected an image index 0..{n - 1} (got {reference_index})")
    if faceframes is not None and np.shape(faceframes) != (n, 3, 2):
        raise AppealInputError(f"keypoints: expected 3 points (left eye, right eye, philtrum) for each of the {n} "
                               f"images (got shape {np.shape(faceframes)})")
    if landmarks is not None:
        landmarks = np.asarray(landmarks, float)
        if landmarks.ndim != 3 or landmarks.shape[0] != n or landmarks.shape[2] != 2:
            raise AppealInputError(f"landmarks: expected the same K (x, y) points for each of the {n} images "
                                   f"(got shape {landmarks.shape})")
        for i, pts in enumerate(landmarks):
            check_landmarks(pts, (h, w), f"landmarks[{i}]" if names is None else f"{names[i]}: keypoints")
    ms = decompose(imgs, reference_index, backend, levels, weights=weights, landmarks=landmarks, refine=refine)
    t_flow = time.perf_counter() - t0
    rel = ms.vectors()
    wts = np.full(n, 1.0 / n) if weights is None else np.asarray(weights, float)
    mean = (wts.astype(np.float32) @ rel).astype(np.float32)
    rel -= mean  # in place: the absolute vectors are not needed any more
    components, variances, total, loadings = pca_with_loadings(rel, n_components, variance)
    frame = faceframe_on_mean(ms.warps, np.asarray(faceframes)) if faceframes is not None else None
    meta = {"format": FORMAT, "format_version": FORMAT_VERSION, "backend": backend, "levels": levels,
            "n_images": n, "reference_index": reference_index,
            "names": list(names) if names is not None else [f"image{i}" for i in range(n)],
            "seconds_flow": t_flow, "seconds_total": time.perf_counter() - t0}
    if landmarks is not None:
        meta.update(landmark_points=int(landmarks.shape[1]), landmark_refine=bool(refine))
    return MorphModel(components=components, mean=mean, variances=variances, size=(h, w), reference=imgs[reference_index],
                      ref_positions=ms.ref_positions, loadings=loadings, faceframe=frame,
                      total_variance=total, meta=meta,
                      ref_landmarks=None if landmarks is None else landmarks[reference_index],
                      landmarks=None if landmarks is None else faceframe_on_mean(ms.warps, landmarks))
