"""Rendering speed: ``render_mesh`` vs a plain pyrender loop, and images/s vs worker processes.

Scene: the ICT neutral head (all parts, ~27k vertices) at 1024 x 768, no shadows, OSMesa.
Baseline ("plain pyrender"): what a user would write without this package — build a
``pyrender.Scene`` from the trimesh, one ``OffscreenRenderer`` reused, ``render()`` in a loop.
Both runs include the scene construction per image (each stimulus has its own geometry).

Run:  .venv/bin/python benchmarks/render.py [--ict ../shared/data/meshes/ict-facekit] [--n 8]
Prints medians of repeats (ms per image), the ratio, and images/s for 1 and 2 processes; then
the ``skin`` shading against ``pbr`` with shadows on (direct_hard: the key light's map;
direct_soft: its disc baked per vertex, timed once per geometry and reused by every material
and shading).
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np


def _ict_parts(ict: Path, shading: str = "pbr"):
    """The ICT head's parts; under ``skin`` shading with its baked occlusion (timed and printed)."""
    from stimulus_engine.characters.ict import load_ict_rig
    from stimulus_engine.characters.render_parts import rig_occlusion, rig_render_parts

    rig = load_ict_rig(ict, shapes=[])
    occlusion = None
    if shading == "skin":
        t = time.perf_counter()
        occlusion = rig_occlusion(rig, rig.vertices)
        print(f"  occlusion bake ({len(rig.vertices)} vertices x 32 rays, once per geometry): "
              f"{time.perf_counter() - t:.2f} s")
    return rig, rig_render_parts(rig, rig.vertices, None, shading=shading, occlusion=occlusion)


def ours_ms(ict: str, n: int, shading: str = "pbr", lighting: str = "gi_soft", shadows: bool = False) -> list[float]:
    from stimulus_engine.render import face_camera, render_mesh

    rig, parts = _ict_parts(Path(ict), shading)
    lm = rig.landmark_points()
    cam = face_camera((lm["eye_left"] + lm["eye_right"]) / 2, 20.0)
    render_mesh(parts, lighting=lighting, camera=cam, shadows=shadows)
    out = []
    for _ in range(n):
        t = time.perf_counter()
        render_mesh(parts, lighting=lighting, camera=cam, shadows=shadows)
        out.append((time.perf_counter() - t) * 1000)
    return out


def soft_bake_s(ict: str) -> float:
    """Seconds to bake direct_soft's disc visibility on the ICT head (the cache emptied first)."""
    from stimulus_engine.render import face_camera, lighting_preset
    from stimulus_engine.render.baked_shadows import _CACHE
    from stimulus_engine.render.renderer import _baked_visibility, _items

    rig, parts = _ict_parts(Path(ict), "skin")
    lm = rig.landmark_points()
    cam = face_camera((lm["eye_left"] + lm["eye_right"]) / 2, 20.0)
    items, lights = _items(parts), lighting_preset("direct_soft")[0]
    times = []
    for _ in range(3):
        _CACHE.clear()
        t = time.perf_counter()
        _baked_visibility(items, lights, cam)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def plain_ms(ict: str, n: int) -> list[float]:
    from stimulus_engine.render import release_renderers
    from stimulus_engine.render._pyrender import pyrender  # same platform/np.infty set-up

    release_renderers()  # our context holds the (shared) eye texture; a texture lives in one context

    rig, parts = _ict_parts(Path(ict))
    r = pyrender.OffscreenRenderer(1024, 768)
    pose = np.eye(4)
    pose[:3, 3] = [0, 3, 60]

    def once() -> None:
        scene = pyrender.Scene(bg_color=[0.5, 0.5, 0.5, 1.0], ambient_light=[0.3] * 3)
        for p in parts:
            scene.add(pyrender.Mesh.from_trimesh(p.mesh, material=p.material))
        scene.add(pyrender.PerspectiveCamera(yfov=np.radians(20), aspectRatio=4 / 3), pose=pose)
        for k in range(14):  # the same number of lights as the gi_soft preset
            scene.add(pyrender.DirectionalLight(intensity=0.5), pose=pose)
        r.render(scene)

    once()
    out = []
    for _ in range(n):
        t = time.perf_counter()
        once()
        out.append((time.perf_counter() - t) * 1000)
    r.delete()
    return out


def _batch(args: tuple[str, int]) -> tuple[int, float, float]:
    """Warm up (load, first render), then time ``n`` renders; wall-clock start and end."""
    from stimulus_engine.render import face_camera, render_mesh

    ict, n = args
    rig, parts = _ict_parts(Path(ict))
    lm = rig.landmark_points()
    cam = face_camera((lm["eye_left"] + lm["eye_right"]) / 2, 20.0)
    render_mesh(parts, lighting="gi_soft", camera=cam, shadows=False)
    t0 = time.time()
    for _ in range(n):
        render_mesh(parts, lighting="gi_soft", camera=cam, shadows=False)
    return n, t0, time.time()


def throughput(ict: str, n: int, jobs: int) -> float:
    """Images per second over the span in which the workers' timed loops ran."""
    from appeal.parallel import parallel_map

    res = [r for r in parallel_map(_batch, [(ict, n)] * jobs, n_jobs=jobs).results if r]
    return sum(r[0] for r in res) / (max(r[2] for r in res) - min(r[1] for r in res))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ict", default=str(Path(__file__).resolve().parents[2] / "shared/data/meshes/ict-facekit"))
    ap.add_argument("--n", type=int, default=8)
    a = ap.parse_args()
    ours = statistics.median(ours_ms(a.ict, a.n))
    plain = statistics.median(plain_ms(a.ict, a.n))
    print(f"render_mesh (ours):      {ours:7.1f} ms/image (median of {a.n}, 1024x768, no shadows)")
    print(f"plain pyrender loop:     {plain:7.1f} ms/image")
    print(f"ratio plain/ours:        {plain / ours:7.2f}")
    for jobs in (1, 2):
        print(f"throughput, {jobs} process(es): {throughput(a.ict, a.n, jobs):6.2f} images/s")
    # the skin shading (scattering-softened skin, wet eyes, filmic tone curve) with soft shadows on
    print(f"soft-shadow bake (direct_soft, per geometry and lighting, reused by every material): "
          f"{soft_bake_s(a.ict):.2f} s")
    for lighting in ("direct_hard", "direct_soft", "gi_soft"):
        pbr = statistics.median(ours_ms(a.ict, a.n, "pbr", lighting, True))
        skin = statistics.median(ours_ms(a.ict, a.n, "skin", lighting, True))
        print(f"{lighting} with shadows: pbr {pbr:7.1f} ms/image, skin {skin:7.1f} ms/image, ratio skin/pbr "
              f"{skin / pbr:5.2f} (target <= 100 ms)")


if __name__ == "__main__":
    main()
