"""A textured human head made entirely by code: the embedded default of the demo and tests.

The head is a latitude/longitude sphere (so its UVs are the sphere's parameters, seam at the
back) deformed into head proportions, with nose, brow ridge, eye sockets, cheeks, lips and chin
as smooth bumps, two eyeballs (part ``eye``, textured with sclera, iris and pupil), expression blendshapes for every shape the
FACS recipes use (smooth displacement fields at the right places), and an albedo texture painted
analytically in UV space (skin tone with multi-scale noise, lips, brows, cheek blush, hair cap).
Everything derives from ``seed``; no file is read.

The result is a :class:`stimulus_engine.characters.rig.FaceRig` like the ICT rig, so expressions,
stylisation, materials, rendering and neoteny measures treat both the same way.
"""

from __future__ import annotations

import functools

import numpy as np

from stimulus_engine.characters.gaze import pupil_ring
from stimulus_engine.characters.rig import FaceRig
from stimulus_engine.parts.eyes import eyeball_uv, photographic_eye_texture, tint_iris
from stimulus_engine.geometry.ramps import smoothstep

__all__ = ["paint_albedo_at", "paint_detail_maps_at", "procedural_head", "value_noise3"]

_PARTS = ("skin", "eye", "teeth", "mouth", "lashes", "hidden")


def _g(x: np.ndarray, y: np.ndarray, cx: float, cy: float, sx: float, sy: float) -> np.ndarray:
    return np.exp(-((x - cx) ** 2) / (2 * sx**2) - ((y - cy) ** 2) / (2 * sy**2))


def _head_surface(theta: np.ndarray, phi: np.ndarray, p: dict[str, float]) -> np.ndarray:
    """Head surface point for sphere parameters (θ from the top, φ = 0 at the front)."""
    st, ct = np.sin(theta), np.cos(theta)
    x = p["rx"] * st * np.sin(phi)
    y = p["ry"] * ct
    z = p["rz"] * st * np.cos(phi)
    # jaw: narrow and flatten the lower head, pull the back of the lower head in
    low = smoothstep(y, 0.5, -p["ry"])
    x = x * (1 - p["jaw"] * low)
    z = np.where(z < 0, z * (1 - 0.45 * low), z * (1 - 0.12 * low))
    front = smoothstep(z, 0.0, 0.5 * p["rz"])
    bump = (
        p["nose"] * _g(x, y, 0, -0.9, 0.95, 1.3) * smoothstep(y, -2.6, -0.4)
        + 0.9 * p["nose"] * _g(x, y, 0, 1.0, 0.7, 1.6)
        + 0.55 * _g(x, y, -3.0, 3.9, 1.6, 0.7) + 0.55 * _g(x, y, 3.0, 3.9, 1.6, 0.7)
        - 1.25 * _g(x, y, -3.1, 2.6, 1.25, 0.95) - 1.25 * _g(x, y, 3.1, 2.6, 1.25, 0.95)
        + 0.45 * _g(x, y, -3.9, -0.4, 1.5, 1.4) + 0.45 * _g(x, y, 3.9, -0.4, 1.5, 1.4)
        + 0.45 * _g(x, y, 0, -3.85, p["mouth"] * 1.3, 0.35) + 0.5 * _g(x, y, 0, -4.75, p["mouth"] * 1.15, 0.4)
        - 0.22 * _g(x, y, 0, -4.3, p["mouth"] * 1.4, 0.12)
        + 0.55 * _g(x, y, 0, -7.2, 1.7, 0.9)
    )
    z = z + bump * front
    return np.stack([x, y, z], axis=-1)


def _value_noise(shape: tuple[int, int], cells: int, rng: np.random.Generator) -> np.ndarray:
    """Smooth noise: random values on a (cells × cells) lattice, bicubic-upsampled (periodic in u)."""
    from scipy.ndimage import zoom

    lat = rng.standard_normal((cells, cells))
    lat = np.concatenate([lat, lat[:, :3]], axis=1)
    up = zoom(lat, (shape[0] / cells, shape[1] / cells), order=3, mode="grid-wrap")
    return up[: shape[0], : shape[1]]


