"""A plain pyrender loop under OSMesa (this machine) or EGL (a GPU machine): ms per image.

The ICT neutral head (28,911 vertices, 52,220 faces after trimesh's OBJ load) at 1024 x 768,
one PBR material, two directional lights and a spot light, the colour and depth read back every
image; with no shadows, then with directional and spot shadow maps (pyrender's
``SHADOWS_ALL`` fails on llvmpipe). The script needs only numpy, trimesh, pyrender and
PyOpenGL, so it runs on a GPU machine without this package's other dependencies.
``PYOPENGL_PLATFORM`` chooses the back-end (``osmesa`` here, ``egl`` on a GPU); one process runs
one platform, so run it once per platform and compare the medians.

Measured 2026-11-25 (medians, render + read-back per image; the two platforms' images agree
to 0.8 / 255 per pixel on average):

* this 2-core machine, OSMesa llvmpipe (2 runs): 50-55 ms without shadows, 204 ms with them;
* one NVIDIA H100 (the lent device; 3 runs on 2 machines), EGL, pyrender 0.1.45, PyOpenGL
  3.1.10: 5.9-9.2 ms without shadows, 9.1-16.2 ms with them.

So a GPU renders this plain scene 5-9x faster without shadows and 13-22x with shadow maps. The
package's own renderer (skin shader, baked shadows) was not run there: its dependencies (OpenCV
among them) do not fit the 64 MiB a lent machine is sent, and nothing may be downloaded on it.

Run:  PYOPENGL_PLATFORM=osmesa .venv/bin/python benchmarks/render_egl.py [MESH.obj.gz] [--n 30]
      PYOPENGL_PLATFORM=egl python3 benchmarks/render_egl.py generic_neutral_mesh.obj.gz --n 200
(MESH defaults to ``../shared/data/meshes/ict-facekit/generic_neutral_mesh.obj.gz``.) With
``--png DIR`` the unshadowed image is saved there, to compare the platforms' pictures.
"""

from __future__ import annotations

import argparse
import gzip
import io
import os
import statistics
import time
from pathlib import Path

import numpy as np

# Plain pyrender on purpose, without the package: it has to run on a lent GPU machine where
# the package cannot be installed, and the package's own pyrender set-up
# (stimulus_engine/render/_pyrender.py, the project's one place for the np.infty alias) also
# patches the shadow pass (with it, this loop's shadowed images took 504 ms here, not 204), so the platforms would
# not be compared on the same work. Hence pyrender 0.1.45's np.infty, aliased here too.
if not hasattr(np, "infty"):
    np.infty = np.inf
import pyrender  # noqa: E402


def _look_at(position) -> np.ndarray:
    """A light or camera pose at ``position`` facing the origin (+y up)."""
    z = np.asarray(position, float)
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, np.cross(z, x), z, position
    return pose


def head_scene(mesh_path: Path):
    """The head, unit bounding-box diagonal, centred, lit and framed."""
    import trimesh

    with gzip.open(mesh_path, "rb") if mesh_path.suffix == ".gz" else open(mesh_path, "rb") as fh:
        mesh = trimesh.load(io.BytesIO(fh.read()), file_type="obj", process=False, force="mesh")
    mesh.apply_translation(-mesh.bounds.mean(axis=0))
    mesh.apply_scale(1.0 / np.linalg.norm(mesh.extents))
    material = pyrender.MetallicRoughnessMaterial(baseColorFactor=(0.8, 0.65, 0.55, 1.0), roughnessFactor=0.6,
                                                  metallicFactor=0.0)
    scene = pyrender.Scene(bg_color=(0.5, 0.5, 0.5, 1.0), ambient_light=(0.1, 0.1, 0.1))
    scene.add(pyrender.Mesh.from_trimesh(mesh, material=material, smooth=True))
    camera_pose = np.eye(4)
    camera_pose[2, 3] = 2.5
    scene.add(pyrender.PerspectiveCamera(yfov=np.deg2rad(20), aspectRatio=1024 / 768), pose=camera_pose)
    scene.add(pyrender.DirectionalLight(intensity=3.0), pose=_look_at([1, 1, 2]))
    scene.add(pyrender.DirectionalLight(intensity=1.0), pose=_look_at([-2, 0.5, 1]))
    scene.add(pyrender.SpotLight(intensity=8.0, innerConeAngle=0.3, outerConeAngle=0.6), pose=_look_at([0, 2, 2]))
    return scene, mesh


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    default = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes" / "ict-facekit" / "generic_neutral_mesh.obj.gz"
    ap.add_argument("mesh", nargs="?", type=Path, default=default)
    ap.add_argument("--n", type=int, default=30, help="timed images per setting")
    ap.add_argument("--png", type=Path, help="save the unshadowed image in this folder")
    a = ap.parse_args()
    scene, mesh = head_scene(a.mesh)
    renderer = pyrender.OffscreenRenderer(1024, 768)
    from OpenGL.GL import GL_RENDERER, glGetString

    print(f"platform {os.environ.get('PYOPENGL_PLATFORM', '(default)')}: {glGetString(GL_RENDERER).decode()}; "
          f"{len(mesh.vertices)} vertices, {len(mesh.faces)} faces, 1024 x 768")
    flags = pyrender.RenderFlags
    for name, flag in (("no shadows", flags.NONE), ("directional + spot shadows", flags.SHADOWS_DIRECTIONAL | flags.SHADOWS_SPOT)):
        for _ in range(3):  # warm-up: shader compilation, shadow textures
            renderer.render(scene, flags=flag)
        times = []
        for _ in range(a.n):
            t = time.perf_counter()
            color, _ = renderer.render(scene, flags=flag)
            times.append(time.perf_counter() - t)
        print(f"  {name:28s} median {1e3 * statistics.median(times):7.2f} ms per image ({a.n} images)")
        if a.png is not None and flag == flags.NONE:
            from PIL import Image

            a.png.mkdir(parents=True, exist_ok=True)
            Image.fromarray(color).save(a.png / f"head_{os.environ.get('PYOPENGL_PLATFORM', 'default')}.png")
    renderer.delete()


if __name__ == "__main__":
    main()
