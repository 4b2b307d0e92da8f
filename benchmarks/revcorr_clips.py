"""Benchmark: a reverse-correlation pool rendered as clips in one grid run (``animation.revcorr``).

    python benchmarks/revcorr_clips.py [--trials 6] [--size 384] [--levels 0 1] [--jobs 2] [--data ../shared/data]

One grid of one ICT identity (``identity000``, pyrender, ``--size`` square, ``gi_soft`` light,
skin shading) at the given shape levels plays trials 0 .. ``--trials`` - 1 of the grammar
(``appeal.revcorr.grammar``: 1.25 s at 30 fps, 39 frames a clip) in every level, rendered by
``--jobs`` worker processes. A first run of one trial builds the character (reported apart; each
mode then starts from a copy of that cache, so neither reuses the other's posed frames); then the
pool is rendered twice, with ambient occlusion baked for every
frame (``animation.occlusion: frame``) and blended between the neutral first frame and the apex
(``blend``). Printed: each run's clips per minute (the whole run's wall time, preparation
included, over its clips) against issue 53's target of 10 clips a minute here, the ratio
blend / frame, and what blending changes in the images (mean and 99th percentile of the absolute
8-bit difference over every frame). No competitor exists (Jack et al.'s grammar is not public),
so the target is the reference.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from appeal.studyfile import load_study_file  # noqa: E402
from stimulus_engine.grid import run_grid  # noqa: E402
from stimulus_engine.grid.schema import GridFile  # noqa: E402

TARGET_CLIPS_PER_MINUTE = 10.0

GRID = """kind: grid
name: revcorr_bench
characters:
  - name: ict000
    ict: {ict}
    identity: identity000
shapes: {levels}
materials: [original]
expressions: [neutral]
lighting: [gi_soft]
shading: [skin]
render: {{width: {size}, height: {size}}}
animation: {{fps: 30, occlusion: {occlusion}, revcorr: {{seed: 53, trials: {trials}, first: {first}}}}}
"""


def run(tmp: Path, name: str, args: argparse.Namespace, *, occlusion: str, trials: int, first: int = 0,
        cache: str = "cache"):
    """One grid run into ``tmp/name`` with the cache ``tmp/cache``; (manifest, seconds)."""
    from PIL import Image  # noqa: F401  (loaded before the clock starts)

    grid = tmp / f"{name}.yaml"
    grid.write_text(GRID.format(ict=args.data / "meshes" / "ict-facekit", levels=list(args.levels), size=args.size,
                                occlusion=occlusion, trials=trials, first=first))
    out = tmp / name
    (out / ".cache").parent.mkdir(parents=True, exist_ok=True)
    if not (out / ".cache").exists():
        (out / ".cache").symlink_to(tmp / cache, target_is_directory=True)
    t = time.perf_counter()
    manifest, _ = run_grid(load_study_file(grid, GridFile), out, n_jobs=args.jobs)
    return manifest, time.perf_counter() - t


def frame_difference(a: Path, b: Path, manifest) -> tuple[float, float]:
    """Mean and 99th percentile of |a - b| (8-bit) over every frame of every clip of ``manifest``."""
    from PIL import Image

    diffs = []
    for r in manifest.itertuples():
        for k in range(int(r.n_frames)):
            name = f"{r.frames}/frame_{k:05d}.png"
            x, y = (np.asarray(Image.open(root / name).convert("RGB"), np.int16) for root in (a, b))
            diffs.append(np.abs(x - y).ravel())
    d = np.concatenate(diffs)
    return float(d.mean()), float(np.percentile(d, 99))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=6)
    ap.add_argument("--size", type=int, default=384)
    ap.add_argument("--levels", type=float, nargs="+", default=[0.0, 1.0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "cache").mkdir()
        _, build = run(tmp, "build", args, occlusion="frame", trials=1, first=99_000)
        print(f"character and levels built: {build:.1f} s (one clip per level included)", flush=True)
        rates = {}
        for mode in ("frame", "blend"):  # each from the built character alone (no frame of the pool cached)
            shutil.copytree(tmp / "cache", tmp / f"cache_{mode}")
            manifest, secs = run(tmp, mode, args, occlusion=mode, trials=args.trials, cache=f"cache_{mode}")
            rates[mode] = 60.0 * len(manifest) / secs
            print(f"occlusion {mode}: {len(manifest)} clips of {int(manifest['n_frames'].iloc[0])} frames in "
                  f"{secs:.1f} s -> {rates[mode]:.1f} clips/min at {args.size} px, {args.jobs} worker(s); target "
                  f"{TARGET_CLIPS_PER_MINUTE:.0f}/min: ratio {rates[mode] / TARGET_CLIPS_PER_MINUTE:.2f}", flush=True)
        mean, p99 = frame_difference(tmp / "frame", tmp / "blend", manifest)
        print(f"blend / frame speed: {rates['blend'] / rates['frame']:.2f}x; blended occlusion changes the frames by "
              f"{mean:.3f} (mean) and {p99:.1f} (99th percentile) of 255")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