def paint_albedo_at(pts: np.ndarray, anchors: dict[str, np.ndarray], colours: dict[str, tuple[float, float, float]],
                    rng: np.random.Generator, valid: np.ndarray | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Paint skin, lips, brows, blush and hair at 3D points (one per texel) of a face.

    Parameters
    ----------
    pts : (H, W, 3) array
        The neutral-face 3D point of every texel (cm, +y up, face towards +z).
    anchors : dict
        Landmark points: ``mouth`` (centre), ``mouth_half`` (half width, scalar),
        ``brow_right``/``brow_left`` (centres), ``eye_right``/``eye_left``, ``hairline`` (y, scalar).
    colours : dict
        ``skin``, ``lips``, ``hair`` as linear-ish RGB in 0..1.
    rng : numpy Generator
        Noise source (pores, freckles, hair strands).
    valid : (H, W) bool array, optional
        Texels that lie on the surface; others get the skin colour.

    Returns
    -------
    albedo : (H, W, 3) uint8
    masks : dict of (H, W) float32
        ``lips``, ``brows``, ``hair`` (1 inside); skin is what is left.
    """
    h, w = pts.shape[:2]
    x, y, z = pts[..., 0], pts[..., 1], pts[..., 2]
    skin = np.array(colours["skin"])
    noise = (0.55 * _value_noise((h, w), 48, rng) + 0.3 * _value_noise((h, w), 128, rng)
             + 0.15 * rng.standard_normal((h, w)))
    col = skin[None, None, :] * (1 + 0.035 * noise[..., None])
    col = col * (1 - 0.18 * ((rng.random((h, w)) < 0.004) * (z > 2))[..., None])
    ex = abs(float(anchors["eye_left"][0] - anchors["eye_right"][0])) / 2
    cy = float(anchors["eye_left"][1]) - 3.3
    blush = 0.5 * (_g(x, y, -1.25 * ex, cy, 1.5, 1.2) + _g(x, y, 1.25 * ex, cy, 1.5, 1.2)) * (z > 0)
    col = col * (1 - 0.10 * blush[..., None]) + np.array([0.75, 0.35, 0.35]) * 0.10 * blush[..., None]
    mx, my = float(anchors["mouth"][0]), float(anchors["mouth"][1])
    mh = float(anchors["mouth_half"])
    lips = np.clip(_g(x, y, mx, my + 0.35, mh * 0.8, 0.33) + _g(x, y, mx, my - 0.4, mh * 0.72, 0.38), 0, 1)
    lips = smoothstep(lips, 0.35, 0.6) * (z > 0)
    col = col * (1 - lips[..., None]) + np.array(colours["lips"]) * (1 + 0.04 * noise[..., None]) * lips[..., None]
    brows = np.zeros_like(x)
    for key in ("brow_right", "brow_left"):
        bx, by = float(anchors[key][0]), float(anchors[key][1])
        brows += _g(x, y, bx, by + 0.15 - 0.05 * (x - bx) ** 2, 1.45, 0.3)
    brows = smoothstep(brows * (1 + 0.3 * noise), 0.3, 0.7) * (z > 0)
    hair_col = np.array(colours["hair"])
    col = col * (1 - brows[..., None]) + hair_col * brows[..., None]
    hl = float(anchors["hairline"])
    hairline = hl - 3.2 * smoothstep(z, 2.0, -6.0)  # lower at the back of the head
    hair = np.clip(smoothstep(y - hairline, -0.25, 0.25) * (1 - smoothstep(z, 3.5, 6.5) * (y < hl + 2.3)), 0, 1)
    strands = 1 + 0.12 * _value_noise((h, w), 160, rng)
    col = col * (1 - hair[..., None]) + hair_col * strands[..., None] * hair[..., None]
    if valid is not None:
        col[~valid] = skin
    img = np.clip(col * 255, 0, 255).astype(np.uint8)
    return img, {"lips": lips.astype(np.float32), "brows": brows.astype(np.float32), "hair": hair.astype(np.float32)}


def value_noise3(pts: np.ndarray, cell: float, seed: int) -> np.ndarray:
    """Smooth 3D value noise in 0..1 at ``pts`` (lattice spacing ``cell``; hashed lattice values)."""
    q = pts / cell
    i0 = np.floor(q).astype(np.int64)
    f = q - i0
    f = f * f * (3 - 2 * f)
    out = np.zeros(len(pts))
    primes = np.array([73856093, 19349663, 83492791], np.uint64)
    for corner in range(8):
        o = np.array([(corner >> k) & 1 for k in range(3)])
        key = ((i0 + o).astype(np.uint64) * primes).sum(axis=1) ^ np.uint64(seed * 2654435761 % 2**32)
        key = (key * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(40)  # well-mixed top 24 bits
        w = np.prod(np.where(o == 1, f, 1 - f), axis=1)
        out += w * (key.astype(np.float64) / 2**24)
    return out


def paint_detail_maps_at(pts: np.ndarray, valid: np.ndarray, landmarks: dict[str, np.ndarray],
                         masks: dict[str, np.ndarray] | None = None, seed: int = 0, *,
                         pore_tilt: float = 0.06) -> tuple[np.ndarray, np.ndarray]:
    """Paint a skin-pore normal map and a specular map at 3D points (one per texel) of a face.

    Parameters
    ----------
    pts : (H, W, 3) array
        The neutral-face 3D point of every texel (texture row 0 = UV v 1).
    valid : (H, W) bool array
        Texels on the surface.
    landmarks : dict of str to (3,) arrays
        The rig's landmark points (``face_left``/``face_right``, ``brow_left``/``brow_right``,
        ``forehead_top``, ``nasion``, ``nose_tip``, ``chin``, ``mouth_left``/``mouth_right``).
    masks : dict of (H, W) arrays, optional
        ``lips``, ``brows``, ``hair`` of the albedo (lips shiny; no pores under hair and brows).
    seed : int
        Pore pattern.
    pore_tilt : float
        RMS tilt of the pore normals in radians (mild: 0.06 ≈ 3.4°).

    Returns
    -------
    normal : (H, W, 3) uint8
        Tangent-space normal map (OpenGL convention: R = +u, G = +v, B = out of the surface;
        flat = (128, 128, 255)); pores are small pits of 3D noise, so their size does not depend
        on how the UV layout stretches the skin.
    specular : (H, W) uint8
        Specularity, white = shiny, mid-grey = skin as without a map: forehead, nose, chin and
        lips shinier than the cheeks, brows and hair matt.
    """
    h, w = valid.shape
    width = float(np.linalg.norm(landmarks["face_left"] - landmarks["face_right"]))
    masks = masks or {}
    z = np.zeros((h, w))
    hair = np.clip(masks.get("hair", z) + masks.get("brows", z), 0, 1)
    lips = np.clip(masks.get("lips", z), 0, 1)
    p = pts[valid]
    pores = np.zeros((h, w))
    pores[valid] = (-smoothstep(value_noise3(p, width / 140, seed), 0.55, 0.85)
                    + 0.35 * value_noise3(p, width / 45, seed + 1))
    pores *= (1 - hair) * (1 - 0.7 * lips)
    # world-space slopes along +u (columns) and +v (rows upwards): the tangent-space gradient
    step_u = np.linalg.norm(np.gradient(pts, axis=1), axis=2)
    step_v = np.linalg.norm(np.gradient(pts, axis=0), axis=2)
    inner = valid.copy()
    inner[1:-1, 1:-1] &= valid[:-2, 1:-1] & valid[2:, 1:-1] & valid[1:-1, :-2] & valid[1:-1, 2:]
    inner[[0, -1], :] = False
    inner[:, [0, -1]] = False
    su = np.where(inner, np.gradient(pores, axis=1) / np.maximum(step_u, 1e-12), 0.0)
    sv = np.where(inner, -np.gradient(pores, axis=0) / np.maximum(step_v, 1e-12), 0.0)
    rms = float(np.sqrt(np.mean(su[inner] ** 2 + sv[inner] ** 2))) if inner.any() else 0.0
    k = pore_tilt / rms if rms > 0 else 0.0
    # at most ~20° (texels where the UV layout collapses, e.g. near a sphere's poles, would
    # otherwise give a few huge slopes)
    mag = np.maximum(np.hypot(su, sv) * k, 1e-12)
    k = k * np.minimum(1.0, 0.35 / mag)
    n = np.stack([-k * su, -k * sv, np.ones((h, w))], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    normal = np.clip(np.rint((n * 0.5 + 0.5) * 255), 0, 255).astype(np.uint8)

    def bump(centre: np.ndarray, sigma: float) -> np.ndarray:
        d2 = np.sum((pts - centre) ** 2, axis=-1)
        return np.exp(-d2 / (2 * (sigma * width) ** 2))

    brow_mid = (landmarks["brow_left"] + landmarks["brow_right"]) / 2
    forehead = brow_mid + 0.45 * (landmarks["forehead_top"] - brow_mid)
    mouth = (landmarks["mouth_left"] + landmarks["mouth_right"]) / 2
    bridge = (landmarks["nasion"] + landmarks["nose_tip"]) / 2
    spec = (0.42 + 0.25 * bump(forehead, 0.22) + 0.40 * bump(landmarks["nose_tip"], 0.08)
            + 0.25 * bump(bridge, 0.07) + 0.15 * bump(landmarks["chin"], 0.10) - 0.08 * bump(mouth, 0.25))
    spec = np.clip(spec, 0, 0.9) * (1 - lips) + 0.8 * lips
    spec = spec * (1 - 0.8 * hair) * (1 + 0.3 * pores)
    spec[~valid] = 0.5
    return normal, np.clip(np.rint(spec * 255), 0, 255).astype(np.uint8)


def _paint_texture(p: dict, size: int, rng: np.random.Generator) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The procedural head's albedo: the head surface is analytic, so every texel's 3D point is known."""
    v, u = np.meshgrid((np.arange(size) + 0.5) / size, (np.arange(size) + 0.5) / size, indexing="ij")
    pts = _head_surface(v * np.pi, (u - 0.5) * 2 * np.pi, p)  # texture row 0 = top of the head
    anchors = {"mouth": np.array([0.0, -4.3]), "mouth_half": 1.55 * p["mouth"], "brow_right": np.array([-3.0, 4.1]),
               "brow_left": np.array([3.0, 4.1]), "eye_right": np.array([-3.1, 2.6]), "eye_left": np.array([3.1, 2.6]),
               "hairline": 6.3}
    return paint_albedo_at(pts, anchors, {k: p[k] for k in ("skin", "lips", "hair")}, rng)


