"""Dense warp fields: multi-scale optical flow, warping, inversion and fold-over repair.

Conventions: images are float32 ``(h, w, 3)`` (or ``(h, w)``) arrays; a *displacement field*
``d`` is float32 ``(h, w, 2)`` holding (dx, dy) in pixels; an *absolute* field holds the
positions ``grid + d``. The flow ``f`` from a reference ``R`` to an image ``I`` says where each
reference pixel went: ``R(x) ≈ I(x + f(x))`` (OpenCV's convention with ``prev=R``).

The paper's McGM (multi-channel gradient model) is not available as open software; the
gradient-based, coarse-to-fine DIS (default) and Farnebäck flows of OpenCV stand in for it.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["FLOW_BACKENDS", "compute_flow", "grid", "warp_image", "sample_field", "invert_displacement",
           "jacobian_det", "fix_foldovers"]

FLOW_BACKENDS = ("dis", "farneback")


def grid(h: int, w: int) -> np.ndarray:
    """The identity absolute field: ``(h, w, 2)`` float32 with ``[..., 0] = x``, ``[..., 1] = y``."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    return np.dstack([x, y])


def _grey_u8(img: np.ndarray) -> np.ndarray:
    if img.ndim == 3:
        img = img @ np.array([0.299, 0.587, 0.114], np.float32)
    return np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)


def _flow_one_level(a: np.ndarray, b: np.ndarray, init: np.ndarray | None, backend: str) -> np.ndarray:
    if backend == "dis":
        dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
        dis.setFinestScale(0)
        dis.setPatchSize(8)
        dis.setPatchStride(3)
        dis.setGradientDescentIterations(25)
        dis.setVariationalRefinementIterations(10)
        dis.setVariationalRefinementAlpha(20.0)
        dis.setUseSpatialPropagation(True)
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
    from an automatically chosen coarsest scale down to full resolution, then variational
    refinement; Farnebäck: 3 levels at scale 0.5), so the result is one full-resolution field
    holding the large motions of the coarse levels and the detail of the fine ones. ``levels > 1``
    adds an outer pyramid: the images are subsampled by 2 ``levels - 1`` times and each level's
    flow, upsampled, initialises the next.

    Parameters
    ----------
    reference, image : ndarray
        Same-sized float images in [0, 1] (colour or grey).
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
    a0, b0 = _grey_u8(reference), _grey_u8(image)
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


def warp_image(image: np.ndarray, positions: np.ndarray, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
    """Sample ``image`` at absolute ``positions`` (``out(p) = image(positions(p))``).

    Backward mapping: every output pixel gets a value, so there are no holes; outside the
    image the border is replicated.
    """
    pos = np.ascontiguousarray(positions, dtype=np.float32)  # one CV_32FC2 map: no x/y split
    return cv2.remap(np.ascontiguousarray(image, dtype=np.float32), pos, None, interpolation,
                     borderMode=cv2.BORDER_REPLICATE)


def sample_field(field: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Bilinearly sample a 2-channel field at absolute ``positions`` (border replicated)."""
    return warp_image(field, positions, cv2.INTER_LINEAR)


def invert_displacement(d: np.ndarray, iterations: int = 12, base: np.ndarray | None = None) -> np.ndarray:
    """The inverse ``e`` of a fold-free displacement ``d``: ``x + d(x) = p  ⇔  x = p + e(p)``.

    Fixed-point iteration ``e ← -d(p + e)`` (converges where the warp does not fold).
    """
    g = grid(*d.shape[:2]) if base is None else base
    e = -d
    for _ in range(iterations):
        e = -sample_field(d, g + e)
    return e


def jacobian_det(d: np.ndarray) -> np.ndarray:
    """Determinant of the Jacobian of ``x ↦ x + d(x)`` per pixel (≤ 0 where the warp folds over)."""
    dxdy, dxdx = np.gradient(d[..., 0])
    dydy, dydx = np.gradient(d[..., 1])
    return (1.0 + dxdx) * (1.0 + dydy) - dxdy * dydx


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
