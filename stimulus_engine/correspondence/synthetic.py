"""Synthetic face pairs made by code: embedded defaults for tests, the demo and benchmarks.

A face is a height field over an elliptic disc (forehead dome, brow ridge, eye sockets with
eyeballs, nose, lips, chin) with UVs = its (x, y) parameters and a painted texture. A
*stylised* version scales the eyes and the nose (the thesis's stylisation examples: bigger
eyes, smaller nose) and is tessellated differently (a jittered point set instead of a grid),
so the pair differs in proportions and in topology, like a scan and a cartoon.
"""

from __future__ import annotations

import numpy as np
import trimesh
from PIL import Image
from scipy.spatial import Delaunay

__all__ = ["face_height", "face_points", "synthetic_face", "synthetic_landmarks", "synthetic_pair", "LANDMARK_NAMES"]

_RX, _RY = 0.8, 1.0
_EYE_X, _EYE_Y = 0.32, 0.22


def _g(x, y, cx, cy, sx, sy):
    return np.exp(-((x - cx) ** 2) / (2 * sx**2) - ((y - cy) ** 2) / (2 * sy**2))


def _ridge(x: np.ndarray, y: np.ndarray, n: float, hook: float) -> np.ndarray:
    """The nose ridge and tip: a Gaussian, steeper below its crest when ``hook`` > 0."""
    sy = np.where(y < -0.02, 0.20 * n * (1.0 - 0.7 * hook), 0.20 * n)
    return 0.28 * n * np.exp(-(x**2) / (2 * (0.07 * n) ** 2) - ((y + 0.02) ** 2) / (2 * sy**2))


def face_height(x: np.ndarray, y: np.ndarray, eyes: float = 1.0, nose: float = 1.0, nose_hook: float = 0.0) -> np.ndarray:
    """Height z(x, y) of the synthetic face; ``eyes``/``nose`` scale those features' size,
    ``nose_hook`` makes the underside of the nose steep (see :func:`face_points`)."""
    r2 = (x / _RX) ** 2 + (y / _RY) ** 2
    z = 0.45 * np.sqrt(np.clip(1.0 - 0.8 * r2, 0.0, None))
    z += 0.05 * _g(x, y, 0.0, 0.42, 0.5, 0.06)  # brow ridge
    for sx in (-1, 1):
        ex = sx * _EYE_X
        s = 0.09 * eyes
        z -= 0.10 * _g(x, y, ex, _EYE_Y, 1.3 * s, s)  # socket
        z += 0.07 * _g(x, y, ex, _EYE_Y, 0.8 * s, 0.6 * s)  # eyeball
    n = nose
    z += _ridge(x, y, n, nose_hook)  # nose ridge and tip
    z += 0.06 * n * _g(x, y, 0.0, -0.16 * n, 0.14 * n, 0.05 * n)  # nostril wings
    z += 0.05 * _g(x, y, 0.0, -0.44, 0.22, 0.035) - 0.03 * _g(x, y, 0.0, -0.49, 0.20, 0.012)  # lips
    z += 0.05 * _g(x, y, 0.0, -0.78, 0.18, 0.08)  # chin
    return z


def face_points(
    x: np.ndarray, y: np.ndarray, eyes: float = 1.0, nose: float = 1.0, nose_hook: float = 0.0
) -> np.ndarray:
    """3D points (N, 3) of the face at parameters (x, y).

    ``nose_hook`` in [0, 1] makes a hooked cartoon nose: the ridge below its crest gets
    steeper (its width in y shrinks by ``1 - 0.7 nose_hook``) and every point of the ridge
    moves down (-y) by ``nose_hook`` times its ridge height. From ``nose_hook`` ≈ 0.65 on,
    the steep underside turns to face downwards and overhangs the nostril wings and upper lip
    (like the tip and columella of a real nose, or the ear of the thesis's Fig. 3.2): the
    surface is no longer a height field over (x, y). It stays embedded (points with the same
    x and z keep their order in y).
    """
    z = face_height(x, y, eyes, nose, nose_hook)
    yy = y - nose_hook * _ridge(x, y, nose, nose_hook) if nose_hook else y
    return np.column_stack([x, yy, z])


