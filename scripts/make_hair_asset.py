"""Rebuild ``stimulus_engine/data/hair/`` from MakeHuman's CC0 hair styles (:data:`STYLES`).

Each hair mesh is placed on MakeHuman's base mesh by its ``.mhclo`` fitting file (each hair
vertex a barycentric combination of three base vertices plus an offset scaled by the base's
proportions). Every hair vertex is then stored as its *anchor* (the closest point of the base's
head, above the neck), its *lift* above it along the head's normal and its whole *offset* from
it (for locks that hang away from the head), with seven head points of the base (eye centres,
top, back and the two sides of the cranium): :func:`stimulus_engine.parts.hair.fit_hair` puts
the same anchors on any rig's head. MakeHuman's hair textures are not in the CC0 release, so
each strand texture (``STYLE.png``: grey strands, alpha = hair) is synthesised here: noise
smeared along the combing direction (line-integral convolution along the gradient of the
distance to the hairline), with strand tips of varied length at the hairline.

Usage::

    python scripts/make_hair_asset.py ../shared/data/meshes/makehuman-cc0
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image
from scipy import ndimage

from stimulus_engine.geometry.closest import SurfaceIndex
from stimulus_engine.parts.hair import head_points
from stimulus_engine.geometry.obj_format import parse_obj
from stimulus_engine.geometry.uv_raster import rasterize_uv

OUT = Path(__file__).resolve().parents[1] / "stimulus_engine" / "data" / "hair"
SIZE = 512
#: The styles built (MakeHuman's CC0 hair proxies).
STYLES = ("short01", "short02", "short03", "short04", "bob02", "long01", "afro01", "ponytail01")


def mhclo_vertices(base: np.ndarray, mhclo: Path) -> np.ndarray:
    """Proxy vertices on ``base`` from a MakeHuman ``.mhclo`` file (``verts`` section)."""
    scale, rows, inside = {}, [], False
    for line in mhclo.read_text().splitlines():
        w = line.split()
        if not w or w[0].startswith("#"):
            continue
        if w[0] in ("x_scale", "y_scale", "z_scale"):
            scale[w[0][0]] = (int(w[1]), int(w[2]), float(w[3]))
        elif w[0] == "verts":
            inside = True
        elif inside and len(w) == 9:
            rows.append([float(x) for x in w])
        elif inside and len(w) == 1:
            rows.append([float(w[0])] * 3 + [1, 0, 0, 0, 0, 0])
        elif inside and rows:  # the verts section ends (lines such as 'material' may come before it starts)
            break
    r = np.array(rows)
    s = np.array([abs(base[scale[a][0], i] - base[scale[a][1], i]) / scale[a][2] for i, a in enumerate("xyz")])
    idx = r[:, :3].astype(np.int64)
    return np.einsum("nk,nkd->nd", r[:, 3:6], base[idx]) + r[:, 6:9] * s


#: Where a fringe is cut, in inter-ocular distances above the eye centres, between the temples
#: (short02's fringe hangs to 0.41, onto the brows of a rig: it read as a bowl cut over painted
#: eyebrows); hair beside the face (further than FRINGE_HALF_WIDTH_IOD from the midline) hangs on.
FRINGE_CUT_IOD, FRINGE_HALF_WIDTH_IOD = 0.8, 1.0


def strand_texture(faces: np.ndarray, face_uv: np.ndarray, uv: np.ndarray, vertices: np.ndarray,
                   eyes: list[np.ndarray], seed: int = 0) -> np.ndarray:
    """(SIZE, SIZE, 4) uint8: grey strands combed away from the crown, alpha 0 past the hairline
    and below the fringe cut in front of the temples."""
    rng = np.random.default_rng(seed)
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    edges = mesh.edges_sorted
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    rim = np.unique(uniq[count == 1])  # the hairline: the mesh's boundary in 3D
    dist = np.linalg.norm(vertices[:, None, :] - vertices[rim][None, :, :], axis=2).min(axis=1)
    mid, iod = (eyes[0] + eyes[1]) / 2, float(np.linalg.norm(eyes[1] - eyes[0]))
    front = (vertices[:, 2] > mid[2] - 0.4 * iod) & (np.abs(vertices[:, 0] - mid[0]) < FRINGE_HALF_WIDTH_IOD * iod)
    dist = np.where(front, np.minimum(dist, vertices[:, 1] - (mid[1] + FRINGE_CUT_IOD * iod)), dist)
    rows, cols, face, bary = rasterize_uv(uv, face_uv, SIZE, SIZE)
    inside = np.zeros((SIZE, SIZE), bool)
    inside[rows, cols] = True
    d = np.zeros((SIZE, SIZE))
    d[rows, cols] = np.einsum("nk,nk->n", bary, dist[faces[face]])
    d = d / np.percentile(d[inside], 95)  # 0 at the hairline .. ~1 at the crown (< 0 cut off)
    # fill outside the islands with the nearest inside value (smooth gradients at the edges)
    near = ndimage.distance_transform_edt(~inside, return_distances=False, return_indices=True)
    d = d[near[0], near[1]]
    gy, gx = np.gradient(ndimage.gaussian_filter(d, 3))
    norm = np.hypot(gx, gy) + 1e-9
    dx, dy = gx / norm, gy / norm
    noise = rng.random((SIZE, SIZE))
    # line-integral convolution: average the noise along the combing direction
    acc, ys, xs = noise.copy(), *np.mgrid[0:SIZE, 0:SIZE].astype(np.float64)
    for sign in (1.0, -1.0):
        y, x = ys.copy(), xs.copy()
        for _ in range(24):
            iy, ix = np.clip(np.rint(y), 0, SIZE - 1).astype(int), np.clip(np.rint(x), 0, SIZE - 1).astype(int)
            y, x = y + sign * dy[iy, ix], x + sign * dx[iy, ix]
            acc += ndimage.map_coordinates(noise, [y, x], order=1, mode="nearest")
    strands = (acc - acc.mean()) / acc.std()
    broad = ndimage.gaussian_filter(rng.standard_normal((SIZE, SIZE)), 10)
    grey = np.clip(0.72 + 0.16 * strands + 1.5 * broad, 0.25, 1.0)
    # tips: strands end at different distances from the hairline (alpha-tested, so 0 or 255)
    tip = 0.05 + 0.05 * np.clip(strands, -2, 2)
    alpha = inside & (d > tip)
    rgba = np.zeros((SIZE, SIZE, 4), np.uint8)
    rgba[..., :3] = np.rint(255 * grey)[..., None]
    rgba[..., 3] = np.where(alpha, 255, 0)
    # texels outside the islands repeat the nearest inside one (colour and alpha): filtering and
    # mipmaps then draw no dark line or gap along the UV seams, and the hairline keeps its tips
    return rgba[near[0], near[1]]


def build_style(style: str, src: Path, out: Path, base, head_faces: np.ndarray, eyes: list[np.ndarray],
                head: np.ndarray) -> None:
    """Write ``out/STYLE.npz`` and ``out/STYLE.png`` for one hair style."""
    v = base.vertices
    hair = parse_obj(src / "proxies" / f"{style}.obj")
    p = mhclo_vertices(v, src / "proxies" / f"{style}.mhclo")
    hit = SurfaceIndex(v, head_faces).query(p)
    anchors = np.einsum("nk,nkd->nd", hit.bary, v[head_faces[hit.face]])
    normals = trimesh.Trimesh(v, head_faces, process=False).vertex_normals
    n = np.einsum("nk,nkd->nd", hit.bary, normals[head_faces[hit.face]])
    lift = np.einsum("nd,nd->n", p - anchors, n / np.linalg.norm(n, axis=1, keepdims=True))
    # one render vertex per (vertex, uv) pair: the texture's seams stay sharp
    pairs, inv = np.unique(np.stack([hair.faces.ravel(), hair.face_uv.ravel()], axis=1), axis=0, return_inverse=True)
    np.savez_compressed(out / f"{style}.npz", anchors=anchors[pairs[:, 0]].astype(np.float32),
                        lift=lift[pairs[:, 0]].astype(np.float32), offset=(p - anchors)[pairs[:, 0]].astype(np.float32),
                        head=head.astype(np.float32), faces=inv.reshape(-1, 3).astype(np.int32),
                        uv=hair.uv_coords[pairs[:, 1]].astype(np.float32))
    rgba = strand_texture(hair.faces, hair.face_uv, hair.uv_coords, p, eyes)
    Image.fromarray(rgba).convert("LA").save(out / f"{style}.png", optimize=True)  # grey strands and alpha
    print(f"{out / style}: {len(pairs)} vertices, {len(hair.faces)} faces")


def main(src: Path, out: Path = OUT, styles: tuple[str, ...] = STYLES) -> None:
    base = parse_obj(src / "base.obj")
    body = base.faces[base.face_group == base.groups.index("body")]
    v = base.vertices
    eyes = [v[np.unique(base.faces[base.face_group == base.groups.index(f"joint-{s}-eye")])].mean(axis=0)
            for s in ("r", "l")]
    # anchors on the head only (above the neck's joint): a lock hanging to the shoulders is
    # carried by the head it grows from, not by the shoulder it lies on
    neck_y = v[np.unique(base.faces[base.face_group == base.groups.index("joint-neck")])].mean(axis=0)[1]
    head_faces = body[(v[body, 1] > neck_y).all(axis=1)]
    head = head_points(v[np.unique(body)], *eyes)
    out.mkdir(parents=True, exist_ok=True)
    for style in styles:
        build_style(style, src, out, base, head_faces, eyes, head)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    main(Path(sys.argv[1]))
