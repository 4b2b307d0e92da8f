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

from stimulus_engine.data import DATA_DIR
from stimulus_engine.geometry.ramps import smoothstep

__all__ = ["eye_shadow_texture", "eye_texture", "eyeball_asset", "eyeball_uv", "fit_sphere", "painted_pupils",
           "photographic_eye_texture", "tint_iris"]

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
    # texture row 0 is v = 1 (see skin_maps.bake_surface_points): flip v
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


def tint_iris(texture: np.ndarray, colour: np.ndarray, least: float | None = None) -> np.ndarray:
    """An eyeball texture with its iris (its saturated pixels) in ``colour`` (sRGB 0-255),
    keeping the iris's own light and dark fibres (its luminance relative to its median).

    ``least``: the colour is first lifted, hue kept, to at least this mean grey (a colour read off
    a scan's shaded painted eye comes out darker than the iris was).
    """
    from matplotlib.colors import rgb_to_hsv

    colour = np.asarray(colour, np.float64)
    if least is not None:
        colour = colour * max(least / max(float(colour.mean()), 1.0), 1.0)
    t = texture.astype(np.float64)
    iris = rgb_to_hsv(t / 255.0)[..., 1] > 0.3
    lum = t @ np.array([0.2126, 0.7152, 0.0722])
    rel = lum / max(float(np.median(lum[iris])), 1e-6)
    # a painted iris is seen through the cornea and lashes: lift it slightly towards the texture's own level
    out = t.copy()
    out[iris] = np.clip(rel[iris, None] * colour * 1.15, 0, 255)
    return np.rint(out).astype(np.uint8)


@functools.lru_cache(maxsize=4)
def photographic_eye_texture(size: int = 512, iris_angle: float = IRIS_ANGLE) -> np.ndarray:
    """The photographic eyeball of ``stimulus_engine/data/eyes`` (MakeHuman, CC0) in the
    :func:`eyeball_uv` layout, its iris edge moved to ``iris_angle``.

    Every texel's direction on the ball (equal-area layout about the gaze axis) is found on the
    template eyeball's surface, whose own UVs give the colour in the photograph; angles from the
    gaze axis are stretched piecewise linearly so the photograph's limbus falls at ``iris_angle``
    (the rig's iris geometry) and the template's edge at 120 degrees; from there to the back the
    texture darkens, as :func:`eye_texture`'s.

    Computed at most 256 pixels wide (the photograph's eye disk is about that) and resized.

    Returns
    -------
    (size, size, 3) uint8 array (read-only; cached)
    """
    if size > 256:
        from PIL import Image

        img = np.asarray(Image.fromarray(photographic_eye_texture(256, iris_angle)).resize((size, size), Image.BICUBIC))
        img.setflags(write=False)
        return img
    from matplotlib.colors import rgb_to_hsv
    from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator
    from scipy.ndimage import map_coordinates

    templates, photo = eyeball_asset()
    unit, _, uv = templates[0]
    h, w = photo.shape[:2]
    # the gaze axis through the photograph's pupil: the direction whose UV is nearest the centre
    # of the iris (its saturated texels) in the part of the photograph this ball's UVs cover
    rows, cols = np.mgrid[0:h, 0:w]
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    tu, tv = cols / (w - 1), 1 - rows / (h - 1)
    mine = (tu >= lo[0]) & (tu <= hi[0]) & (tv >= lo[1]) & (tv <= hi[1])
    iris_px = mine & (rgb_to_hsv(photo / 255.0)[..., 1] > 0.3)
    centre_uv = np.array([tu[iris_px].mean(), tv[iris_px].mean()])
    d = unit / np.linalg.norm(unit, axis=1, keepdims=True)
    d = _rotate_onto(d, d[np.argmin(np.linalg.norm(uv - centre_uv, axis=1))], np.array([0.0, 0.0, 1.0]))
    theta = np.degrees(np.arccos(np.clip(d[:, 2], -1, 1)))
    phi = np.arctan2(d[:, 1], d[:, 0])

    def sample(q: np.ndarray) -> np.ndarray:
        rows, cols = (1 - q[:, 1]) * (h - 1), q[:, 0] * (w - 1)
        return np.stack([map_coordinates(photo[..., c].astype(np.float64), [rows, cols], order=1, mode="nearest")
                         for c in range(3)], axis=-1)

    flat = np.column_stack([np.sin(np.radians(theta) / 2) * np.cos(phi), np.sin(np.radians(theta) / 2) * np.sin(phi)])
    lin, near = LinearNDInterpolator(flat, uv), NearestNDInterpolator(flat, uv)

    def to_uv(t: np.ndarray, p: np.ndarray) -> np.ndarray:  # photograph UV of directions (theta deg, phi)
        x, y = np.sin(np.radians(t) / 2) * np.cos(p), np.sin(np.radians(t) / 2) * np.sin(p)
        q = lin(x, y)
        bad = ~np.isfinite(q).all(axis=1)
        q[bad] = near(x[bad], y[bad])
        return q

    # the photograph's limbus: where the iris's saturation ends, going out from the pupil
    rings = np.linspace(0.0, 60.0, 241)
    sat = rgb_to_hsv(sample(to_uv(np.repeat(rings, 72), np.tile(np.linspace(-np.pi, np.pi, 72, endpoint=False),
                                                                   len(rings)))) / 255.0)[:, 1]
    ring_sat = sat.reshape(len(rings), 72).mean(axis=1)
    coloured = ring_sat > 0.5 * ring_sat.max()
    first = int(np.argmax(coloured))
    src_iris = float(rings[first + int(np.argmin(coloured[first:])) - 1]) if not coloured[first:].all() else iris_angle
    src_max = float(theta.max())
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    u, v = x - 0.5, (1.0 - y) - 0.5  # texture row 0 is v = 1
    t_theta = np.degrees(2 * np.arcsin(np.minimum(np.hypot(u, v) / 0.5, 1.0))).ravel()
    t_phi = np.arctan2(v, u).ravel()
    s_theta = np.where(t_theta <= iris_angle, t_theta * src_iris / iris_angle,
                       src_iris + (t_theta - iris_angle) * (src_max - src_iris) / (120.0 - iris_angle))
    out = sample(to_uv(np.minimum(s_theta, src_max), t_phi))
    # the back of the ball is dark, as eye_texture's: what one sees through a pupil that is a hole
    out *= np.clip((120.0 - t_theta) / 10.0, 0.0, 1.0)[:, None] * 0.97 + 0.03
    img = np.clip(np.rint(out.reshape(size, size, 3)), 0, 255).astype(np.uint8)
    img.setflags(write=False)
    return img

