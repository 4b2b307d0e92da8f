"""Rebuild ``stimulus_engine/data/body/`` from MakeHuman's CC0 base mesh: a neck, shoulders and
upper chest ("bust") in a plain crew-neck garment.

The base mesh stands in MakeHuman's A pose (arms 40 degrees from the body); its arms are turned
down about the shoulder joints by :data:`ARM_DROP_DEG` (a smooth weight across the shoulder, so
the deltoid bends instead of breaking), and the mesh is cut to the part a head-and-shoulders
portrait shows: from under the jaw (the back of the neck up to the skull) down to
:data:`Y_LOW`. Its triangles are cut along a crew neckline (:func:`stimulus_engine.parts.body.neckline`,
lower in front than at the back; :func:`split_at_zero`), so the garment's edge is a smooth line, and every face
is marked neck skin or garment. The garment's
texture (``jersey.png``: a fine knit, grey, multiplied by the garment colour) is synthesised
here. :func:`stimulus_engine.parts.body.fit_body` joins the bust to any character's neck.

Usage::

    python scripts/make_body_asset.py ../shared/data/meshes/makehuman-cc0
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage

from stimulus_engine.geometry.obj_format import parse_obj
from stimulus_engine.geometry.ramps import smoothstep
from stimulus_engine.parts.body import neck_axis, neckline

OUT = Path(__file__).resolve().parents[1] / "stimulus_engine" / "data" / "body"
#: Lowest height kept (base-mesh units, decimetres; the eyes are at 7.28, the shoulders at 5.25).
Y_LOW = 3.9
#: How far the arms are turned down from MakeHuman's A pose, about the shoulder joints.
ARM_DROP_DEG = 32.0
#: Half-width kept: the arms are cut beyond it (below the frame's bottom in a portrait).
X_MAX = 3.0


def _joint(base, name: str) -> np.ndarray:
    return base.vertices[np.unique(base.faces[base.face_group == base.groups.index(name)])].mean(axis=0)


def drop_arms(v: np.ndarray, shoulder_r: np.ndarray, shoulder_l: np.ndarray, degrees: float) -> np.ndarray:
    """Vertices with the arms turned down about the shoulder joints (weight 0 on the chest,
    1 on the arm: a smoothstep across the shoulder)."""
    out = v.copy()
    for joint, sign in ((shoulder_r, -1.0), (shoulder_l, 1.0)):
        w = smoothstep((sign * v[:, 0] - (abs(joint[0]) - 0.35)) / 0.7)
        side = sign * v[:, 0] > 0
        a = np.radians(-sign * degrees) * w
        dx, dy = v[:, 0] - joint[0], v[:, 1] - joint[1]
        c, s = np.cos(a), np.sin(a)
        out[side, 0] = (joint[0] + c * dx - s * dy)[side]
        out[side, 1] = (joint[1] + s * dx + c * dy)[side]
    return out


def split_at_zero(v: np.ndarray, faces: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cut the triangles that ``f`` (a value per vertex) changes sign in along its zero line
    (linear along each edge), so the line runs along edges: new vertices, faces, and for each
    face whether it lies where ``f < 0``."""
    f = np.where(f == 0, 1e-9, f)
    verts, new_faces, below = list(v), [], []
    made: dict[tuple[int, int], int] = {}

    def cut(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in made:
            t = f[a] / (f[a] - f[b])
            verts.append(v[a] + t * (v[b] - v[a]))
            made[key] = len(verts) - 1
        return made[key]

    for tri in faces:
        neg = f[tri] < 0
        if neg.all() or not neg.any():
            new_faces.append(tri)
            below.append(bool(neg[0]))
            continue
        lone = int(np.flatnonzero(neg if neg.sum() == 1 else ~neg)[0])  # the corner alone on its side
        a, b, c = tri[lone], tri[(lone + 1) % 3], tri[(lone + 2) % 3]
        ab, ac = cut(a, b), cut(a, c)
        new_faces += [[a, ab, ac], [ab, b, c], [ab, c, ac]]
        below += [bool(neg[lone]), not neg[lone], not neg[lone]]
    return np.array(verts), np.array(new_faces), np.array(below)


def jersey_texture(size: int = 256, seed: int = 0) -> np.ndarray:
    """(size, size) uint8: a fine knit (rows of small loops) with soft blotches, mean about 200."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:size, 0:size].astype(np.float64)
    loops = 0.5 + 0.5 * np.cos(2 * np.pi * x / 4) * np.cos(2 * np.pi * (y + 2 * (x // 4 % 2)) / 5)
    fibre = ndimage.gaussian_filter(rng.standard_normal((size, size)), 0.7)
    blotch = ndimage.gaussian_filter(rng.standard_normal((size, size)), 12, mode="wrap")
    g = 0.8 + 0.06 * loops + 0.05 * fibre / fibre.std() + 0.6 * blotch
    return np.clip(np.rint(255 * g), 0, 255).astype(np.uint8)


def main(src: Path, out: Path = OUT) -> None:
    base = parse_obj(src / "base.obj")
    body = base.faces[base.face_group == base.groups.index("body")]
    eyes = [_joint(base, f"joint-{s}-eye") for s in ("r", "l")]
    neck = _joint(base, "joint-neck")
    v = drop_arms(base.vertices, _joint(base, "joint-r-shoulder"), _joint(base, "joint-l-shoulder"), ARM_DROP_DEG)
    # under the jaw in front, up to the skull at the back of the neck
    keep = (v[:, 1] > Y_LOW) & (np.abs(v[:, 0]) < X_MAX) & ((v[:, 1] < neck[1] + 0.3) | ((v[:, 2] < 0.3) & (v[:, 1] < 6.6)))
    faces = body[keep[body].all(axis=1)]
    used, faces = np.unique(faces, return_inverse=True)
    faces = faces.reshape(-1, 3)
    axis = neck_axis(v, body, *eyes)
    verts, faces, cloth_face = split_at_zero(v[used], faces, neckline(v[used], axis, *eyes))
    # a vertex is garment when any face of it is (the neckline's own vertices wear the garment's
    # edge); the neck skin's faces are those above the line
    cloth = np.zeros(len(verts), bool)
    cloth[faces[cloth_face].ravel()] = True
    out.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out / "bust.npz", vertices=verts.astype(np.float32), faces=faces.astype(np.int32),
                        cloth=cloth, cloth_face=cloth_face, eyes=np.array(eyes, np.float32), axis=axis.astype(np.float32))
    Image.fromarray(jersey_texture()).save(out / "jersey.png", optimize=True)
    print(f"{out}: {len(verts)} vertices, {len(faces)} faces, {int(cloth.sum())} in the garment")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    main(Path(sys.argv[1]))