def _sphere(n_lat: int, n_lon: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lat/long grid: (θ, φ) per vertex, UVs, triangles (a duplicated seam column at the back)."""
    th = np.linspace(1e-3, np.pi - 1e-3, n_lat + 1)
    ph = np.linspace(-np.pi, np.pi, n_lon + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    uv = np.stack([(P / (2 * np.pi) + 0.5).ravel(), (1 - T / np.pi).ravel()], axis=1)
    idx = np.arange((n_lat + 1) * (n_lon + 1)).reshape(n_lat + 1, n_lon + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    return np.stack([T.ravel(), P.ravel()], axis=1), uv, faces


def _eyeball(centre: np.ndarray, radius: float, n: int = 24) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A small eyeball sphere facing +z: vertices, faces, is-iris flag per face."""
    (tp, _uv, f) = _sphere(n, n)
    th, ph = tp[:, 0], tp[:, 1]
    # pole along +z: rotate the lat/long sphere so θ = 0 looks forward
    vx = np.sin(th) * np.cos(ph)  # a cyclic permutation of the head's axes: a rotation, so
    vy = np.sin(th) * np.sin(ph)  # the triangles keep facing outwards
    vz = np.cos(th)
    v = centre + radius * np.stack([vx, vy, vz], axis=1)
    iris = th[f].mean(axis=1) < 0.62
    return v, f, iris


def _nearest(v: np.ndarray, point: tuple[float, float, float], pool: np.ndarray) -> np.ndarray:
    return np.array([pool[np.argmin(np.linalg.norm(v[pool] - np.asarray(point), axis=1))]])


def _field(v: np.ndarray, centre: tuple[float, float], s: tuple[float, float], disp: tuple[float, float, float],
           front: np.ndarray) -> np.ndarray:
    w = _g(v[:, 0], v[:, 1], centre[0], centre[1], s[0], s[1]) * front
    return w[:, None] * np.asarray(disp)[None, :]


def _blendshapes(v: np.ndarray, skin: np.ndarray, p: dict[str, float]) -> dict[str, np.ndarray]:
    """Displacement fields standing in for the ICT/ARKit shapes the FACS recipes use."""
    front = np.zeros(len(v))
    front[skin] = smoothstep(v[skin, 2], 0.0, 4.0)
    m = p["mouth"]
    spec: dict[str, list[tuple[tuple[float, float], tuple[float, float], tuple[float, float, float]]]] = {
        "browInnerUp": [((1.2, 4.0), (0.9, 0.7), (0, 0.55, 0))],
        "browOuterUp": [((3.6, 4.0), (1.0, 0.7), (0, 0.5, 0))],
        "browDown": [((2.2, 4.0), (1.6, 0.8), (-0.25, -0.45, 0.1))],
        "eyeWide": [((3.1, 3.2), (1.0, 0.5), (0, 0.25, 0))],
        "eyeSquint": [((3.1, 1.8), (1.1, 0.4), (0, 0.22, 0.05))],
        "eyeBlink": [((3.1, 3.1), (1.0, 0.5), (0, -0.3, 0.05))],
        "cheekSquint": [((3.6, 0.4), (1.4, 1.0), (0.05, 0.45, 0.2))],
        "noseSneer": [((0.9, 0.6), (0.7, 0.9), (0, 0.3, 0.05))],
        "mouthSmile": [((1.25 * m, -4.3), (0.8, 0.8), (0.45, 0.55, -0.15)), ((2.4, -2.0), (1.2, 1.2), (0.1, 0.25, 0.2))],
        "mouthDimple": [((1.5 * m, -4.3), (0.6, 0.6), (0.25, 0, -0.2))],
        "mouthFrown": [((1.25 * m, -4.4), (0.8, 0.8), (0.05, -0.5, 0))],
        "mouthLowerDown": [((0.5 * m, -4.75), (0.9, 0.35), (0, -0.25, 0))],
        "mouthPress": [((0.5 * m, -4.3), (1.0, 0.5), (0, 0, -0.2)), ((0.5 * m, -3.9), (1.0, 0.3), (0, -0.1, 0)),
                       ((0.5 * m, -4.75), (1.0, 0.3), (0, 0.12, 0))],
        # upper lip raiser (anger's snarl) and lip stretcher (corners pulled sideways)
        "mouthUpperUp": [((0.55 * m, -3.85), (0.8, 0.35), (0, 0.25, 0.05))],
        "mouthStretch": [((1.3 * m, -4.35), (0.7, 0.7), (0.35, -0.05, -0.1))],
    }
    out: dict[str, np.ndarray] = {}
    for name, fields in spec.items():
        for side, sgn in (("_L", 1.0), ("_R", -1.0)):  # _L = subject's left = +x
            d = np.zeros_like(v)
            for (cx, cy), s, (dx, dy, dz) in fields:
                d += _field(v, (sgn * cx, cy), s, (sgn * dx, dy, dz), front)
            out[name + side] = d
    # jaw open: the lower face rotates down about a hinge in front of the ears; lips part a little
    below = smoothstep(v[:, 1], -4.2, -4.9) * (v[:, 2] > -2)
    out["jawOpen"] = below[:, None] * np.array([0.0, -1.3, -0.35])[None, :]
    return out


@functools.lru_cache(maxsize=8)
def _cached(seed: int, texture_size: int, resolution: int) -> FaceRig:
    rng = np.random.default_rng(seed)
    j = lambda s: 1 + s * rng.uniform(-1, 1)  # noqa: E731
    p = {
        "rx": 7.4 * j(0.05), "ry": 10.6 * j(0.04), "rz": 9.6 * j(0.04), "jaw": 0.28 * j(0.25),
        "nose": 1.9 * j(0.15), "mouth": 1.6 * j(0.1),
        "skin": tuple(np.array([0.80, 0.60, 0.50]) * j(0.12)),
        "lips": (0.62, 0.30, 0.30), "hair": tuple(np.array([0.22, 0.14, 0.09]) * j(0.3)),
    }
    tp, uv, faces = _sphere(resolution, int(resolution * 1.25))
    head = _head_surface(tp[:, 0], tp[:, 1], p)
    n_head = len(head)
    eye_c = [(-3.1, 2.6, 0.0), (3.1, 2.6, 0.0)]
    ecz = float(_head_surface(np.array([np.arccos(2.6 / p["ry"])]), np.array([np.arcsin(3.1 / p["rx"])]), p)[0, 2])
    verts, fs, parts, uvs = [head], [faces], [np.zeros(len(faces), int)], [uv]
    eye_sets = []
    for cx, cy, _ in eye_c:
        c = np.array([cx, cy, ecz - 0.45])
        ev, ef, iris = _eyeball(c, 1.2)
        off = sum(len(a) for a in verts)
        eye_sets.append(np.arange(off, off + len(ev)))
        # UVs about the gaze axis and a sclera/iris/pupil texture (stimulus_engine.parts.eyes)
        verts.append(ev); fs.append(ef + off); parts.append(np.ones(len(ef), int))
        uvs.append(eyeball_uv(ev, c, np.array([0.0, 0.0, 1.0])))
    v = np.concatenate(verts)
    f = np.concatenate(fs)
    skin = np.arange(n_head)
    pool = skin[v[skin, 2] > 0]

    def at(x: float, y: float) -> np.ndarray:  # the front-most skin vertex near (x, y)
        d = np.linalg.norm(v[pool, :2] - np.array([x, y]), axis=1)
        # within 0.6 units, or (coarse meshes, where that can be empty) the nearest in x/y:
        # falling back to the whole face would put the landmark on the nose
        cand = pool[d < max(0.6, 1.5 * float(d.min()))]
        return _nearest(v, (x, y, v[cand, 2].max()), cand)

    m = p["mouth"]
    lms = {
        "eye_right": eye_sets[0], "eye_left": eye_sets[1],
        "eye_right_outer": at(-4.35, 2.6), "eye_right_inner": at(-1.85, 2.6),
        "eye_right_top": at(-3.1, 3.45), "eye_right_bottom": at(-3.1, 1.75),
        "eye_left_outer": at(4.35, 2.6), "eye_left_inner": at(1.85, 2.6),
        "eye_left_top": at(3.1, 3.45), "eye_left_bottom": at(3.1, 1.75),
        "nasion": at(0, 2.6), "subnasale": at(0, -2.6), "nose_tip": at(0, -0.9),
        "nose_right": at(-1.2, -1.9), "nose_left": at(1.2, -1.9),
        "mouth_right": at(-1.55 * m, -4.3), "mouth_left": at(1.55 * m, -4.3),
        "mouth_top": at(0, -3.8), "mouth_bottom": at(0, -4.8), "chin": at(0, -p["ry"] * 0.86),
        "face_right": _nearest(v, (-p["rx"], 1.0, 0.0), skin), "face_left": _nearest(v, (p["rx"], 1.0, 0.0), skin),
        "forehead_top": at(0, 6.3), "brow_right": np.concatenate([at(-2.0, 4.1), at(-3.0, 4.2), at(-4.0, 4.1)]),
        "brow_left": np.concatenate([at(2.0, 4.1), at(3.0, 4.2), at(4.0, 4.1)]),
        **{f"pupil_{side}": pupil_ring(v, ball, np.array([cx, cy, ecz - 0.45]), np.array([0.0, 0.0, 1.0]))
           for side, ball, (cx, cy, _) in zip(("right", "left"), eye_sets, eye_c)},
    }
    tex, masks = _paint_texture(p, texture_size, rng)
    return FaceRig(
        name=f"procedural_{seed}", vertices=v, faces=f, uv=np.concatenate(uvs), face_uv=f.copy(), face_part=np.concatenate(parts),
        part_names=_PARTS, landmarks=lms, blendshapes=_blendshapes(v, skin, p), rigid_sets=eye_sets, skin=skin,
        texture=tex, texture_masks=masks, part_textures={"eye": tint_iris(photographic_eye_texture(256), np.array([64.0, 82.0, 107.0]))},
    )


def procedural_head(seed: int = 0, *, texture_size: int = 1024, resolution: int = 96) -> FaceRig:
    """A textured, rigged head generated by code (no files, no downloads).

    Parameters
    ----------
    seed : int
        Proportions, skin and hair colour, and texture noise derive from it; same seed → same head.
    texture_size : int
        Albedo texture edge length in pixels.
    resolution : int
        Latitude rows of the head mesh (longitude columns are 1.25 × that).

    Returns
    -------
    FaceRig
        Centimetre units, +y up, face towards +z; parts ``skin`` and ``eye``; every
        blendshape the FACS recipes use; UV texture with ``lips``/``brows``/``hair`` masks.
        The returned rig is shared between calls with the same arguments: do not modify it
        in place (use :meth:`FaceRig.with_vertices`).

    Examples
    --------
    >>> rig = procedural_head(seed=1, texture_size=128, resolution=32)
    >>> rig.texture.shape, "mouthSmile_L" in rig.blendshapes
    ((128, 128, 3), True)
    """
    return _cached(int(seed), int(texture_size), int(resolution))
