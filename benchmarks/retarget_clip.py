"""A retargeted performance played on every stylisation level (issue 50): as far on the cartoon?

A synthetic actor (another ICT identity, its blendshapes the rig's scaled 0.6-1.6 per shape, 90
markers, ``--noise`` cm of noise; :mod:`stimulus_engine.characters.synthetic_actor`) performs its
warm-up, then a smooth take: ``--keys`` FACS-like expressions from the recipes at random
intensities, each eased in and out over ``--frames-per-key`` frames. The take is retargeted with
``appeal stimuli retarget``'s defaults (aligned actor blendshapes, Eq. 4.16 scale-free), and a grid
plays the recovered weights (``animation: {performance: ...}``) on the rig at shapes 0, 0.5 and 1
once with each expression transfer; printed per transfer: each judged measure's gain at every
level against the realistic one (1 = the same movement, as far in units of the face) and the
traces' correlation (``performance_agreement.csv``), and the recovered weights against the truth.
``--design`` ends the continuum in the shipped grids' designed head (GDQuest's Sophia, ElastiFace),
where the aligned transfer moves the cartoon at least 1.1x as far (stylised faces read as more
intense, thesis §6.5). The grids' filmstrips, ``performance_measures.png`` and clips stay in
``--out`` to look at.

Run::

    .venv/bin/python benchmarks/retarget_clip.py --out /tmp/retarget_clip
    .venv/bin/python benchmarks/retarget_clip.py --out /tmp/retarget_clip_design --design
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def smooth_take(act, keys: int, per_key: int, rng: np.random.Generator) -> np.ndarray:
    """(keys * per_key + 1, K) true weights: each key a recipe at a random intensity, eased in and out."""
    from stimulus_engine.characters.expressions import expression_weights, facs_recipes

    idx = {n: i for i, n in enumerate(act.names)}
    recipes = [e for e in sorted(facs_recipes()["expressions"]) if e != "neutral"]
    u = np.linspace(0.0, 1.0, per_key, endpoint=False)
    bump = np.sin(np.pi * u) ** 2  # 0 -> 1 -> 0
    rows = []
    for e in rng.choice(recipes, keys, replace=keys > len(recipes)):
        v = np.zeros(len(act.names))
        for s, x in expression_weights(str(e)).items():
            if s in idx:
                v[idx[s]] = x
        rows.append(bump[:, None] * v[None] * rng.uniform(0.6, 1.0))
    return np.vstack(rows + [np.zeros((1, len(act.names)))])


def grid_text(take: Path, transfer: str, design: bool, width: int) -> str:
    import yaml

    ict = "data:ict-facekit"
    text = (f"kind: grid\nname: retarget_{transfer}\ncharacters:\n  - {{name: a, ict: {ict}, identity: identity000}}\n"
            f"shapes: [0.0, 0.5, 1.0]\nmaterials: [original]\nexpressions: [happy]\nexpression_transfer: {transfer}\n"
            f"lighting: [gi_soft]\nshading: [pbr]\nrender: {{width: {width}, height: {width * 3 // 4}, shadows: false}}\n"
            f"animation: {{fps: 30, performance: {take}}}\n")
    if design:
        spec = yaml.safe_load((REPO / "protocols" / "grids" / "exp2_stylisation.yaml").read_text())["design"]
        spec["landmarks"] = str(REPO / "protocols" / "grids" / spec["landmarks"])
        text += "design: " + yaml.safe_dump(spec, default_flow_style=True, width=1000)
    return text


def main() -> None:
    import pandas as pd

    from appeal.datasets import resolve_reference
    from appeal.studyfile import load_study_file
    from stimulus_engine.characters.ict import load_ict_rig
    from stimulus_engine.characters.retarget import retarget_performance
    from stimulus_engine.characters.synthetic_actor import synthetic_actor
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True, help="folder for the take, the grids and the figures")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--actor", default="identity002", help="the actor's ICT identity")
    ap.add_argument("--noise", type=float, default=0.02, help="marker noise, cm (0.02: 0.2 mm)")
    ap.add_argument("--keys", type=int, default=6, help="expressions in the take")
    ap.add_argument("--frames-per-key", type=int, default=20)
    ap.add_argument("--width", type=int, default=512)
    ap.add_argument("--design", action="store_true", help="end the continuum in the shipped design (Sophia)")
    ap.add_argument("--transfers", nargs="+", default=["aligned", "deformation_transfer"])
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    ict = Path(resolve_reference("data:ict-facekit"))
    rig, actor = load_ict_rig(ict, "identity000", textures=False), load_ict_rig(ict, a.actor, textures=False)
    rng = np.random.default_rng(a.seed)
    act = synthetic_actor(rig, actor.vertices, seed=a.seed, noise=a.noise)
    truth = smooth_take(act, a.keys, a.frames_per_key, rng)
    clean = act.positions[0] + np.einsum("fk,kmc->fmc", truth, act.blendshapes)
    take = clean + rng.normal(0.0, a.noise, clean.shape)
    warm = act.positions[~act.test]  # the warm-up the aligned transfer learns from, then the take
    t = time.perf_counter()
    w = retarget_performance(rig, act.neutral, np.concatenate([warm, take]), act.markers)[len(warm):]
    print(f"retargeted {len(warm) + len(take)} frames in {time.perf_counter() - t:.1f} s; "
          f"take weights RMS against the truth {np.sqrt(np.mean((w - truth) ** 2)):.3f}")
    df = pd.DataFrame(w, columns=act.names)
    df.insert(0, "frame", range(len(df)))
    df.insert(1, "time", np.arange(len(df)) / 30)
    df.to_csv(a.out / "take.csv", index=False, float_format="%.6f")
    rows = []
    for transfer in a.transfers:
        (a.out / f"{transfer}.yaml").write_text(grid_text(a.out / "take.csv", transfer, a.design, a.width))
        grid = load_study_file(a.out / f"{transfer}.yaml", GridFile)
        t = time.perf_counter()
        run_grid(grid, a.out / transfer)
        agree = pd.read_csv(a.out / transfer / "performance_agreement.csv")
        print(f"{transfer}: grid of {len(grid.shape_levels())} clips x {len(df)} frames in {time.perf_counter() - t:.0f} s")
        for r in agree[agree["judged"] & (agree["shape"] > 0)].itertuples():
            rows.append({"transfer": transfer, "shape": r.shape, "measure": r.measure, "gain": r.gain,
                         "peak_ratio": r.peak_ratio, "correlation": r.correlation})
    table = pd.DataFrame(rows)
    print(table.round(3).to_string(index=False))
    for (transfer, shape), g in table.groupby(["transfer", "shape"]):
        print(f"{transfer} at shape {shape:g}: judged gains {g['gain'].min():.2f}-{g['gain'].max():.2f}, "
              f"largest |gain - 1| {abs(g['gain'] - 1).max():.2f}, correlation >= {g['correlation'].min():.3f}")
    print(f"filmstrips and performance_measures.png under {a.out}")


if __name__ == "__main__":
    main()
