"""A shipped grid's wall time now against another revision of the project (default: the one
before the complete-character work of issue 27), in the same run, alternating.

Each run is a whole ``appeal stimuli grid GRID --out DIR --force`` in its own process, with a
cold cache (the output folder is new every time): characters, materials, geometry, the mouth's
visibility and every image. The other revision runs from a ``git worktree`` of this checkout,
with the same virtual environment and data, on its own version of a shipped grid file (the
grid as it was shipped then: a field added since, such as a hair style, would not parse there). Prints each run's seconds, the medians and the
ratio now / then (machines are noisy: alternate, and read the median).

Measured 2026-11-26 on this 2-core machine (pyrender, OSMesa), the shipped Exp. 2 grid (250
images) with every part on (eyes aimed, lashes, mouth interior, hair styles, bust and garment):
64.0 and 66.2 s now against 57.3 and 55.2 s at e309ec3: median ratio 1.16 (the issue's bound: 1.5);
with the lids' shadow, one glint per eye and Kajiya-Kay hair (b1d00c5): 69.8 and 73.8 s against
60.9 and 60.9 s, ratio 1.18; with a scan's lid margins, the neck fade and blended hair (f17b266):
76.8 and 73.3 s against 63.1 and 61.8 s, ratio 1.20; anti-aliased by supersampling 1.5x
(b10fd2c): 89.9 and 87.9 s against 59.2 and 57.5 s, ratio 1.52 -- over the bound; with the
images rendered in runs that share an albedo (no re-upload of a 2400 x 1600 texture per image)
and a table-driven linear-light downsample: 84.1 and 84.2 s against 59.0 and 57.1 s, ratio 1.45.
With the material continuum measured on the cold run (issue 28, 96f7518: 9 candidate renders and
up to 3 rounds of the levels per character, cached for later runs): 194.3 s against 67.5 s,
ratio 2.88 (one repeat) -- over the bound on a first run. With the shipped grid's levels pinned
in its file (ceaad83: a study's levels are part of its protocol, measured once) and render
workers no longer restarted by loky at 300 MB: 82.5 and 82.6 s against 59.4 and 58.6 s, ratio
1.40. ``--measure`` drops the pins, so the cold run measures the continuum as a new grid file's
first run does (one probe per round for both characters, 5 candidates, stylised materials and
probe images reused): 106.7 s against 60.7 s (one run), ratio 1.76 on that first run only.
With the eyes, lashes and hair stylised along the scale (c85e223; the pinned grid): 89.4 and
87.2 s against 62.4 and 59.2 s, ratio 1.45.

Run:  .venv/bin/python benchmarks/grid_speed.py [--grid protocols/grids/exp2_stylisation.yaml]
          [--base e309ec3] [--repeats 2] [--measure]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: The last revision before issue 27's eyes, mouth, lashes and hair (the stimulus engine re-layout).
BASE = "e309ec3"


def _run(code_root: Path, grid: Path, out: Path, env: dict) -> float:
    """Seconds of one cold grid render with the project at ``code_root``."""
    cmd = [sys.executable, "-m", "appeal_cli", "stimuli", "grid", str(grid), "--out", str(out), "--force"]
    t = time.perf_counter()
    res = subprocess.run(cmd, cwd=code_root, env={**env, "PYTHONPATH": str(code_root)}, capture_output=True, text=True)
    seconds = time.perf_counter() - t
    if res.returncode != 0:
        raise SystemExit(f"grid_speed: {code_root}: the grid failed: {res.stderr.strip().splitlines()[-1:]}")
    return seconds


def _unpinned(grid: Path, tmp: Path) -> Path:
    """A copy of ``grid`` (in ``tmp``, its data paths as they were) without pinned continuum levels."""
    import yaml

    spec = yaml.safe_load(grid.read_text())
    for factor in ("materials", "shapes"):
        if isinstance(spec.get(factor), dict):
            spec[factor].pop("measured", None)
    out = tmp / grid.name
    out.write_text(yaml.safe_dump(spec, sort_keys=False))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=Path, default=ROOT / "protocols" / "grids" / "exp2_stylisation.yaml")
    ap.add_argument("--base", default=BASE, help="the revision to compare with (default: %(default)s)")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--measure", action="store_true",
                    help="drop the grid file's pinned continuum levels now: the first run measures them")
    args = ap.parse_args()
    grid = args.grid.resolve()
    data = os.environ.get("APPEAL_DATA") or str((ROOT.parent / "shared" / "data").resolve())
    env = {**os.environ, "APPEAL_DATA": data, "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "osmesa"),
           "MPLBACKEND": "Agg"}
    tmp = Path(tempfile.mkdtemp(prefix="grid_speed_"))
    now_grid = _unpinned(grid, tmp) if args.measure else grid
    base_root = tmp / "base"
    subprocess.run(["git", "worktree", "add", "--detach", "-q", str(base_root), args.base], cwd=ROOT, check=True)
    times: dict[str, list[float]] = {"then": [], "now": []}
    try:
        for i in range(args.repeats):
            for label, root in (("then", base_root), ("now", ROOT)):
                shipped = root / grid.relative_to(ROOT) if grid.is_relative_to(ROOT) else grid
                if label == "now":
                    shipped = now_grid
                s = _run(root, shipped if shipped.exists() else grid, tmp / f"{label}{i}", env)
                times[label].append(s)
                print(f"{label:>4} ({args.base if label == 'then' else 'this checkout'}) run {i + 1}: {s:.1f} s", flush=True)
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(base_root)], cwd=ROOT, check=False)
        shutil.rmtree(tmp, ignore_errors=True)
    then, now = statistics.median(times["then"]), statistics.median(times["now"])
    print(f"{grid.name}: median {now:.1f} s now, {then:.1f} s at {args.base}: ratio {now / then:.2f}")


if __name__ == "__main__":
    main()
