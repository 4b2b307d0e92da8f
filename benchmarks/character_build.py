"""Building the shipped grids' scan characters from nothing (issue 14: at most 10 s per scan).

For each character of ``protocols/grids/exp2_stylisation.yaml`` (james drawn as itself; Lee
Perry-Smith on the ICT rig), the median over ``--repeats`` builds, each in a new process (as a
user's ``appeal stimuli grid`` runs; the ICT files are cached per process) into an empty cache, of
:func:`stimulus_engine.grid.characters.load_character`: rig loading, automatic landmarks,
ElastiFace correspondence, and — for a scan drawn as itself — eyes, lips and region masks, or —
for a rig character — the texture and normal map re-laid. Then a build from the filled cache, in the same process.

The competitor is the floor every scan character pays before any of our own work: loading the
ICT rig (32 OBJ files) and one render-and-detect of the face (pyrender + dlib); the ratio says
how many such floors a build costs.

Run: .venv/bin/python benchmarks/character_build.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
GRID = ROOT / "protocols" / "grids" / "exp2_stylisation.yaml"


def _floor(spec: object) -> float:
    """Seconds to load the character's rig and detect its face once in a frontal render."""
    from stimulus_engine.correspondence.auto_landmarks import AXIS_VIEWS, _drawable, _View
    from stimulus_engine.characters.ict import load_ict_rig
    from stimulus_engine.geometry.mesh_io import load_mesh
    from stimulus_engine.morphpca.keypoints import detect_landmarks_scored

    import numpy as np

    t = time.perf_counter()
    load_ict_rig(spec.ict, spec.identity)
    mesh = load_mesh(spec.mesh.file)
    v = np.asarray(mesh.vertices)
    lo, hi = v.min(axis=0), v.max(axis=0)
    d, up = AXIS_VIEWS["+z"]
    view = _View(_drawable(mesh), (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2, np.asarray(d, float),
                 np.asarray(up, float), 640)
    detect_landmarks_scored(view.image, "floor")
    return time.perf_counter() - t


def _one(name: str, what: str) -> None:
    """In this (new) process: build ``name`` (then again from the cache) or time its floor; print seconds."""
    from appeal.studyfile import validate_data
    from stimulus_engine.grid.characters import load_character
    from stimulus_engine.grid.schema import GridFile

    grid = validate_data(yaml.safe_load(GRID.read_text()), GridFile, source=GRID, base_dir=GRID.parent)
    spec = next(c for c in grid.characters if c.name == name)
    if what == "floor":
        print(_floor(spec))
        return
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        load_character(spec, Path(d), "benchmark")
        build = time.perf_counter() - t
        t = time.perf_counter()
        load_character(spec, Path(d), "benchmark")
        print(build, time.perf_counter() - t)


def _run(name: str, what: str) -> list[float]:
    out = subprocess.run([sys.executable, __file__, "--one", name, what], capture_output=True, text=True, check=True)
    return [float(x) for x in out.stdout.split()]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--one", nargs=2, metavar=("NAME", "WHAT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        _one(*args.one)
        return
    names = [c["name"] for c in yaml.safe_load(GRID.read_text())["characters"]]
    print(f"{'character':10} {'build (median)':>15} {'cached':>8} {'floor':>7} {'build/floor':>12} {'<= 10 s':>8}")
    for name in names:
        runs = [_run(name, "build") for _ in range(args.repeats)]
        build, cached = statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)
        floor = statistics.median(_run(name, "floor")[0] for _ in range(args.repeats))
        print(f"{name:10} {build:14.1f}s {cached:7.1f}s {floor:6.1f}s {build / floor:12.1f} "
              f"{'yes' if build <= 10 else 'NO':>8}")


if __name__ == "__main__":
    main()
