"""Write the rig landmarks of GDQuest's Sophia (``data:gdquest-sophia/sophia.glb``) as a design's
``landmarks`` file: ``protocols/grids/designs/sophia_landmarks.yaml``.

Sophia's eyes and mouth are painted decals (flat patches in front of the face, textured with the
eye and the line of the mouth). Each decal's painted region (dark, opaque texels of the half of
its texture its UVs use: the open eye) is mapped through the decal's UVs onto the patch; an eye's
corners and lid apexes are the ends of the axes of that region's moment ellipse (two standard
deviations: a uniform ellipse's semi-axes), the mouth's corners its leftmost and rightmost points,
its lips' middle the highest and lowest points near the midline. The nose (a small modelled
button), chin, forehead and the face's sides are read off the head's surface by the rules below.
Every point is then put on the head's skin along the view direction (the decals float in front).

Usage::

    python scripts/design_landmarks.py ../shared/data/meshes/gdquest-sophia/sophia.glb > protocols/grids/designs/sophia_landmarks.yaml
"""

from __future__ import annotations

import sys

import numpy as np
import trimesh


def uv_to_3d(mesh: trimesh.Trimesh, uvs: np.ndarray) -> np.ndarray:
    """Points of ``mesh`` at texture coordinates ``uvs`` (the first triangle holding each; others dropped)."""
    uv, f, v = np.asarray(mesh.visual.uv), np.asarray(mesh.faces), np.asarray(mesh.vertices)
    a, b, c = uv[f[:, 0]], uv[f[:, 1]], uv[f[:, 2]]
    e0, e1 = b - a, c - a
    d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)
    den = np.where(d00 * d11 - d01 * d01 == 0, 1e-30, d00 * d11 - d01 * d01)
    out = []
    for p in uvs:
        e2 = p - a
        d20, d21 = (e2 * e0).sum(1), (e2 * e1).sum(1)
        w1, w2 = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
        w0 = 1 - w1 - w2
        hit = np.flatnonzero((w0 >= -1e-6) & (w1 >= -1e-6) & (w2 >= -1e-6))
        if len(hit):
            i = hit[0]
            out.append(w0[i] * v[f[i, 0]] + w1[i] * v[f[i, 1]] + w2[i] * v[f[i, 2]])
    return np.array(out)


def painted_points(decal: trimesh.Trimesh, limit: int = 3000) -> np.ndarray:
    """3-D points of the decal's dark, opaque texels (the painted eye or mouth)."""
    tex = np.asarray(decal.visual.material.baseColorTexture.convert("RGBA")).astype(float)
    h, w = tex.shape[:2]
    ys, xs = np.nonzero((tex[..., 3] > 128) & (tex[..., :3].sum(-1) < 200))
    uv = np.c_[(xs + 0.5) / w, 1 - (ys + 0.5) / h]
    vmin, vmax = np.asarray(decal.visual.uv)[:, 1].min(), np.asarray(decal.visual.uv)[:, 1].max()
    uv = uv[(uv[:, 1] >= vmin) & (uv[:, 1] <= vmax)]
    return uv_to_3d(decal, uv[:: max(1, len(uv) // limit)])


def main(path: str) -> dict[str, np.ndarray]:
    scene = trimesh.load(path)
    geoms = list(scene.geometry.values())
    body = max(geoms, key=lambda g: len(g.vertices))
    pieces = trimesh.graph.connected_components(body.face_adjacency, nodes=np.arange(len(body.faces)), min_len=1)
    head = body.submesh([max(pieces, key=len)], append=True)  # the bald head: the largest piece
    lm: dict[str, np.ndarray] = {}
    for decal in geoms:
        if decal is body:
            continue
        pts = painted_points(decal)
        c = pts.mean(axis=0)
        sx, sy = 2 * pts[:, 0].std(), 2 * pts[:, 1].std()
        if np.ptp(decal.vertices[:, 1]) > 0.2:  # an eye (the mouth's decal is a thin strip)
            side = "left" if c[0] > 0 else "right"  # the subject's left is +x
            out = np.array([sx if side == "left" else -sx, 0, 0])
            lm[f"eye_{side}_outer"], lm[f"eye_{side}_inner"] = c + out, c - out
            lm[f"eye_{side}_top"], lm[f"eye_{side}_bottom"] = c + [0, sy, 0], c - [0, sy, 0]
        else:
            lm["mouth_left"], lm["mouth_right"] = pts[np.argmax(pts[:, 0])], pts[np.argmin(pts[:, 0])]
            mid = pts[np.abs(pts[:, 0]) < 0.15 * np.ptp(pts[:, 0])]
            lm["mouth_top"], lm["mouth_bottom"] = mid[np.argmax(mid[:, 1])], mid[np.argmin(mid[:, 1])]
    v = np.asarray(head.vertices)
    front = v[(np.abs(v[:, 0]) < 0.01) & (v[:, 2] > 0)]  # the midline profile, facing +z
    eyes_y = (lm["eye_right_top"][1] + lm["eye_right_bottom"][1]) / 2
    mouth_y = lm["mouth_left"][1]
    nose = front[(front[:, 1] > mouth_y) & (front[:, 1] < eyes_y)]
    tip = nose[np.argmax(nose[:, 2])]  # the button nose: the most forward point between mouth and eyes
    lm["nose_tip"] = tip
    lm["subnasale"] = tip - [0, 0.048, 0]  # where the button meets the lip, under the tip
    lm["nose_right"], lm["nose_left"] = tip + [-0.02, -0.005, 0], tip + [0.02, -0.005, 0]  # its sides
    lm["nasion"] = np.array([0.0, lm["eye_right_inner"][1] + 0.015, 0.0])  # between the eyes' inner corners
    below = front[front[:, 1] < mouth_y]
    lm["chin"] = below[np.argmax(below[:, 2] - 4 * np.abs(below[:, 1] - (mouth_y - 0.08)))]  # the chin's front
    lm["forehead_top"] = np.array([0.0, eyes_y + 0.205, 0.0])  # where a hairline would be
    band = v[(np.abs(v[:, 1] - eyes_y) < 0.03) & (v[:, 2] > 0)]  # the face's sides at eye height, in front of the ears
    lm["face_right"], lm["face_left"] = band[np.argmin(band[:, 0])], band[np.argmax(band[:, 0])]
    names = sorted(lm)
    rays = np.array([[lm[k][0], lm[k][1], 1.0] for k in names])  # onto the skin along the view
    hits, ray, _ = head.ray.intersects_location(rays, np.tile([0.0, 0.0, -1.0], (len(names), 1)), multiple_hits=False)
    for h, r in zip(hits, ray):
        if names[r] not in ("face_right", "face_left"):
            lm[names[r]] = h
    return lm


if __name__ == "__main__":
    points = main(sys.argv[1])
    print("# Rig landmarks on GDQuest's Sophia (sophia.glb of the gdquest-sophia dataset, CC BY 4.0), written by")
    print("# scripts/design_landmarks.py: the painted eyes' and mouth's outlines, the button nose, chin, sides.")
    for k in sorted(points):
        print(f"{k}: [{points[k][0]:.4f}, {points[k][1]:.4f}, {points[k][2]:.4f}]")
