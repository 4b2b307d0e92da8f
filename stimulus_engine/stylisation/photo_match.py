"""How closely a render of a photo character matches photographs of the person (issue 49).

* :func:`render_vs_photo`: the render and the photograph aligned on dlib's 68 landmarks (the
  photograph moved onto the render by the similarity of its points), then by intensity: the
  photograph shifted by the sub-pixel translation that best matches its luminance to the render's
  inside the face (OpenCV's ECC, at most :data:`MAX_REFINE_PX`; dlib's points on a render and on
  a photograph scatter by about half a pixel, and SSIM at σ = 1.5 px reads that misregistration of
  stubble and pores as a difference: over 16 London people a median 0.59 px shift raised the
  median SSIM from 0.895 to 0.926), and the photograph's luminance given the render's mean and
  spread inside the face; compared by the SSIM of luminance inside the face (the hull of the jaw
  line and the brows; ``ssim_landmarks`` keeps the value before the shift) and by dlib's face
  descriptor distance (same person: under 0.6);
* :func:`mouth_motion` and :func:`motion_agreement`: how the mouth moves from neutral to an
  expression — dlib's 20 mouth points (48-67) in an eye-aligned frame (eye midpoint at the
  origin, eyes level, unit eye distance) — and whether two such motions agree in direction
  (correlation of the 40 coordinates) and size (ratio of their norms).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MAX_REFINE_PX", "PhotoMatch", "eye_frame", "face_hull_mask", "motion_agreement", "mouth_motion",
           "render_vs_photo"]

#: The largest translation (pixels) the intensity-based refinement may add to the landmark alignment;
#: a larger one (or none found) keeps the landmark alignment.
MAX_REFINE_PX: float = 2.0


@dataclass(frozen=True)
class PhotoMatch:
    """Render vs photograph: SSIM of luminance inside the face (after the refinement, and with the
    landmark alignment alone), descriptor distance, the refinement's shift (pixels) and the
    photograph as aligned onto the render (for a figure)."""

    ssim: float
    descriptor_distance: float
    aligned: np.ndarray
    ssim_landmarks: float = float("nan")
    shift_px: float = 0.0


def _luma(img: np.ndarray) -> np.ndarray:
    return np.asarray(img[..., :3], np.float64) @ np.array([0.299, 0.587, 0.114])


def face_hull_mask(shape: tuple[int, int], points: np.ndarray) -> np.ndarray:
    """Pixels inside the hull of the 68 points' jaw line and brows (0-26)."""
    import cv2

    mask = np.zeros(shape[:2], np.uint8)
    hull = cv2.convexHull(np.rint(points[:27]).astype(np.int32))
    cv2.fillConvexPoly(mask, hull, 1)
    return mask.astype(bool)


def _similarity(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """2 x 3 similarity taking ``src`` points nearest ``dst`` (least squares)."""
    from stimulus_engine.correspondence.alignment import umeyama

    pad = lambda p: np.c_[p, np.zeros(len(p))]
    s = umeyama(pad(src), pad(dst))
    return np.c_[(s.scale * s.rotation)[:2, :2], s.translation[:2]]


def render_vs_photo(render: np.ndarray, photo: np.ndarray, *, render_points: np.ndarray | None = None,
                    photo_points: np.ndarray | None = None) -> PhotoMatch:
    """Compare a render with a photograph of the same face (see the module docstring).

    Parameters
    ----------
    render, photo : (H, W, 3) uint8 arrays
    render_points, photo_points : (68, 2) arrays, optional
        Their landmarks (default: found by dlib).
    """
    import cv2
    from skimage.metrics import structural_similarity

    from stimulus_engine.morphpca.keypoints import detect_landmarks
    from stimulus_engine.stylisation.identity import face_descriptor, identity_distance

    rp = detect_landmarks(render, "render") if render_points is None else render_points
    pp = detect_landmarks(photo, "photo") if photo_points is None else photo_points
    h, w = render.shape[:2]
    aligned = cv2.warpAffine(np.ascontiguousarray(photo[..., :3]), _similarity(pp, rp), (w, h), flags=cv2.INTER_AREA,
                             borderMode=cv2.BORDER_REPLICATE)
    mask = face_hull_mask((h, w), rp)
    a = _luma(render)

    def ssim(b: np.ndarray) -> float:  # the photograph's luma on the render's frame
        b = (b - b[mask].mean()) / max(b[mask].std(), 1e-6) * a[mask].std() + a[mask].mean()
        _, smap = structural_similarity(a, b, data_range=255.0, gaussian_weights=True, sigma=1.5,
                                        use_sample_covariance=False, full=True)
        return float(smap[mask].mean())

    luma = _luma(aligned)
    by_landmarks = ssim(luma)
    shift = _intensity_shift(a, luma, mask)
    if shift is not None:
        aligned = cv2.warpAffine(aligned, np.array([[1.0, 0.0, -shift[0]], [0.0, 1.0, -shift[1]]]), (w, h),
                                 flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    d = identity_distance(face_descriptor(render), face_descriptor(aligned))
    return PhotoMatch(ssim(_luma(aligned)) if shift is not None else by_landmarks, float(d), aligned, by_landmarks,
                      0.0 if shift is None else float(np.hypot(*shift)))


def _intensity_shift(render_luma: np.ndarray, photo_luma: np.ndarray, mask: np.ndarray) -> np.ndarray | None:
    """The translation (x, y) in pixels that best matches ``photo_luma`` to ``render_luma`` inside
    ``mask`` (OpenCV's enhanced correlation coefficient, translation only); None where ECC does not
    converge or the shift exceeds :data:`MAX_REFINE_PX`."""
    import cv2

    warp = np.eye(2, 3, dtype=np.float32)
    try:
        _, warp = cv2.findTransformECC(render_luma.astype(np.float32), photo_luma.astype(np.float32), warp,
                                       cv2.MOTION_TRANSLATION,
                                       (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-5),
                                       mask.astype(np.uint8), 5)
    except cv2.error:
        return None
    shift = warp[:, 2].astype(np.float64)
    return shift if np.all(np.isfinite(shift)) and np.hypot(*shift) <= MAX_REFINE_PX else None


def eye_frame(points: np.ndarray) -> np.ndarray:
    """``points`` (68, 2) in the eye-aligned frame: eye midpoint at the origin, the eyes level,
    unit distance between the eye centres."""
    p = np.asarray(points, np.float64)
    r, l = p[36:42].mean(axis=0), p[42:48].mean(axis=0)
    d = l - r
    c, s = d / np.linalg.norm(d)
    rot = np.array([[c, s], [-s, c]])
    return (p - (r + l) / 2) @ rot.T / np.linalg.norm(d)


def mouth_motion(neutral: np.ndarray, expression: np.ndarray) -> np.ndarray:
    """The 20 mouth points' displacement ``(20, 2)`` from ``neutral`` to ``expression`` (68 points
    each), in the eye-aligned frame of each."""
    return eye_frame(expression)[48:68] - eye_frame(neutral)[48:68]


def motion_agreement(motion: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """Correlation of two motions' 40 coordinates and the ratio of their sizes (``motion`` over
    ``reference``)."""
    a, b = np.ravel(motion), np.ravel(reference)
    return float(np.corrcoef(a, b)[0, 1]), float(np.linalg.norm(a) / max(np.linalg.norm(b), 1e-12))
