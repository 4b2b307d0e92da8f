"""Cycles hair: seconds per image with strands (curves, Principled Hair BSDF) against the
alpha-tested hair mesh alone (what Cycles drew before), and the time to grow the strands.

Scene: the shipped Exp. 2 grid's Lee Perry-Smith (ICT rig, MakeHuman's short04 hair), realistic
shape and material, neutral, gi_soft, 1024 x 768, 16 samples + OpenImageDenoise (needs
../shared/data and ``make cycles``). The scene is exported once; the same ``scene.json`` is
rendered with its strands and with the strand flag removed, alternately, ``--repeats`` times
each; medians and the ratio are printed.

Run: .venv/bin/python benchmarks/cycles_hair.py [--repeats 2]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def _scene(folder: Path) -> Path:
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid.prepare import prepare_grid
    from stimulus_engine.grid.schema import GridFile
    from stimulus_engine.grid.worker import export_item_scene
    from stimulus_engine.render.hair_strands import grow_strands

    grid = yaml.safe_load((ROOT / "protocols/grids/exp2_stylisation.yaml").read_text())
    grid["characters"] = [c for c in grid["characters"] if c["name"] == "lps"]
    grid.update(shapes=[0.0], materials=["original"], expressions=["neutral"])
    path = folder / "lps.yaml"
    path.write_text(yaml.safe_dump(grid))
    _, items, _ = prepare_grid(load_study_file(path, GridFile), folder / "out")
    scene = export_item_scene(items[0], folder / "scene")  # 1024 x 768, gi_soft, as shipped
    spec = json.loads(scene.read_text())
    k = [p["name"] for p in spec["parts"]].index("hair")
    arrays = np.load(scene.parent / "parts.npz")
    alpha = np.asarray(Image.open(scene.parent / spec["parts"][k]["texture"]))[..., -1] > 127
    t = []
    for _ in range(3):
        t0 = time.perf_counter()
        grow_strands(arrays[f"v{k}"], arrays[f"f{k}"], arrays[f"uv{k}"], alpha, spec["mm_per_unit"])
        t.append(time.perf_counter() - t0)
    print(f"strands: {len(arrays[f'ss{k}'])} curves, {len(arrays[f'sp{k}'])} points, "
          f"grown in {statistics.median(t):.2f} s (median of 3)")
    spec["parts"][k].pop("strands")
    (scene.parent / "cards.json").write_text(json.dumps(spec))
    return scene


def main() -> None:
    from stimulus_engine.render.cycles import _WORKER, check_cycles

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args()
    exe = check_cycles()
    with tempfile.TemporaryDirectory() as tmp:
        scene = _scene(Path(tmp))
        times: dict[str, list[float]] = {"strands": [], "mesh only": []}
        for _ in range(a.repeats):
            for name, path in (("strands", scene), ("mesh only", scene.parent / "cards.json")):
                t0 = time.perf_counter()
                subprocess.run([str(exe), str(_WORKER), str(path), str(Path(tmp) / f"{name}.png"), "--samples", "16",
                                "--threads", str(os.cpu_count() or 1)], check=True, capture_output=True)
                times[name].append(time.perf_counter() - t0)
    med = {k: statistics.median(v) for k, v in times.items()}
    for k, v in med.items():
        print(f"Cycles {k:9s}: {v:6.1f} s per image (median of {a.repeats}: {', '.join(f'{x:.1f}' for x in times[k])})")
    print(f"ratio strands / mesh only: {med['strands'] / med['mesh only']:.2f}")


if __name__ == "__main__":
    main()