#: Names of :func:`synthetic_landmarks` rows.
LANDMARK_NAMES = (
    "eye_r_out", "eye_r_in", "eye_l_in", "eye_l_out", "nose_tip", "nose_wing_r", "nose_wing_l",
    "mouth_r", "mouth_l", "lip_top", "chin", "brow_r", "brow_l", "cheek_r", "cheek_l", "forehead",
)


def synthetic_landmarks(eyes: float = 1.0, nose: float = 1.0, nose_hook: float = 0.0) -> np.ndarray:
    """16 feature points (x, y, z) of the face with these proportions (:data:`LANDMARK_NAMES`)."""
    e = 0.12 * eyes
    xy = np.array([
        [-_EYE_X - e, _EYE_Y], [-_EYE_X + e, _EYE_Y], [_EYE_X - e, _EYE_Y], [_EYE_X + e, _EYE_Y],
        [0.0, -0.02 - 0.12 * nose], [-0.12 * nose, -0.16 * nose], [0.12 * nose, -0.16 * nose],
        [-0.22, -0.47], [0.22, -0.47], [0.0, -0.41], [0.0, -0.80], [-_EYE_X, 0.42], [_EYE_X, 0.42],
        [-0.45, -0.15], [0.45, -0.15], [0.0, 0.70],
    ])
    return face_points(xy[:, 0], xy[:, 1], eyes, nose, nose_hook)


def _texture(size: int, eyes: float, nose: float) -> Image.Image:
    """Skin with darker brows, eyes and lips at this face's feature positions (UV = (x, y))."""
    u, v = np.meshgrid((np.arange(size) + 0.5) / size, 1 - (np.arange(size) + 0.5) / size)
    x, y = (u - 0.5) * 2 * _RX, (v - 0.5) * 2 * _RY
    skin = np.array([0.85, 0.66, 0.55])
    img = np.ones((size, size, 3)) * skin
    def paint(mask, colour):
        nonlocal img
        img = img * (1 - mask[..., None]) + mask[..., None] * np.asarray(colour)
    for sx in (-1, 1):
        paint(_g(x, y, sx * _EYE_X, _EYE_Y, 0.08 * eyes, 0.045 * eyes) ** 0.5 * 0.95, (0.95, 0.95, 0.95))
        paint(_g(x, y, sx * _EYE_X, _EYE_Y, 0.035 * eyes, 0.035 * eyes) ** 0.5 * 0.95, (0.25, 0.35, 0.6))
        paint(_g(x, y, sx * _EYE_X, 0.40, 0.12, 0.02) * 0.9, (0.3, 0.2, 0.12))
    paint(_g(x, y, 0.0, -0.46, 0.20, 0.035) * 0.9, (0.75, 0.3, 0.3))
    paint(_g(x, y, 0.0, -0.16 * nose, 0.05 * nose, 0.03 * nose) * 0.5, (0.6, 0.4, 0.35))
    return Image.fromarray(np.clip(img * 255, 0, 255).astype(np.uint8))


