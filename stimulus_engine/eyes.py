"""Eyes that read as open eyes: a procedural eyeball texture (sclera, iris, pupil) and its UVs.

Face models rarely ship an eye texture (the ICT Face Model has none; its eyeballs are a textured
inner ball plus a transparent corneal shell meant for Unreal's eye shader). Here every eyeball
gets its own texture coordinates from its *geometry*: a Lambert azimuthal equal-area projection
about the gaze axis (:func:`eyeball_uv`, the pupil at UV (0.5, 0.5), the back pole on the UV
circle of radius 0.5), so one radial texture (:func:`eye_texture`) serves both eyes of any mesh,
whatever its own UV layout. The texture is painted by angle from the gaze axis: pupil, iris
with radial fibres and a dark limbal ring, off-white sclera.
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["eye_texture", "eyeball_uv", "fit_sphere"]

#: Default angles (degrees from the gaze axis, seen from the eyeball centre). Measured on the ICT
#: Face Model's inner eyeball (the flattened iris cone ends at 24–27°, the pupil dip at ~8°;
#: /tmp/f5/eye2.py in the issue-5 follow-up notes), close to a real eye (iris radius 5.9 mm on
#: a 12 mm ball: 29°).
IRIS_ANGLE = 25.5
PUPIL_ANGLE = 7.5


def fit_sphere(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares sphere through ``points`` (algebraic fit): centre (3,) and radius.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> d = rng.normal(size=(50, 3)); d /= np.linalg.norm(d, axis=1, keepdims=True)
    >>> c, r = fit_sphere(np.array([1.0, 2.0, 3.0]) + 2.5 * d)
    >>> np.round(c, 6).tolist(), round(r, 6)
    ([1.0, 2.0, 3.0], 2.5)
    """
    p = np.asarray(points, np.float64)
    A = np.column_stack([2 * p, np.ones(len(p))])
    x = np.linalg.lstsq(A, (p**2).sum(axis=1), rcond=None)[0]
    c = x[:3]
    return c, float(np.sqrt(x[3] + c @ c))


def eyeball_uv(points: np.ndarray, centre: np.ndarray, axis: np.ndarray,
               up: tuple[float, float, float] = (0.0, 1.0, 0.0)) -> np.ndarray:
    """Texture coordinates of eyeball points: equal-area azimuthal projection about ``axis``.

    A point at angle θ from the gaze axis and azimuth φ (φ = 0 towards image right) maps to
    ``(0.5, 0.5) + 0.5·sin(θ/2)·(cos φ, sin φ)``: the pupil centre is the UV centre, the back
    of the ball the UV circle of radius 0.5.

    Parameters
    ----------
    points : (n, 3) array
    centre : (3,) array
        Eyeball centre.
    axis : (3,) array
        Gaze direction (from the centre through the pupil).
    up : tuple of float
        World up (fixes φ; only matters for iris fibres, which are rotation-symmetric anyway).

    Returns
    -------
    (n, 2) float array in [0, 1]
    """
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    e1 = np.cross(np.asarray(up, np.float64), a)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    d = np.asarray(points, np.float64) - np.asarray(centre, np.float64)
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    theta = np.arccos(np.clip(d @ a, -1.0, 1.0))
    phi = np.arctan2(d @ e2, d @ e1)
    r = 0.5 * np.sin(theta / 2)
    return np.column_stack([0.5 + r * np.cos(phi), 0.5 + r * np.sin(phi)])


@functools.lru_cache(maxsize=8)
def eye_texture(size: int = 512, iris_colour: tuple[float, float, float] = (0.33, 0.22, 0.13), *,
                iris_angle: float = IRIS_ANGLE, pupil_angle: float = PUPIL_ANGLE,
                seed: int = 0) -> np.ndarray:
    """A radial eyeball albedo for :func:`eyeball_uv` coordinates (pupil at the image centre).

    Parameters
    ----------
    size : int
        Texture width and height in pixels.
    iris_colour : tuple of float
        Mean iris colour (sRGB 0..1); the default is a mid brown.
    iris_angle, pupil_angle : float
        Outer edges of iris and pupil in degrees from the gaze axis.
    seed : int
        Phases of the iris fibre pattern (deterministic).

    Returns
    -------
    (size, size, 3) uint8 array (read-only; cached)
    """
    if not 0 < pupil_angle < iris_angle < 90:
        raise ValueError(f"expected 0 < pupil_angle < iris_angle < 90 (got {pupil_angle}, {iris_angle})")
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    # texture row 0 is v = 1 (see materials.bake_surface_points): flip v
    u, v = x - 0.5, (1.0 - y) - 0.5
    r = np.minimum(np.hypot(u, v) / 0.5, 1.0)
    theta = np.degrees(2 * np.arcsin(r))
    phi = np.arctan2(v, u)
    rng = np.random.default_rng(seed)
    fibres = np.zeros_like(phi)
    for k, ph in zip((23, 37, 59, 83), rng.uniform(0, 2 * np.pi, 4)):
        fibres += np.sin(k * phi + ph + 3 * (theta / iris_angle))
    fibres /= 4
    t = np.clip((theta - pupil_angle) / (iris_angle - pupil_angle), 0, 1)  # 0 at the pupil, 1 at the limbus
    iris = np.asarray(iris_colour)[None, None, :] * (0.75 + 0.35 * fibres[..., None] * (0.4 + t[..., None]))
    iris *= (1.25 - 0.45 * t)[..., None] ** 1.0  # lighter collarette near the pupil
    limbus = np.exp(-(((theta - iris_angle) / 2.2) ** 2))[..., None]
    iris = iris * (1 - 0.6 * limbus)
    sclera = np.array([0.93, 0.90, 0.86])[None, None, :] - 0.10 * np.clip((theta - 60) / 90, 0, 1)[..., None] \
        * np.array([0.0, 0.35, 0.35])
    pupil = np.array([0.02, 0.02, 0.02])
    # the back of the ball is dark: it is what one sees through a pupil that is a hole in the mesh
    sclera = sclera + (pupil - sclera) * np.clip((theta - 110) / 10, 0, 1)[..., None]

    def edge(x0: float, width: float) -> np.ndarray:  # smooth 0→1 step at x0 (anti-aliased borders)
        return np.clip((theta - x0) / width + 0.5, 0, 1)[..., None]

    img = pupil + (iris - pupil) * edge(pupil_angle, 1.0)
    img = img + (sclera - img) * edge(iris_angle + 0.8, 1.6)
    out = np.clip(np.rint(img * 255), 0, 255).astype(np.uint8)
    out.setflags(write=False)
    return out
