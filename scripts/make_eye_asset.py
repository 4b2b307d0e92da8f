"""Rebuild ``stimulus_engine/data/eyes/`` from MakeHuman's CC0 high-poly eyes.

Keeps the two textured eyeballs of ``proxies/high-poly.obj`` (the corneal shells, which need a
transparent material, are left out), as one ``eyeballs.npz`` (vertices in MakeHuman's units,
faces, UVs, an eye index per vertex), and ``brown_eye.png`` re-encoded at 512 x 512 as JPEG.

Usage::

    python scripts/make_eye_asset.py ../shared/data/meshes/makehuman-cc0
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

OUT = Path(__file__).resolve().parents[1] / "stimulus_engine" / "data" / "eyes"


def photographic(rgb: np.ndarray) -> np.ndarray:
    """The texture's colours brought to a photographed brown eye.

    The CC0 texture's iris is nearly pure red (median sRGB 71, 12, 1), which rendered reads as a
    red eye: its saturated pixels are turned to a brown hue (25 degrees) at 60 % of their
    saturation; the sclera (the unsaturated rest) is darkened by 20 % (lids shadow it in a photo).
    """
    from matplotlib.colors import hsv_to_rgb, rgb_to_hsv

    hsv = rgb_to_hsv(rgb / 255.0)
    iris = hsv[..., 1] > 0.5
    hsv[..., 0] = np.where(iris, 25.0 / 360.0, hsv[..., 0])
    hsv[..., 1] = np.where(iris, 0.6 * hsv[..., 1], hsv[..., 1])
    hsv[..., 2] = np.where(iris, np.minimum(1.0, 1.25 * hsv[..., 2]), 0.8 * hsv[..., 2])
    return np.rint(255 * hsv_to_rgb(hsv)).astype(np.uint8)


def main(src: Path) -> None:
    m = trimesh.load(src / "proxies" / "high-poly.obj", process=False, force="mesh")
    uv = np.asarray(m.visual.uv, np.float64)
    parts = trimesh.graph.connected_components(m.face_adjacency, nodes=np.arange(len(m.faces)))
    # the eyeballs are the large pieces mapped into the iris disks; the corneas map to the
    # white disk in the texture's lower-right corner
    balls = [p for p in parts if len(p) > 100 and (uv[m.faces[p]].mean(axis=(0, 1))[0] < 0.85)]
    if len(balls) != 2:
        raise SystemExit(f"{src}: expected two eyeballs in high-poly.obj, found {len(balls)}")
    faces = np.concatenate([m.faces[p] for p in balls])
    used, inv = np.unique(faces, return_inverse=True)
    eye = np.zeros(len(used), np.int8)
    eye[np.unique(inv.reshape(-1, 3)[len(balls[0]):])] = 1
    OUT.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(OUT / "eyeballs.npz", vertices=m.vertices[used].astype(np.float32),
                        faces=inv.reshape(-1, 3).astype(np.int32), uv=uv[used].astype(np.float32), eye=eye)
    with Image.open(src / "textures" / "brown_eye.png") as im:
        Image.fromarray(photographic(np.asarray(im.convert("RGB")))).resize((512, 512), Image.LANCZOS).save(
            OUT / "brown_eye.jpg", quality=92)
    print(f"{OUT}: {len(used)} vertices, {len(faces)} faces")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/meshes/makehuman-cc0"))
