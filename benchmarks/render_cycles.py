"""Path-traced tier: seconds per 1024 x 768 Cycles image, images per minute, beside pyrender.

Scene: the menpo3d james scan drawn as itself (ICT rig, needs ../shared/data), neutral, under
the three lighting presets of Exp. 1b (direct_hard, direct_soft, gi_soft), PBR skin, the
grid's defaults (16 samples + OpenImageDenoise). The inputs are prepared once; the timings are
the rendering only, through the grid's own parallel map:

* seconds per image, one process (Cycles uses every core), median over the presets, beside
  pyrender's time for the same images (the fast tier) and the ratio;
* images per minute with 1 and 2 worker processes (each Cycles process then shares the cores)
  and on a ``dask.distributed`` ``LocalCluster`` (2 workers x 1 thread), the way a cluster
  spreads a 250-image grid over machines;
* noise: the mean and 99th-percentile difference of the 16-sample image to a 64-sample one.

Run: .venv/bin/python benchmarks/render_cycles.py   (after ``make cycles``)
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def _items(folder: Path):
    from appeal.assets import shared_data_dir
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid.examples import james_grid
    from stimulus_engine.grid.prepare import prepare_grid
    from stimulus_engine.grid.schema import GridFile

    p = james_grid(folder / "cycles_bench.yaml", shared_data_dir(), lighting=("direct_hard", "direct_soft", "gi_soft"),
                   render="{width: 1024, height: 768, engine: cycles}")
    grid = load_study_file(p, GridFile)
    _, items, _ = prepare_grid(grid, folder / "out")
    return items


def _timed_map(items, n_jobs=None, scheduler=None) -> float:
    from appeal.parallel import parallel_map
    from stimulus_engine.grid.worker import render_item

    t = time.perf_counter()
    res = parallel_map(render_item, items, n_jobs=n_jobs, scheduler=scheduler, desc="rendering")
    if not res.ok:
        raise RuntimeError(res.summary())
    return time.perf_counter() - t


def main() -> None:
    from dataclasses import replace

    from stimulus_engine.grid.worker import ENGINES
    from stimulus_engine.render.cycles import cycles_python

    if cycles_python() is None:
        print("Cycles not installed: run 'make cycles'")
        return
    with tempfile.TemporaryDirectory() as tmp:
        items = _items(Path(tmp))
        per, py = [], []
        for it in items:
            t = time.perf_counter()
            ENGINES["cycles"](it)
            per.append(time.perf_counter() - t)
            ENGINES["pyrender"](replace(it, engine="pyrender"))  # warm-up: texture upload, shader compile
            t = time.perf_counter()
            ENGINES["pyrender"](replace(it, engine="pyrender"))
            py.append(time.perf_counter() - t)
        s_cy, s_py = statistics.median(per), statistics.median(py)
        print(f"Cycles, 1024x768, {items[0].samples} samples + denoiser, 1 process: {s_cy:.1f} s/image "
              f"(median over {len(items)} presets: {', '.join(f'{x:.1f}' for x in per)}; target <= 30 s)")
        print(f"pyrender, same images: {1000 * s_py:.0f} ms/image; ratio Cycles/pyrender {s_cy / s_py:.0f}x")
        for jobs in (1, 2):
            batch = [replace(it, out_dir=str(Path(tmp) / f"j{jobs}")) for it in items * 2]
            Path(tmp, f"j{jobs}").mkdir()
            dt = _timed_map(batch, n_jobs=jobs)
            print(f"  {jobs} process(es): {60 * len(batch) / dt:.2f} images/min ({len(batch)} images in {dt:.0f} s)")
        from dask.distributed import LocalCluster

        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            batch = [replace(it, out_dir=str(Path(tmp) / "dask")) for it in items * 2]
            Path(tmp, "dask").mkdir()
            dt = _timed_map(batch, scheduler=cluster.scheduler_address)
            print(f"  dask LocalCluster (2 workers): {60 * len(batch) / dt:.2f} images/min ({len(batch)} images in {dt:.0f} s)")
        a = ENGINES["cycles"](items[0])
        b = ENGINES["cycles"](replace(items[0], samples=64))
        face = np.abs(a.astype(int) - 128).sum(-1) > 30
        d = np.abs(a.astype(int) - b.astype(int))[face]
        print(f"noise: 16 vs 64 samples, face pixels: mean |diff| {d.mean():.2f}, 99th percentile {np.percentile(d, 99):.0f} "
              "grey levels")
        sheet = Path(tempfile.gettempdir()) / "render_cycles_16_vs_64.png"
        Image.fromarray(np.hstack([a, b])).save(sheet)
        print(f"  16 | 64 samples side by side: {sheet}")


if __name__ == "__main__":
    main()
