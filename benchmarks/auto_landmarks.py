"""Automatic mesh landmarks (``landmarks: auto``) against hand-placed ground truth.

For each mesh with ground truth: the mean and largest distance between detected and true
landmarks in % of the mesh's bounding-box diagonal, for the inner points (iBUG 17-67: brows,
eyes, nose, mouth) and the jaw line (0-16, a silhouette in the detector), the mean confidence
of each group, and the time. Meshes (../shared/data/meshes, see its MANIFEST.md):

* menpo3d james (textured scan): truth james.ljson (menpo's 68-point LJSON);
* the ICT Face Model's generic neutral mesh (no texture, shaded grey): truth its Multi-PIE 68
  landmark vertices (vertex_indices.json, iBUG order);
* Lee Perry-Smith (textured scan, eyes closed): no ground truth, so only time and confidence
  (look at the PNG it writes).

Also writes PNGs of the front render with detected (green) and true (red) points projected,
into --out (default /tmp/auto_landmarks). No competitor runs here: there is no other offline
3D landmarker in the environment to compare with; the ratio printed is to the time of one
pyrender render + dlib detection (the floor for any render-and-detect method).

Run: .venv/bin/python benchmarks/auto_landmarks.py [--out DIR]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from appeal.assets import shared_data_dir
from stimulus_engine.correspondence.auto_landmarks import ALL_AXIS_VIEWS, _View, detect_mesh_landmarks
from stimulus_engine.correspondence.landmark_sets import read_ljson, reorder_landmarks
from stimulus_engine.geometry.ict_topology import ict_regions
from stimulus_engine.geometry.mesh_io import load_mesh
from stimulus_engine.morphpca.keypoints import detect_landmarks_scored


def _truth(name: str, d: Path, mesh) -> np.ndarray | None:
    if name == "james":
        pts, order = read_ljson(d / "menpo3d-james" / "james.ljson")
        return reorder_landmarks(pts, order)
    if name == "ict":
        return np.asarray(mesh.vertices)[np.asarray(ict_regions(d / "ict-facekit" / "vertex_indices.json")["landmarks"])]
    return None


def _picture(mesh, found, truth, front, path: Path) -> None:
    from PIL import Image, ImageDraw

    from stimulus_engine.correspondence.auto_landmarks import _drawable

    lo, hi = found.min(0), found.max(0)  # framed on the face found, so the points can be judged
    d, up = (np.asarray(x, float) for x in ALL_AXIS_VIEWS[front])
    view = _View(_drawable(mesh), (lo + hi) / 2, float(np.linalg.norm(hi - lo)) * 0.75, d, up, 640)
    img = Image.fromarray(view.image)
    draw = ImageDraw.Draw(img)
    rot, pos, t = view.camera.rotation(), np.asarray(view.camera.position), np.tan(view.yfov / 2)
    for pts, colour in ((truth, (255, 40, 40)), (found, (40, 255, 40))):
        if pts is None:
            continue
        cam = (np.asarray(pts) - pos) @ rot
        x = (cam[:, 0] / (-cam[:, 2] * t) + 1) / 2 * 640
        y = (1 - cam[:, 1] / (-cam[:, 2] * t)) / 2 * 640
        for a, b in zip(x, y):
            draw.ellipse([a - 2.5, b - 2.5, a + 2.5, b + 2.5], fill=colour)
    img.save(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("/tmp/auto_landmarks"))
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    d = shared_data_dir() / "meshes"
    meshes = {"james": d / "menpo3d-james" / "james.obj", "ict": d / "ict-facekit" / "generic_neutral_mesh.obj.gz",
              "leeperrysmith": d / "leeperrysmith" / "LeePerrySmith.obj"}
    inner, jaw = np.arange(17, 68), np.arange(17)
    print(f"{'mesh':15s} {'front':5s} views  inner mean/max %   jaw mean/max %   conf inner/jaw   seconds  x one view")
    for name, path in meshes.items():
        mesh = load_mesh(path)
        t0 = time.perf_counter()
        lm = detect_mesh_landmarks(mesh, name=name)
        secs = time.perf_counter() - t0
        v = np.asarray(mesh.vertices)
        lo, hi = v.min(0), v.max(0)
        t1 = time.perf_counter()
        from stimulus_engine.correspondence.auto_landmarks import _drawable

        view = _View(_drawable(mesh), (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2,
                     *(np.asarray(x, float) for x in ALL_AXIS_VIEWS[lm.front]), 640)
        detect_landmarks_scored(view.image, name, max_side=640)
        one = time.perf_counter() - t1
        truth = _truth(name, d, mesh)
        diag = float(np.linalg.norm(hi - lo))
        if truth is not None:
            err = np.linalg.norm(lm.points - truth, axis=1) / diag * 100
            errs = f"{err[inner].mean():6.2f} / {err[inner].max():5.2f}    {err[jaw].mean():6.2f} / {err[jaw].max():5.2f}"
        else:
            errs = f"{'(no truth)':>15s}  {'':>15s}"
        print(f"{name:15s} {lm.front:5s} {lm.views:5d}  {errs}   {lm.confidence[inner].mean():.2f} / "
              f"{lm.confidence[jaw].mean():.2f}      {secs:6.2f}  {secs / one:5.1f}")
        _picture(mesh, lm.points, truth, lm.front, a.out / f"{name}.png")
    print(f"pictures: {a.out}")


if __name__ == "__main__":
    main()
