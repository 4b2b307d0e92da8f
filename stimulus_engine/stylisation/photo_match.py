"""How closely a render of a photo character matches photographs of the person (issue 49).

* :func:`render_vs_photo`: the render and the photograph aligned on dlib's 68 landmarks (the
  photograph moved onto the render by the similarity of its points), then by intensity (the
  photograph's luminance given the render's mean and spread inside the face), and compared by the
  SSIM of luminance inside the face (the hull of the jaw line and the brows) and by dlib's face
  descriptor distance (same person: under 0.6);
* :func:`mouth_motion` and :func:`motion_agreement`: how the mouth moves from neutral to an
  expression — dlib's 20 mouth points (48-67) in an eye-aligned frame (eye midpoint at the
  origin, eyes level, unit eye distance) — and whether two such motions agree in direction
  (correlation of the 40 coordinates) and size (ratio of their norms).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PhotoMatch", "eye_frame", "face_hull_mask", "motion_agreement", "mouth_motion", "render_vs_photo"]


@dataclass(frozen=True)
class PhotoMatch:
    """Render vs photograph: SSIM of luminance inside the face, descriptor distance, and the
    photograph as aligned onto the render (for a figure)."""

    ssim: float
    descriptor_distance: float
    aligned: np.ndarray


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
    a, b = _luma(render), _luma(aligned)
    b = (b - b[mask].mean()) / max(b[mask].std(), 1e-6) * a[mask].std() + a[mask].mean()
    _, smap = structural_similarity(a, b, data_range=255.0, gaussian_weights=True, sigma=1.5,
                                    use_sample_covariance=False, full=True)
    d = identity_distance(face_descriptor(render), face_descriptor(aligned))
    return PhotoMatch(float(smap[mask].mean()), float(d), aligned)


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