#: The eye's shadow layer (a rig's eye-occlusion shell over the eye opening): the darkest it gets
#: under the upper lid, above the lower lid and in the corners (alpha 0..1), its colour (sRGB), and
#: the caruncle's (the pink fold in the inner corner).
EYE_SHADOW_UPPER, EYE_SHADOW_LOWER, EYE_SHADOW_CORNER = 0.6, 0.3, 0.45
EYE_SHADOW_COLOUR = (52, 30, 26)
CARUNCLE_COLOUR, CARUNCLE_ALPHA = (196, 112, 106), 0.85


@functools.lru_cache(maxsize=4)
def eye_shadow_texture(size: int = 128) -> np.ndarray:
    """(size, size, 4) uint8 RGBA for a rig's eye-occlusion shell: a soft shadow along the lids and
    the corners, transparent over the middle of the eye, and the caruncle in the inner corner.

    The shell's UVs (the ICT Face Model's ``eye_occlusion`` meshes) run across the eye opening:
    u from the outer corner (0) to the inner (1), v from the lower lid (0) to the upper (1), its
    border on the lid margins. The upper lid's shadow is the widest and darkest (it shades the
    sclera's top third in photographs, where the rasteriser draws the eyeball evenly lit); the
    caruncle is an ellipse of pink at the inner end, which turns the sclera's hard white wedge into
    the fleshy corner of a real eye.
    """
    v, u = np.mgrid[0:size, 0:size].astype(np.float64)
    u, v = (u + 0.5) / size, 1.0 - (v + 0.5) / size  # image rows run top (v = 1) to bottom
    layers = (EYE_SHADOW_UPPER * smoothstep(v, 0.52, 0.9), EYE_SHADOW_LOWER * (1 - smoothstep(v, 0.12, 0.42)),
              EYE_SHADOW_CORNER * (1 - smoothstep(u, 0.0, 0.16)), EYE_SHADOW_CORNER * smoothstep(u, 0.8, 1.0))
    alpha = 1 - np.prod([1 - a for a in layers], axis=0)
    rgb = np.broadcast_to(np.asarray(EYE_SHADOW_COLOUR, np.float64), (size, size, 3)).copy()
    r = np.hypot((u - 0.97) / 0.07, (v - 0.5) / 0.16)
    pink = CARUNCLE_ALPHA * (1 - smoothstep(r, 0.55, 1.0))
    rgb = rgb * (1 - pink[..., None]) + np.asarray(CARUNCLE_COLOUR, np.float64) * pink[..., None]
    alpha = np.maximum(alpha, pink)
    img = np.rint(np.dstack([rgb, 255 * alpha])).clip(0, 255).astype(np.uint8)
    img.setflags(write=False)
    return img


_ASSET = DATA_DIR / "eyes"