def synthetic_face(
    n_vertices: int = 3000,
    eyes: float = 1.0,
    nose: float = 1.0,
    tessellation: str = "grid",
    seed: int = 0,
    texture_size: int = 256,
    nose_hook: float = 0.0,
) -> trimesh.Trimesh:
    """A textured face mesh (open, disc topology) with about ``n_vertices`` vertices.

    Parameters
    ----------
    tessellation : {"grid", "jitter"}
        A regular grid clipped to the face outline, or jittered random points (a different
        triangulation of the same kind of surface).
    nose_hook : float
        Hook the nose down over the upper lip (see :func:`face_points`; 0 = none).
    """
    rng = np.random.default_rng(seed)
    area = np.pi * _RX * _RY
    n_ring = int(2 * np.sqrt(n_vertices * np.pi))
    n_in = max(n_vertices - n_ring, 10)
    h = np.sqrt(area / n_in)
    if tessellation == "grid":
        xs = np.arange(-_RX, _RX + h, h)
        ys = np.arange(-_RY, _RY + h, h * np.sqrt(3) / 2)
        gx, gy = np.meshgrid(xs, ys)
        gx = gx + (np.arange(len(ys))[:, None] % 2) * h / 2
        pts = np.column_stack([gx.ravel(), gy.ravel()])
    elif tessellation == "jitter":
        pts = rng.uniform([-_RX, -_RY], [_RX, _RY], size=(int(n_in * 4 / np.pi) + 1, 2))
    else:
        raise ValueError(f"tessellation must be 'grid' or 'jitter' (got {tessellation!r})")
    inside = (pts[:, 0] / _RX) ** 2 + (pts[:, 1] / _RY) ** 2 < (1 - 0.6 * h / _RY) ** 2
    pts = pts[inside]
    if tessellation == "jitter":
        # thin out points that are too close (keeps triangles well shaped)
        from scipy.spatial import cKDTree

        keep = np.ones(len(pts), dtype=bool)
        for i, j in sorted(cKDTree(pts).query_pairs(0.55 * h)):
            if keep[i] and keep[j]:
                keep[j] = False
        pts = pts[keep]
    t = np.linspace(0, 2 * np.pi, n_ring, endpoint=False)
    ring = np.column_stack([_RX * np.cos(t), _RY * np.sin(t)])
    pts = np.vstack([pts, ring])
    tri = Delaunay(pts).simplices
    # drop slivers Delaunay makes along the convex outline (all three vertices on the ring)
    on_ring = np.zeros(len(pts), dtype=bool)
    on_ring[-n_ring:] = True
    tri = tri[~on_ring[tri].all(axis=1)]
    v = face_points(pts[:, 0], pts[:, 1], eyes, nose, nose_hook)
    # orient faces towards +z in the (x, y) parameter plane (the same as in 3D without a droop)
    e1, e2 = pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]]
    back = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    tri[back] = tri[back][:, ::-1]
    used = np.unique(tri)
    remap = np.full(len(v), -1)
    remap[used] = np.arange(len(used))
    v, tri, pts = v[used], remap[tri], pts[used]
    uv = np.column_stack([pts[:, 0] / (2 * _RX) + 0.5, pts[:, 1] / (2 * _RY) + 0.5])
    mat = trimesh.visual.material.SimpleMaterial(image=_texture(texture_size, eyes, nose))
    mesh = trimesh.Trimesh(v, tri, visual=trimesh.visual.TextureVisuals(uv=uv, material=mat), process=False)
    hook = f", nose_hook={nose_hook}" if nose_hook else ""
    mesh.metadata["source_path"] = f"synthetic_face(eyes={eyes}, nose={nose}{hook}, {tessellation})"
    return mesh


def synthetic_pair(
    n_source: int = 3000,
    n_target: int = 2000,
    eyes: float = 1.6,
    nose: float = 0.6,
    seed: int = 0,
    texture_size: int = 256,
    nose_hook: float = 0.0,
):
    """Source (grid, plain proportions) and stylised target (jittered, ``eyes``/``nose`` scaled)
    with their correspondences: the 16 feature points plus boundary-loop pairs filled from
    four anchors (top, bottom, left, right of the outline).

    ``nose_hook`` hooks the target's nose down over its upper lip (:func:`face_points`).

    Returns
    -------
    source, target : trimesh.Trimesh
    corr : Correspondences
    """
    from stimulus_engine.correspondence.boundary import boundary_correspondences, nearest_boundary_vertices
    from stimulus_engine.correspondence.points import Correspondences, parse_points

    src = synthetic_face(n_source, 1.0, 1.0, "grid", seed, texture_size)
    tgt = synthetic_face(n_target, eyes, nose, "jitter", seed + 1, texture_size, nose_hook)
    corr = Correspondences(
        parse_points(synthetic_landmarks(1.0, 1.0), src, "source landmarks", snap_tolerance=0.1),
        parse_points(synthetic_landmarks(eyes, nose, nose_hook), tgt, "target landmarks", snap_tolerance=0.1),
    )
    ends = np.array([[0, _RY, 0], [0, -_RY, 0], [_RX, 0, 0], [-_RX, 0, 0]], dtype=float)
    a = nearest_boundary_vertices(src.vertices, src.faces, ends)
    b = nearest_boundary_vertices(tgt.vertices, tgt.faces, ends)
    corr = corr.concat(boundary_correspondences(src.vertices, src.faces, tgt.vertices, tgt.faces, list(zip(a, b))))
    return src, tgt, corr
