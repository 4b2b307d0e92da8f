"""Symmetric faces: mirrored templates and symmetrised shape and colour (WebMorph's *Symmetrise*).

Mirroring a template needs to know which point is whose left-right partner: a *mirror map*
``m`` with ``m[i]`` = the partner of point ``i`` (midline points are their own partners, and
``m[m[i]] == i``). Two are built in:

* ``FRL_189_MIRROR`` for WebMorph's 189-point FRL template (the London set's ``.tem``),
  derived from the data by :func:`derive_mirror_map`: the 87 London templates, each moved so its
  pupils sit at (−1, 0) and (1, 0), are averaged; the mean is reflected about its vertical
  midline (x = 0) and each point is assigned to the nearest reflected point by an optimal
  one-to-one matching (Hungarian algorithm, :func:`scipy.optimize.linear_sum_assignment`). The
  result is an involution; its 11 fixed points are the midline (philtrum, lips, chin, hairline
  centre ...), all within 0.04 half-eye-distances of the mean's midline. The constant is
  checked against a fresh derivation by the tests.
* ``DLIB_68_MIRROR`` for dlib's 68 landmarks (the standard iBUG 300-W pairing).

:func:`symmetrise` averages a template with its mirror image — the template reflected about the
face's own best symmetry axis (:func:`symmetry_reflection`, a least-squares fit, so a tilted or
off-centre face stays where it is) with partners swapped — giving a shape exactly symmetric
about that axis. Colour is symmetrised by averaging the image with its reflection about the
same axis, each warped onto the output shape (:func:`stimulus_engine.faces2d.warp.warp_to_points`)
so that each side's pixels meet their partners'.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import cv2
import numpy as np

from stimulus_engine.faces2d.warp import warp_to_points

__all__ = ["FRL_189_MIRROR", "DLIB_68_MIRROR", "SYMMETRY_MODES", "mirror_map", "derive_mirror_map",
           "check_mirror_map", "symmetry_reflection", "reflect_points", "reflect_image", "mirror_template",
           "symmetric_points", "symmetrise", "asymmetry"]

SYMMETRY_MODES = ("both", "shape", "colour")

FRL_189_MIRROR = np.array([
    1, 0, 10, 17, 16, 15, 14, 13, 12, 11, 2, 9, 8, 7, 6, 5, 4, 3, 27, 26, 25, 24, 23, 22, 21, 20, 19, 18, 33, 32,
    31, 30, 29, 28, 43, 42, 41, 40, 39, 38, 37, 36, 35, 34, 49, 48, 47, 46, 45, 44, 56, 57, 58, 59, 60, 55, 50, 51,
    52, 53, 54, 66, 67, 68, 69, 70, 61, 62, 63, 64, 65, 82, 81, 80, 79, 78, 77, 76, 75, 74, 73, 72, 71, 86, 85, 84,
    83, 93, 92, 91, 90, 89, 88, 87, 98, 97, 96, 95, 94, 103, 102, 101, 100, 99, 108, 107, 106, 105, 104, 112, 113,
    114, 109, 110, 111, 120, 121, 122, 123, 124, 115, 116, 117, 118, 119, 133, 132, 131, 130, 129, 128, 127, 126,
    125, 144, 143, 142, 141, 140, 139, 138, 137, 136, 135, 134, 157, 156, 155, 154, 153, 152, 151, 150, 149, 148,
    147, 146, 145, 161, 162, 163, 158, 159, 160, 167, 168, 169, 164, 165, 166, 172, 173, 170, 171, 174, 175, 178,
    177, 176, 182, 181, 180, 179, 184, 183, 187, 188, 185, 186], dtype=np.intp)
FRL_189_MIRROR.setflags(write=False)


def _dlib68() -> np.ndarray:
    m = np.arange(68)
    pairs = [(i, 16 - i) for i in range(8)]                                         # jaw
    pairs += [(17 + i, 26 - i) for i in range(5)]                                   # brows
    pairs += [(31, 35), (32, 34)]                                                   # nostrils
    pairs += [(36, 45), (37, 44), (38, 43), (39, 42), (40, 47), (41, 46)]           # eyes
    pairs += [(48, 54), (49, 53), (50, 52), (55, 59), (56, 58)]                     # outer lips
    pairs += [(60, 64), (61, 63), (65, 67)]                                         # inner lips
    for a, b in pairs:
        m[a], m[b] = b, a
    m.setflags(write=False)
    return m


DLIB_68_MIRROR = _dlib68()


def check_mirror_map(mirror: np.ndarray, n: int | None = None) -> np.ndarray:
    """``mirror`` as an index array, checked: a permutation of ``range(n)`` that is its own inverse.

    Raises
    ------
    ValueError
        Wrong length, not a permutation, or not an involution.
    """
    m = np.asarray(mirror, np.intp)
    n = len(m) if n is None else n
    if m.shape != (n,) or not np.array_equal(np.sort(m), np.arange(n)):
        raise ValueError(f"a mirror map for {n} points must be a permutation of 0..{n - 1}")
    if not np.array_equal(m[m], np.arange(n)):
        raise ValueError("a mirror map must be its own inverse (m[m[i]] == i)")
    return m


def mirror_map(n_points: int) -> np.ndarray:
    """The built-in mirror map for a template of ``n_points`` (189: FRL, 68: dlib).

    Raises
    ------
    ValueError
        No built-in map for that many points (derive one with :func:`derive_mirror_map`).
    """
    if n_points == len(FRL_189_MIRROR):
        return FRL_189_MIRROR
    if n_points == len(DLIB_68_MIRROR):
        return DLIB_68_MIRROR
    raise ValueError(f"no left-right mirror map for a {n_points}-point template (built in: 189-point FRL, "
                     "68-point dlib)")


def _eye_frame(points: np.ndarray) -> np.ndarray:
    from stimulus_engine.faces2d.align import align_matrix, eye_points

    m = align_matrix(eye_points(points), np.array([[-1.0, 0.0], [1.0, 0.0]]))
    return np.asarray(points, np.float64) @ m[:, :2].T + m[:, 2]


def derive_mirror_map(templates: Sequence[np.ndarray], *, midline_tol: float = 0.05) -> np.ndarray:
    """A mirror map derived from example templates (see the module docstring).

    Parameters
    ----------
    templates : sequence of (n, 2) arrays
        Templates of frontal faces (pupils found by :func:`stimulus_engine.faces2d.align.eye_points`).
    midline_tol : float
        Points of the mean template within this distance of the midline (in half eye distances)
        must map to themselves, and points mapped to themselves must lie within it.

    Returns
    -------
    (n,) int array

    Raises
    ------
    ValueError
        The matching is not an involution, or the midline check fails.
    """
    from scipy.optimize import linear_sum_assignment

    mean = np.mean([_eye_frame(t) for t in templates], axis=0)
    reflected = mean * [-1.0, 1.0]
    cost = np.linalg.norm(mean[:, None, :] - reflected[None, :, :], axis=2)
    _, col = linear_sum_assignment(cost)
    m = check_mirror_map(col)
    fixed = m == np.arange(len(m))
    near = np.abs(mean[:, 0]) < midline_tol
    if np.any(fixed & ~near):
        raise ValueError(f"points {np.flatnonzero(fixed & ~near).tolist()} map to themselves but are off the "
                         "midline")
    if np.any(near & ~fixed):
        raise ValueError(f"midline points {np.flatnonzero(near & ~fixed).tolist()} have a partner other than "
                         "themselves")
    return m


def symmetry_reflection(points: np.ndarray, mirror: np.ndarray) -> np.ndarray:
    """The reflection (2×3 affine, ``x' = A x + t`` with ``A`` orthogonal, det −1, ``A² = I``) that best
    maps each point onto its partner's position: the face's own symmetry axis (least squares)."""
    p = np.asarray(points, np.float64)
    q = p[check_mirror_map(mirror, len(p))]  # partners
    c = p.mean(0)  # = q.mean(0)
    flip = np.diag([-1.0, 1.0])
    # rotation R minimising |R flip (q - c) - (p - c)|: Kabsch on the flipped partners
    h = ((q - c) @ flip).T @ (p - c)
    u, _, vt = np.linalg.svd(h)
    r = vt.T @ u.T
    if np.linalg.det(r) < 0:
        vt[-1] *= -1
        r = vt.T @ u.T
    a = r @ flip
    a = 0.5 * (a + a.T)  # a reflection matrix is symmetric; remove rounding
    return np.hstack([a, (c - a @ c)[:, None]])


def reflect_points(points: np.ndarray, reflection: np.ndarray) -> np.ndarray:
    """``points`` moved by a 2×3 affine."""
    return np.asarray(points, np.float64) @ reflection[:, :2].T + reflection[:, 2]


def reflect_image(image: np.ndarray, reflection: np.ndarray) -> np.ndarray:
    """``image`` reflected by a 2×3 affine (same size; uncovered pixels repeat the border)."""
    img = np.asarray(image, np.float32)
    h, w = img.shape[:2]
    return cv2.warpAffine(img, reflection, (w, h), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)


def mirror_template(points: np.ndarray, mirror: np.ndarray, reflection: np.ndarray | None = None) -> np.ndarray:
    """The template of the mirrored face: each point is its partner, reflected (by default about the
    face's own axis, :func:`symmetry_reflection`)."""
    p = np.asarray(points, np.float64)
    m = check_mirror_map(mirror, len(p))
    g = symmetry_reflection(p, m) if reflection is None else reflection
    return reflect_points(p[m], g)


def symmetric_points(points: np.ndarray, mirror: np.ndarray) -> np.ndarray:
    """The template averaged with its mirror: exactly symmetric about the face's axis."""
    p = np.asarray(points, np.float64)
    return 0.5 * (p + mirror_template(p, mirror))


def asymmetry(points: np.ndarray, mirror: np.ndarray) -> float:
    """Largest distance (pixels) between a template's points and its mirror template's."""
    p = np.asarray(points, np.float64)
    return float(np.max(np.linalg.norm(p - mirror_template(p, mirror), axis=1)))


def symmetrise(image: np.ndarray, points: np.ndarray, mirror: np.ndarray | None = None, *,
               mode: Literal["both", "shape", "colour"] = "both") -> tuple[np.ndarray, np.ndarray]:
    """A symmetric version of a face: its shape, its colour, or both.

    Parameters
    ----------
    image : (h, w, 3) float array
        RGB in [0, 1].
    points : (n, 2) array
        Its template.
    mirror : (n,) int array, optional
        Left-right partners (default: :func:`mirror_map` for ``n``).
    mode : {"both", "shape", "colour"}
        ``shape``: the image warped onto the symmetric template (its own colours);
        ``colour``: the shape kept, each pixel averaged with its partner across the face's axis
        (the reflected image warped onto the original template);
        ``both``: the image and its reflection, both warped onto the symmetric template, averaged.

    Returns
    -------
    (image, points)
        float32 image (same size) and its template.
    """
    if mode not in SYMMETRY_MODES:
        raise ValueError(f"mode must be one of {SYMMETRY_MODES} (got {mode!r})")
    p = np.asarray(points, np.float64)
    m = mirror_map(len(p)) if mirror is None else check_mirror_map(mirror, len(p))
    g = symmetry_reflection(p, m)
    mirrored = reflect_points(p[m], g)  # where each point of the reflected image is
    target = 0.5 * (p + mirrored) if mode in ("both", "shape") else p
    own = warp_to_points(image, p, target)
    if mode == "shape":
        return np.clip(own, 0.0, 1.0), target
    other = warp_to_points(reflect_image(image, g), mirrored, target)
    return np.clip(0.5 * (own + other), 0.0, 1.0).astype(np.float32), target