@functools.lru_cache(maxsize=1)
def eyeball_asset() -> tuple[list[tuple[np.ndarray, np.ndarray, np.ndarray]], np.ndarray]:
    """The two template eyeballs of ``stimulus_engine/data/eyes`` (MakeHuman's CC0 high-poly
    eyes; unit sphere about the origin, the painted pupil on +z) and their photographic texture.

    Each ball is turned so that its line of sight, from the centre through the pupil painted in
    the texture (:func:`painted_pupils`), runs along +z. (The mesh's own front cap lies 15–18°
    above the painted pupil: aligned by the cap, the irises looked down and showed white above
    them.)

    Returns
    -------
    balls : list of (vertices, faces, uv)
        The subject's right eye first (-x in the rigs' frame), each normalised by its fitted sphere.
    texture : (512, 512, 3) uint8 array
    """
    from PIL import Image

    d = np.load(_ASSET / "eyeballs.npz")
    v, f, uv, eye = (d[k] for k in ("vertices", "faces", "uv", "eye"))
    with Image.open(_ASSET / "brown_eye.jpg") as im:
        texture = np.asarray(im.convert("RGB"))
    pupils = painted_pupils(texture)
    balls = []
    for e in sorted((0, 1), key=lambda e: float(v[eye == e, 0].mean())):
        idx = np.flatnonzero(eye == e)
        remap = np.full(len(v), -1)
        remap[idx] = np.arange(len(idx))
        faces = remap[f[(eye[f] == e).all(axis=1)]]
        centre, radius = fit_sphere(v[idx].astype(np.float64))
        unit = (v[idx] - centre) / radius
        ball_uv = uv[idx].astype(np.float64)
        pupil = min(pupils, key=lambda p: float(np.linalg.norm(ball_uv - p, axis=1).min()))
        balls.append((_rotate_onto(unit, _uv_direction(unit, ball_uv, pupil), np.array([0.0, 0.0, 1.0])), faces, ball_uv))
    texture = _lit_sclera(texture, balls)
    texture.setflags(write=False)
    return balls, texture


#: The sclera's median grey level (sRGB) in the eyeball texture. The photograph behind MakeHuman's
#: texture was taken in dim light: its sclera's median is 120-130, as dark as the skin around a
#: rendered eye (a grey, "dead" eye); in the London photographs the sclera is far lighter than
#: the skin.
SCLERA_LEVEL = 200.0


def _lit_sclera(texture: np.ndarray, balls: list) -> np.ndarray:
    """The texture with each ball's sclera (beyond 26 degrees from the pupil; blended in from
    18) brightened to :data:`SCLERA_LEVEL`, its veins and shading kept as relative variation."""
    from stimulus_engine.geometry.uv_raster import rasterize_uv

    out = np.asarray(texture, np.float64).copy()
    h, w = out.shape[:2]
    for unit, faces, uv in balls:
        angle = np.degrees(np.arccos(np.clip(unit[:, 2], -1.0, 1.0)))
        rows, cols, fid, bary = rasterize_uv(uv, faces, w, h)
        a = np.einsum("nk,nk->n", bary, angle[faces[fid]])
        sclera = (a > 26) & (a < 90)
        gain = SCLERA_LEVEL / max(float(np.median(out[rows[sclera], cols[sclera]].mean(axis=1))), 1.0)
        out[rows, cols] *= (1 + (gain - 1) * smoothstep(a, 18.0, 26.0))[:, None]
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def painted_pupils(texture: np.ndarray, dark: float = 40.0) -> list[np.ndarray]:
    """UV centres of the pupils painted in an eyeball texture: its two largest dark blobs.

    Parameters
    ----------
    texture : (H, W, 3) uint8 array
    dark : float
        Grey level (0–255) below which a pixel counts as pupil.

    Returns
    -------
    list of (2,) arrays
        UV (OBJ convention: v = 0 at the image's bottom row), largest blob first.
    """
    from scipy import ndimage

    grey = np.asarray(texture, np.float64).mean(axis=2)
    labels, n = ndimage.label(grey < dark)
    if n == 0:
        raise ValueError(f"no pupil in the eye texture (no pixel darker than {dark:g})")
    sizes = ndimage.sum_labels(np.ones_like(grey), labels, np.arange(1, n + 1))
    order = np.argsort(-sizes)[:2] + 1
    h, w = grey.shape
    return [np.array([(x + 0.5) / w, 1.0 - (y + 0.5) / h])
            for y, x in ndimage.center_of_mass(np.ones_like(grey), labels, order)]


def _uv_direction(unit: np.ndarray, uv: np.ndarray, at: np.ndarray, radius: float = 0.03) -> np.ndarray:
    """The unit direction of the ball's surface where its UV layout has ``at`` (mean of the
    vertices within ``radius`` in UV, at least the 6 nearest)."""
    d = np.linalg.norm(uv - at, axis=1)
    near = d < radius
    if near.sum() < 6:
        near = np.isin(np.arange(len(d)), np.argsort(d)[:6])
    a = unit[near].mean(axis=0)
    return a / np.linalg.norm(a)


def _rotate_onto(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``points`` rotated by the smallest rotation taking direction ``a`` onto ``b``."""
    from stimulus_engine.geometry.rotation import rotation_onto

    return points @ rotation_onto(a / np.linalg.norm(a), b / np.linalg.norm(b)).T

