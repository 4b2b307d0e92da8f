"""Where dlib's 68 points fall on the ICT Face Model (for fitting it to photographs, issue 49).

The ICT face kit names 68 landmark vertices (its ``vertex_indices.json``), but dlib, which finds
the points in a photograph, places several elsewhere: the jaw line on the face's silhouette, the
inner lips on the lip line's shadow, the brows on their lower edge — by up to a fifth of the eye
distance on renders of the model itself. This script renders identities drawn from the model's
prior (its painted skin, ``gi_soft``, frontal), detects dlib's 68 points in each render and takes,
for every point, the face vertex whose projection lies nearest the detected point on average over
the renders (among vertices seen in all of them). Writes
``stimulus_engine/data/faces2d/ict_dlib68.json``, which the photo fit uses as the model's 68
points::

    .venv/bin/python scripts/ict_dlib_landmarks.py            # 16 identities
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np


def main() -> None:
    from appeal.datasets import resolve_reference
    from stimulus_engine.characters.photo_character import _model
    from stimulus_engine.characters.render_parts import rig_render_parts
    from stimulus_engine.characters.skin_maps import rig_albedo
    from stimulus_engine.data import DATA_DIR
    from stimulus_engine.morphpca.keypoints import detect_landmarks
    from stimulus_engine.render import face_camera, render_mesh

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--identities", type=int, default=16)
    ap.add_argument("--out", type=Path, default=DATA_DIR / "faces2d" / "ict_dlib68.json")
    a = ap.parse_args()
    rig, basis, given, _ = _model(str(resolve_reference("data:ict-facekit")), str(resolve_reference("data:ict-facekit-more")))
    face = np.arange(9409)  # the ICT face region
    total = np.zeros((68, len(face)))
    before = []
    for k in range(a.identities):
        coeffs = np.random.default_rng(k).normal(size=len(basis)) * (0.0 if k == 0 else 0.8)
        v = rig.vertices + np.tensordot(coeffs, basis, 1)
        drawn = replace(rig.with_vertices(v), name=f"identity_{k}")
        albedo, _ = rig_albedo(drawn, size=1024)
        p = drawn.landmark_points()
        eye = (p["eye_left"] + p["eye_right"]) / 2
        cam = face_camera(eye, float(np.linalg.norm(p["forehead_top"] - p["chin"])), yfov_deg=12.0, eye_row=0.4,
                          face_fraction=0.6)
        size = 900
        img, depth = render_mesh(rig_render_parts(drawn, v, albedo, shading="pbr"), width=size, height=size,
                                 lighting="gi_soft", camera=cam, background=(0.55, 0.55, 0.55), shadows=False,
                                 return_depth=True)
        det = detect_landmarks(img, f"render {k}")
        pos, tgt, up = (np.asarray(x, np.float64) for x in (cam.position, cam.target, cam.up))
        fwd = (tgt - pos) / np.linalg.norm(tgt - pos)
        right = np.cross(fwd, up)
        right /= np.linalg.norm(right)
        upv = np.cross(right, fwd)
        X = v[face] - pos
        z = X @ fwd
        t = math.tan(math.radians(cam.yfov_deg) / 2)
        px = np.c_[size / 2 + (X @ right) / z / t * size / 2, size / 2 - (X @ upv) / z / t * size / 2]
        r = np.clip(np.rint(px[:, 1]).astype(int), 0, size - 1)
        c = np.clip(np.rint(px[:, 0]).astype(int), 0, size - 1)
        seen = (depth[r, c] > 0) & (np.abs(depth[r, c] - z) < 0.3)
        iod = np.linalg.norm(det[36:42].mean(axis=0) - det[42:48].mean(axis=0))
        d = np.linalg.norm(det[:, None] - px[None], axis=2) / iod
        d[:, ~seen] = np.inf
        total += d
        gi = np.searchsorted(face, given)
        before.append(np.linalg.norm(det - px[gi], axis=1) / iod)
    best = total.argmin(axis=1)
    after = total[np.arange(68), best] / a.identities
    out = {"identities": a.identities, "vertices": [int(face[b]) for b in best],
           "mean_offset_iod_given": round(float(np.mean(before)), 4), "mean_offset_iod": round(float(after.mean()), 4)}
    a.out.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(f"dlib's 68 points on the ICT face: mean offset {np.mean(before):.3f} -> {after.mean():.3f} of the eye "
          f"distance over {a.identities} renders -> {a.out}")


if __name__ == "__main__":
    main()
