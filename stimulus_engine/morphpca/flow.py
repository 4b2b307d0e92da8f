"""Dense warp fields: multi-scale optical flow, warping, inversion and fold-over repair.

Conventions: images are float32 ``(h, w, 3)`` (or ``(h, w)``) arrays; a *displacement field*
``d`` is float32 ``(h, w, 2)`` holding (dx, dy) in pixels; an *absolute* field holds the
positions ``grid + d``. The flow ``f`` from a reference ``R`` to an image ``I`` says where each
reference pixel went: ``R(x) ≈ I(x + f(x))`` (OpenCV's convention with ``prev=R``).

The paper's McGM (multi-channel gradient model) is not available as open software; the
gradient-based, coarse-to-fine DIS (default) and Farnebäck flows of OpenCV stand in for it.
"""

from __future__ import annotations

import threading

import cv2
import numpy as np

from stimulus_engine.geometry.sampling import sample_bilinear

__all__ = ["FLOW_BACKENDS", "DIS_SETTINGS", "compute_flow", "grey_u8", "grid", "warp_image", "sample_field",
           "invert_displacement", "jacobian_det", "fix_foldovers"]

FLOW_BACKENDS = ("dis", "farneback")

#: DIS settings. ``finest_scale=1`` stops the patch search at half resolution; the variational
#: refinement and the upsampling to full size follow. On the benchmark faces (240×200) this is
#: ~4× faster than searching at full resolution and gives *higher* held-out PSNR (39.7 vs 37.5 dB
#: mean at 100 components) with projection SSIM 0.970 vs 0.972 — the flows are smoother.
DIS_SETTINGS = {"finest_scale": 1, "patch_size": 8, "patch_stride": 3, "gradient_descent_iterations": 25,
                "variational_refinement_iterations": 10, "variational_refinement_alpha": 20.0}

_local = threading.local()  # one DIS object per thread, reused (keeps its buffers between calls)


