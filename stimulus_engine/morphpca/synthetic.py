"""Synthetic aligned faces drawn in code with known expression weights and keypoints.

They give exact ground truth for tests, the demo and the benchmarks: the same expression
weights can be rendered on several identities, so a projected expression can be compared
with the target identity's true rendering. Faces are drawn analytically (soft-edged signed
distance shapes with shading and a fixed per-identity skin texture), not by warping, so the
optical flow has real work to do.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["EXPRESSIONS", "SyntheticIdentity", "draw_weights", "random_identity", "render_synthetic_face",
           "synthetic_set"]

#: Names of the expression weights understood by :func:`render_synthetic_face` (each in [0, 1]).
EXPRESSIONS = ("smile", "jaw_open", "brow_raise", "blink", "frown", "pucker")


@dataclass(frozen=True)
class SyntheticIdentity:
    """Shape and colour parameters of one synthetic person (units: fraction of image width)."""

    face_width: float = 0.36
    face_height: float = 0.42
    eye_sep: float = 0.30
    eye_y: float = 0.40
    eye_size: float = 0.065
    nose_y: float = 0.56
    mouth_y: float = 0.68
    mouth_width: float = 0.13
    lip_thickness: float = 0.022
    skin: tuple[float, float, float] = (0.87, 0.70, 0.60)
    hair: tuple[float, float, float] = (0.25, 0.17, 0.10)
    iris: tuple[float, float, float] = (0.30, 0.45, 0.55)
    lips: tuple[float, float, float] = (0.72, 0.38, 0.38)
    texture_seed: int = 0


def random_identity(rng: np.random.Generator | int) -> SyntheticIdentity:
    """A random plausible identity (parameters drawn around the defaults)."""
    rng = np.random.default_rng(rng)
    u = lambda lo, hi: float(rng.uniform(lo, hi))  # noqa: E731
    skin_tone = u(0.45, 1.0)
    skin = (0.92 * skin_tone + 0.05, 0.72 * skin_tone + 0.04, 0.60 * skin_tone + 0.03)
    return SyntheticIdentity(
        face_width=u(0.32, 0.40), face_height=u(0.39, 0.45), eye_sep=u(0.26, 0.33), eye_y=u(0.38, 0.43),
        eye_size=u(0.055, 0.075), nose_y=u(0.54, 0.59), mouth_y=u(0.66, 0.71), mouth_width=u(0.11, 0.15),
        lip_thickness=u(0.017, 0.027), skin=skin,
        hair=tuple(float(c) for c in rng.uniform(0.05, 0.5) * np.array([1.0, 0.75, 0.5])),
        iris=tuple(float(c) for c in rng.uniform(0.15, 0.6, 3)),
        lips=(u(0.6, 0.8), u(0.3, 0.42), u(0.3, 0.42)), texture_seed=int(rng.integers(0, 2**31)))


def _smooth(d: np.ndarray, width: float) -> np.ndarray:
    """Soft inside-mask of a signed distance (negative inside), ``width`` pixels of anti-aliasing."""
    return np.clip(0.5 - d / width, 0.0, 1.0)


def _ellipse_sd(x, y, cx, cy, rx, ry):
    """Approximate signed distance (pixels) to an axis-aligned ellipse."""
    k = np.sqrt(((x - cx) / rx) ** 2 + ((y - cy) / ry) ** 2)
    return (k - 1.0) * np.minimum(rx, ry)


def _skin_noise(seed: int, h: int, w: int) -> np.ndarray:
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    fine = gaussian_filter(rng.standard_normal((h, w)), 1.0) * 0.6
    coarse = gaussian_filter(rng.standard_normal((h, w)), 6.0) * 6.0
    return (fine + coarse).astype(np.float32)


def _blend(img: np.ndarray, mask: np.ndarray, colour) -> None:
    img *= 1.0 - mask[..., None]
    img += mask[..., None] * np.asarray(colour, dtype=np.float32)


def render_synthetic_face(identity: SyntheticIdentity, weights=None, size: tuple[int, int] = (240, 200),
                          ) -> tuple[np.ndarray, np.ndarray]:
    """Draw ``identity`` with expression ``weights``.

    Parameters
    ----------
    identity : SyntheticIdentity
        Who.
    weights : array-like of float, optional
        One weight in [0, 1] per name in :data:`EXPRESSIONS` (default all zero: neutral).
    size : (int, int)
        Image height and width in pixels.

    Returns
    -------
    image : ndarray, float32, (h, w, 3) in [0, 1]
    keypoints : ndarray, (3, 2)
        x, y of the left eye centre, the right eye centre and the philtrum centre.
    """
    h, w = size
    wt = np.zeros(len(EXPRESSIONS)) if weights is None else np.clip(np.asarray(weights, float), 0, 1)
    if wt.shape != (len(EXPRESSIONS),):
        raise ValueError(f"weights: expected {len(EXPRESSIONS)} values ({', '.join(EXPRESSIONS)}), got {wt.shape}")
    smile, jaw, brow, blink, frown, pucker = wt
    s = w  # unit length
    idn = identity
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    cx, cy = w / 2.0, h * 0.52
    img = np.empty((h, w, 3), np.float32)
    img[:] = (0.82, 0.84, 0.86)

    # hair behind the head, head ellipse (chin drops with the jaw), shading and skin texture
    fw, fh = idn.face_width * s, idn.face_height * s
    hair = _smooth(_ellipse_sd(x, y, cx, cy - 0.08 * s, fw * 1.12, fh * 1.02), 1.5)
    hair *= (y < cy + 0.05 * s)
    _blend(img, hair, idn.hair)
    chin_drop = 0.05 * s * jaw
    lower = y > cy
    ry = np.where(lower, fh + chin_drop, fh)
    head = _smooth(_ellipse_sd(x, y, cx, cy, fw, ry), 1.5)
    r2 = ((x - cx) / fw) ** 2 + ((y - cy) / ry) ** 2
    shade = (1.0 - 0.22 * np.clip(r2, 0, 1) ** 1.5)[..., None]
    noise = _skin_noise(idn.texture_seed, h, w)[..., None] * 0.012
    skin = np.asarray(idn.skin, np.float32) * shade + noise
    img = img * (1 - head[..., None]) + skin * head[..., None]
    # hairline fringe on the forehead
    fringe = _smooth(_ellipse_sd(x, y, cx, cy - 0.38 * s, fw * 0.95, 0.12 * s), 1.5) * head
    _blend(img, fringe, idn.hair)

    # eyes: white, iris, pupil, then the upper lid closes with blink
    ey = idn.eye_y * h + 0.0
    er = idn.eye_size * s
    openness = 1.0 - 0.92 * blink
    eyes = []
    for sign in (-1.0, 1.0):
        ex = cx + sign * idn.eye_sep * s / 2
        eyes.append((ex, ey))
        sclera = _smooth(_ellipse_sd(x, y, ex, ey, er, er * 0.55), 1.2)
        _blend(img, sclera * 0.95, (0.95, 0.94, 0.92))
        iris = _smooth(np.hypot(x - ex, y - ey) - er * 0.42, 1.0) * sclera
        _blend(img, iris, idn.iris)
        pupil = _smooth(np.hypot(x - ex, y - ey) - er * 0.18, 1.0) * sclera
        _blend(img, pupil, (0.03, 0.03, 0.04))
        lid_edge = ey - er * 0.55 + 2 * er * 0.55 * (1 - openness)
        lid = sclera * _smooth(y - lid_edge, 1.2)
        _blend(img, lid, np.asarray(idn.skin) * 0.93)
        lash = sclera * np.clip(1 - np.abs(y - lid_edge) / 1.2, 0, 1) * (x > ex - er) * (x < ex + er)
        _blend(img, lash * 0.8, (0.08, 0.06, 0.05))
        # brow: a thick arc above the eye; raised by brow_raise, lowered and drawn inwards by frown
        by = ey - er * 1.25 - 0.035 * s * brow + 0.02 * s * frown
        bx = ex - sign * 0.012 * s * frown
        tilt = sign * 0.25 * frown
        arc = by - 0.35 * er * (1 - ((x - bx) / (er * 1.3)) ** 2) + tilt * (x - bx) * 0.3
        brow_d = np.maximum(np.abs(y - arc) - 0.011 * s, np.abs(x - bx) - er * 1.3)
        _blend(img, _smooth(brow_d, 1.2) * 0.9, np.asarray(idn.hair) * 0.9)

    # nose: side shading and nostrils
    ny = idn.nose_y * h
    ridge = np.exp(-((x - cx - 0.035 * s) ** 2) / (2 * (0.012 * s) ** 2)) * (y > ey) * (y < ny)
    img -= (ridge * 0.06)[..., None]
    for sign in (-1.0, 1.0):
        nostril = _smooth(_ellipse_sd(x, y, cx + sign * 0.028 * s, ny, 0.014 * s, 0.008 * s), 1.0)
        _blend(img, nostril * 0.8, np.asarray(idn.skin) * 0.35)
    tip = np.exp(-(((x - cx) / (0.04 * s)) ** 2 + ((y - ny + 0.02 * s) / (0.03 * s)) ** 2))
    img += (tip * 0.04)[..., None]

    # mouth: width grows with smile and shrinks with pucker, corners lift with smile, opens with jaw
    my = idn.mouth_y * h + 0.5 * chin_drop
    mw = idn.mouth_width * s * (1 + 0.25 * smile - 0.35 * pucker)
    gap = 0.06 * s * jaw
    u = (x - cx) / mw
    inside = np.abs(u) < 1
    curve = -0.03 * s * smile * u**2 + 0.006 * s * frown * u**2
    lt = idn.lip_thickness * s * (1 + 0.6 * pucker)
    taper = np.sqrt(np.clip(1 - u**2, 0, 1))
    upper_top = my + curve - gap / 2 - lt * taper
    upper_bot = my + curve - gap / 2 * taper
    lower_top = my + curve + gap / 2 * taper
    lower_bot = my + curve + gap / 2 + lt * 1.2 * taper
    mouth_in = inside * _smooth(upper_bot - y, 1.0) * _smooth(y - lower_top, 1.0)
    _blend(img, mouth_in, (0.18, 0.06, 0.07))
    teeth = mouth_in * _smooth((upper_bot + np.minimum(gap * 0.35, 0.012 * s)) - y, 1.0) * (np.abs(u) < 0.7)
    _blend(img, teeth, (0.93, 0.92, 0.86))
    upper_lip = inside * _smooth(upper_top - y, 1.0) * _smooth(y - upper_bot, 1.0)
    lower_lip = inside * _smooth(lower_top - y, 1.0) * _smooth(y - lower_bot, 1.0)
    _blend(img, np.maximum(upper_lip, lower_lip), idn.lips)

    philtrum = (cx, (ny + (my - gap / 2 - lt)) / 2)
    keypoints = np.array([eyes[0], eyes[1], philtrum], dtype=np.float64)
    return np.clip(img, 0, 1).astype(np.float32), keypoints


def synthetic_set(identity: SyntheticIdentity, n: int, rng: np.random.Generator | int, size=(240, 200),
                  include_neutral: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` renderings of ``identity`` under random sparse expression weights.

    Returns
    -------
    images : (n, h, w, 3) float32
    weights : (n, len(EXPRESSIONS))
    keypoints : (n, 3, 2)
    """
    rng = np.random.default_rng(rng)
    weights = draw_weights(n, rng)
    if include_neutral and n:
        weights[0] = 0.0
    out = [render_synthetic_face(identity, wt, size) for wt in weights]
    return np.stack([o[0] for o in out]), weights, np.stack([o[1] for o in out])


def draw_weights(n: int, rng: np.random.Generator | int) -> np.ndarray:
    """Random expression weights: each expression active with probability 0.5, strength U(0, 1)."""
    rng = np.random.default_rng(rng)
    return rng.uniform(0, 1, (n, len(EXPRESSIONS))) * (rng.uniform(0, 1, (n, len(EXPRESSIONS))) < 0.5)
