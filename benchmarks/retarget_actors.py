"""Benchmark: retargeting synthetic actors with a known truth, aligned against RBF and deformation transfer.

    python benchmarks/retarget_actors.py [--seeds 3] [--noise 0.05 0.2 0.3] [--frames 3000] [--ict PATH]

Actors (:mod:`stimulus_engine.characters.synthetic_actor`): the face kit's identity001 and identity002
and random identities of the ICT model's 100 components (``--more PATH``, default beside the kit),
each with its blendshapes scaled per shape by 0.6-1.6 (and, as a control, by 1), a ±10 % gain field,
a small rotation, 90 markers, a warm-up whose ramps overlap, 108 test frames, marker noise in mm.
Every actor is retargeted at the CLI's defaults (``retarget_performance``) with the aligned and the
RBF blendshapes, and with deformation transfer's (which needs the actor's whole mesh, which a
capture does not give; here it is known). Printed: the weight RMS, median |gain - 1| on the
blendshapes whose range differs (scale < 0.8 or > 1.25), the ratio aligned / RBF, and the medians.

Then the whole command, ``appeal stimuli retarget`` on a CSV of ``--frames`` frames, in a fresh
process: wall time, frames per second against the thesis's 105, and the start-up (``--help``).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from stimulus_engine.characters.blendshape_weights import retarget_frames  # noqa: E402
from stimulus_engine.characters.ict import ict_identity_basis, load_ict_rig  # noqa: E402
from stimulus_engine.characters.retarget import bending_prior, retarget_performance  # noqa: E402
from stimulus_engine.characters.synthetic_actor import recovery, synthetic_actor  # noqa: E402

THESIS_FPS = 105.0
DATA = Path(__file__).resolve().parents[2] / "shared/data/meshes"


def _actors(ict: Path, more: Path, n_random: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    faces = {n: load_ict_rig(ict, n, textures=False).vertices for n in ("identity001", "identity002")}
    if n_random and more.is_dir():
        mean = load_ict_rig(ict, "generic_neutral_mesh", textures=False).vertices
        basis = ict_identity_basis(ict, more)
        for i in range(n_random):  # the toolkit's randomize_identity: unit-variance components
            faces[f"random{i}"] = mean + np.einsum("k,knc->nc", rng.normal(size=len(basis)), basis)
    return faces


def _dt_markers(rig, face: np.ndarray, markers: np.ndarray) -> np.ndarray:
    from stimulus_engine.characters.expressions import deformation_transfer

    return np.stack([(deformation_transfer(rig.vertices, rig.vertices + rig.blendshapes[n], face, rig.faces) - face)[markers]
                     for n in sorted(rig.blendshapes)])


def _command(ict: Path, rig, face: np.ndarray, frames: int) -> tuple[float, float]:
    """Wall seconds of ``appeal stimuli retarget`` on ``frames`` frames, and of ``--help``."""
    act = synthetic_actor(rig, face, seed=99, n_test=max(frames - 479, 1))
    pos = act.positions[:frames]
    with tempfile.TemporaryDirectory() as tmp:
        rows = [(f, f"v{v}", *pos[f, i]) for f in range(len(pos)) for i, v in enumerate(act.markers)]
        pd.DataFrame(rows, columns=["frame", "marker", "x", "y", "z"]).to_csv(Path(tmp) / "take.csv", index=False)
        exe = [sys.executable, "-m", "appeal_cli"]
        t0 = time.perf_counter()
        subprocess.run([*exe, "stimuli", "retarget", "--help"], check=True, capture_output=True)
        start = time.perf_counter() - t0
        t0 = time.perf_counter()
        subprocess.run([*exe, "stimuli", "retarget", str(Path(tmp) / "take.csv"), "--ict", str(ict), "--out",
                        str(Path(tmp) / "w.csv")], check=True, capture_output=True)
        return time.perf_counter() - t0, start


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--random-identities", type=int, default=2)
    ap.add_argument("--noise", type=float, nargs="+", default=[0.05, 0.2, 0.3], help="marker noise, mm")
    ap.add_argument("--frames", type=int, default=3000)
    ap.add_argument("--ict", type=Path, default=DATA / "ict-facekit")
    ap.add_argument("--more", type=Path, default=DATA / "ict-facekit-more")
    args = ap.parse_args()
    rig = load_ict_rig(args.ict, "identity000", textures=False)
    prior = bending_prior(rig, sorted(rig.blendshapes))
    faces = _actors(args.ict, args.more, args.random_identities, np.random.default_rng(0))
    rows = []
    for name, face in faces.items():
        for seed in range(args.seeds):
            for noise in args.noise:
                for ranges in ("differ", "equal"):
                    act = synthetic_actor(rig, face, seed=1000 + seed, noise=noise / 10.0,
                                          scale_range=(0.6, 1.6) if ranges == "differ" else (1.0, 1.0))
                    differ = (act.scales < 0.8) | (act.scales > 1.25) if ranges == "differ" else np.ones(len(act.names), bool)
                    frames = act.positions - act.neutral[None]
                    got = {t: retarget_performance(rig, act.neutral, act.positions, act.markers, transfer=t)
                           for t in ("aligned", "rbf")}
                    got["deformation_transfer"] = retarget_frames(frames, _dt_markers(rig, face, act.markers), prior)
                    row = {"actor": name, "seed": seed, "noise_mm": noise, "ranges": ranges}
                    for method, w in got.items():
                        r = recovery(w, act, which=differ)
                        row[f"{method}_rms"], row[f"{method}_gain"] = r["rms"], r["gain"]
                    row["aligned_vs_rbf"] = row["aligned_rms"] / row["rbf_rms"]
                    rows.append(row)
                    print(" ".join(f"{k}={v:.3f}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()),
                          flush=True)
    table = pd.DataFrame(rows)
    print("\nmedians (the blendshapes whose range differs; with equal ranges: all):")
    print(table.groupby(["ranges", "noise_mm"]).median(numeric_only=True).drop(columns="seed").round(3).to_string())
    d = table[(table.ranges == "differ") & (table.noise_mm == 0.2)]
    e = table[(table.ranges == "equal") & (table.noise_mm == 0.2)]
    if len(d) and len(e):
        print(f"\n0.2 mm, ranges differ: aligned RMS median {d.aligned_rms.median():.3f} (issue: <= 0.10), "
              f"aligned/RBF median {d.aligned_vs_rbf.median():.2f} (<= 0.7; worst {d.aligned_vs_rbf.max():.2f}), "
              f"|gain-1| median {d.aligned_gain.median():.3f} (<= 0.15)")
        print(f"0.2 mm, equal ranges: aligned/RBF median {e.aligned_vs_rbf.median():.3f} (issue: <= 1.05; worst "
              f"{e.aligned_vs_rbf.max():.3f})")
    wall, start = _command(args.ict, rig, faces["identity002"], args.frames)
    print(f"\nappeal stimuli retarget, {args.frames} frames: {wall:.1f} s = {args.frames / wall:,.0f} frames/s "
          f"(thesis {THESIS_FPS:.0f}; ratio {args.frames / wall / THESIS_FPS:.1f}x); start-up (--help) {start:.1f} s "
          "(issue: <= 2 s)")
    times = []
    act = synthetic_actor(rig, faces["identity002"], seed=5, n_test=max(args.frames - 479, 1))
    for _ in range(3):
        t0 = time.perf_counter()
        retarget_performance(rig, act.neutral, act.positions, act.markers)
        times.append(time.perf_counter() - t0)
    print(f"retarget_performance alone (align + solve), {len(act.positions)} frames: median "
          f"{statistics.median(times):.2f} s = {len(act.positions) / statistics.median(times):,.0f} frames/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