def grid(h: int, w: int) -> np.ndarray:
    """The identity absolute field: ``(h, w, 2)`` float32 with ``[..., 0] = x``, ``[..., 1] = y``."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    return np.dstack([x, y])


def grey_u8(img: np.ndarray) -> np.ndarray:
    """8-bit greyscale (Rec. 601 luma) of a float image in [0, 1]; a uint8 grey image is returned as is.

    Convert a reference once and pass the result to :func:`compute_flow` for many flows.
    """
    if img.dtype == np.uint8 and img.ndim == 2:
        return img
    img = np.asarray(img, np.float32)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    return np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)


def _dis() -> cv2.DISOpticalFlow:
    dis = getattr(_local, "dis", None)
    if dis is None:
        s = DIS_SETTINGS
        dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
        dis.setFinestScale(s["finest_scale"])
        dis.setPatchSize(s["patch_size"])
        dis.setPatchStride(s["patch_stride"])
        dis.setGradientDescentIterations(s["gradient_descent_iterations"])
        dis.setVariationalRefinementIterations(s["variational_refinement_iterations"])
        dis.setVariationalRefinementAlpha(s["variational_refinement_alpha"])
        dis.setUseSpatialPropagation(True)
        _local.dis = dis
    return dis


def _flow_one_level(a: np.ndarray, b: np.ndarray, init: np.ndarray | None, backend: str) -> np.ndarray:
    if backend == "dis":
        dis = _dis()
        # DIS builds its own pyramid; an initial flow (the coarser level) is refined in place
        flow = init.copy() if init is not None else None
        return dis.calc(a, b, flow)
    flags = cv2.OPTFLOW_USE_INITIAL_FLOW if init is not None else 0
    flow = init.copy() if init is not None else np.zeros(a.shape + (2,), np.float32)
    return cv2.calcOpticalFlowFarneback(a, b, flow, pyr_scale=0.5, levels=3, winsize=13, iterations=5,
                                        poly_n=5, poly_sigma=1.1, flags=flags)


def compute_flow(reference: np.ndarray, image: np.ndarray, backend: str = "dis", levels: int = 1,
                 smooth: float = 1.0) -> np.ndarray:
    """Dense flow from ``reference`` to ``image`` on greyscale pyramids, combined at full size.

    Both backends work coarse-to-fine on a greyscale pyramid themselves (DIS: patch search
    from an automatically chosen coarsest scale down to half resolution (:data:`DIS_SETTINGS`),
    then variational refinement and upsampling to full size; Farnebäck: 3 levels at scale 0.5), so the result is one full-resolution field
    holding the large motions of the coarse levels and the detail of the fine ones. ``levels > 1``
    adds an outer pyramid: the images are subsampled by 2 ``levels - 1`` times and each level's
    flow, upsampled, initialises the next.

    Parameters
    ----------
    reference, image : ndarray
        Same-sized float images in [0, 1] (colour or grey), or their :func:`grey_u8`.
    backend : {"dis", "farneback"}
        OpenCV's DIS (dense inverse search with variational refinement) or Farnebäck flow.
    levels : int
        Outer pyramid levels (1 = only the backend's own pyramid).
    smooth : float
        Gaussian sigma (pixels) applied to the final field; 0 disables.

    Returns
    -------
    ndarray, float32, (h, w, 2)
        Displacement ``f`` with ``reference(x) ≈ image(x + f(x))``.
    """
    if backend not in FLOW_BACKENDS:
        raise ValueError(f"backend: expected one of {', '.join(FLOW_BACKENDS)} (got {backend!r})")
    a0, b0 = grey_u8(reference), grey_u8(image)
    h, w = a0.shape
    flow = None
    for lvl in range(max(1, levels) - 1, -1, -1):
        f = 2**lvl
        size = (max(8, round(w / f)), max(8, round(h / f)))
        a = cv2.resize(a0, size, interpolation=cv2.INTER_AREA) if f > 1 else a0
        b = cv2.resize(b0, size, interpolation=cv2.INTER_AREA) if f > 1 else b0
        init = None
        if flow is not None:
            sx, sy = size[0] / flow.shape[1], size[1] / flow.shape[0]
            init = cv2.resize(flow, size, interpolation=cv2.INTER_LINEAR)
            init[..., 0] *= sx
            init[..., 1] *= sy
        flow = _flow_one_level(a, b, init, backend)
    if smooth > 0:
        flow = cv2.GaussianBlur(flow, (0, 0), smooth)
    return fix_foldovers(flow.astype(np.float32))


def warp_image(image: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Sample ``image`` at absolute ``positions`` (``out(p) = image(positions(p))``), bilinearly
    (:func:`stimulus_engine.geometry.sampling.sample_bilinear`).

    Backward mapping: every output pixel gets a value, so there are no holes; outside the
    image the border is replicated.
    """
    return sample_bilinear(image, positions)


def sample_field(field: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Bilinearly sample a 2-channel field at absolute ``positions`` (border replicated)."""
    return sample_bilinear(field, positions)


def invert_displacement(d: np.ndarray, iterations: int = 12, base: np.ndarray | None = None,
                        buffers: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The inverse ``e`` of a fold-free displacement ``d``: ``x + d(x) = p  ⇔  x = p + e(p)``.

    Fixed-point iteration ``e ← -d(p + e)`` (converges where the warp does not fold).
    ``buffers``: three optional ``(h, w, 2)`` float32 work arrays (``-d``, ``e``, positions) so
    that repeated calls allocate nothing; the result is the second one.
    """
    g = grid(*d.shape[:2]) if base is None else base
    if buffers is None:
        buffers = (np.empty(d.shape, np.float32), np.empty(d.shape, np.float32), np.empty(d.shape, np.float32))
    neg, e, pos = buffers
    np.negative(d, out=neg, casting="same_kind")
    e[...] = neg
    for _ in range(iterations):
        np.add(g, e, out=pos)
        e = sample_bilinear(neg, pos, out=e)
    return e


def _gradients(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.gradient`` along y and x of an ``(h, w, …)`` float32 array (central inside, one-sided at edges)."""
    gy, gx = np.empty_like(f), np.empty_like(f)
    np.subtract(f[2:], f[:-2], out=gy[1:-1])
    gy[1:-1] *= 0.5
    np.subtract(f[1], f[0], out=gy[0])
    np.subtract(f[-1], f[-2], out=gy[-1])
    np.subtract(f[:, 2:], f[:, :-2], out=gx[:, 1:-1])
    gx[:, 1:-1] *= 0.5
    np.subtract(f[:, 1], f[:, 0], out=gx[:, 0])
    np.subtract(f[:, -1], f[:, -2], out=gx[:, -1])
    return gy, gx


def jacobian_det(d: np.ndarray) -> np.ndarray:
    """Determinant of the Jacobian of ``x ↦ x + d(x)`` per pixel (≤ 0 where the warp folds over)."""
    d = np.asarray(d)
    if d.shape[0] < 2 or d.shape[1] < 2:
        dxdy, dxdx = np.gradient(d[..., 0])
        dydy, dydx = np.gradient(d[..., 1])
        return (1.0 + dxdx) * (1.0 + dydy) - dxdy * dydx
    gy, gx = _gradients(np.asarray(d, np.float32))
    gx[..., 0] += 1.0  # 1 + d(dx)/dx
    gy[..., 1] += 1.0  # 1 + d(dy)/dy
    det = gx[..., 0] * gy[..., 1]
    det -= gy[..., 0] * gx[..., 1]
    return det


def fix_foldovers(d: np.ndarray, min_det: float = 0.1, max_iterations: int = 30) -> np.ndarray:
    """Smooth a displacement field locally until its warp no longer folds over.

    Where the Jacobian determinant drops below ``min_det`` the field is blended with a
    Gaussian-smoothed copy (the region grows each round); if that does not suffice the whole
    field is shrunk towards zero, which always ends fold-free.
    """
    d = np.ascontiguousarray(d, dtype=np.float32)
    for it in range(max_iterations):
        det = jacobian_det(d)
        bad = det < min_det
        if not bad.any():
            return d
        sigma = 1.5 + 0.5 * it
        mask = cv2.GaussianBlur(cv2.dilate(bad.astype(np.float32), np.ones((5, 5), np.uint8)), (0, 0), sigma)
        mask = np.clip(mask * 3.0, 0, 1)[..., None]
        d = d * (1 - mask) + cv2.GaussianBlur(d, (0, 0), sigma) * mask
    for _ in range(20):
        if jacobian_det(d).min() >= min_det:
            break
        d = d * 0.8
    return d.astype(np.float32)
