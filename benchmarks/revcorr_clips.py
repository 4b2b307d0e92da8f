"""Benchmark: reverse-correlation trials rendered as clips through a grid's performance path.

    python benchmarks/revcorr_clips.py [--trials 6] [--size 512] [--levels 0 1] [--data ../shared/data]

Each trial of the grammar (``appeal.revcorr.grammar``) is written as a performance CSV
(``stimulus_engine.characters.au_poses.write_trial_performance``: 1.25 s at 30 fps, 39 frames) and
played by a grid of one ICT identity (``identity000``, pyrender, ``--size`` square) at the given
shape levels: one ``run_grid`` per trial, the character built once and cached by the first. The
first run (the character's build) is reported apart; clips per minute come from the median of the
others, against issue 53's target of 10 clips of 1.25 s at 30 fps per minute here. No competitor
exists (the grammar of Jack et al. is not public), so the target is the reference.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from appeal.revcorr.grammar import draw_trial  # noqa: E402
from appeal.studyfile import load_study_file  # noqa: E402
from stimulus_engine.characters.au_poses import write_trial_performance  # noqa: E402
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
shading: [pbr]
render: {{width: {size}, height: {size}}}
animation: {{fps: 30, performance: {performance}}}
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=6)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--levels", type=float, nargs="+", default=[0.0, 1.0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    args = ap.parse_args()
    ict = args.data / "meshes" / "ict-facekit"
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for i in range(args.trials):
            perf = write_trial_performance(draw_trial(53, i), tmp / f"trial_{i:05d}.csv")
            grid = tmp / f"trial_{i:05d}.yaml"
            grid.write_text(GRID.format(ict=ict, levels=list(args.levels), size=args.size, performance=perf))
            t = time.perf_counter()
            manifest, _ = run_grid(load_study_file(grid, GridFile), tmp / f"out_{i:05d}", n_jobs=1)
            dt = time.perf_counter() - t
            times.append(dt / len(manifest))
            print(f"trial {i}: {len(manifest)} clips of {int(manifest['n_frames'].iloc[0])} frames, {dt:.1f} s "
                  f"({dt / len(manifest):.1f} s per clip){' (builds the character)' if i == 0 else ''}", flush=True)
    per_clip = statistics.median(times[1:] or times)
    rate = 60.0 / per_clip
    print(f"median {per_clip:.1f} s per clip -> {rate:.1f} clips/min at {args.size} px; target "
          f"{TARGET_CLIPS_PER_MINUTE:.0f}/min: ratio {rate / TARGET_CLIPS_PER_MINUTE:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
