"""Demo stage 200: simulated sessions of Experiment 2 and of the ERP study in the real runner.

PsychoPy runs in a subprocess (never in the process that rendered the grid with pyrender);
with a display (``make demo`` runs under Xvfb) the sessions draw every screen once in a
window and save screenshots, without one they run window-less on the virtual clock.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import yaml

from appeal.assets import protocols_dir
from appeal.demo import DemoStage
from appeal.errors import AppealInputError
from appeal.report import ReportSection


def _session(protocol: Path, out: Path, shots: Path, stimuli: Path, seed: int, window: bool) -> None:
    cmd = [sys.executable, "-m", "appeal_cli", "-q", "run", str(protocol), "--participant", "demo", "--out", str(out),
           "--force", "--simulate", "default", "--stimuli", str(stimuli), "--seed", str(seed)]
    cmd += ["--screenshots", str(shots)] if window else ["--no-window"]
    res = subprocess.run(cmd, capture_output=True, text=True, check=False, timeout=600)
    if res.returncode != 0:
        raise AppealInputError(f"{protocol.name}: simulated session failed: {res.stderr.strip()[-300:]}")


def _run(out: Path, seed: int) -> ReportSection:
    from experiments.drawn_faces import draw_face_grid

    window = bool(os.environ.get("DISPLAY"))
    grid_manifest = out.parent / "grid" / "manifest.csv"
    exp2 = yaml.safe_load((protocols_dir() / "exp2_stylisation.yaml").read_text())
    if grid_manifest.is_file():
        stim2, source = grid_manifest, "the rendered grid of the grid stage"
    else:
        stim2 = draw_face_grid(out / "faces_exp2", {"character": ["c1", "c2"], "shape": [0, 1, 2, 3, 4],
                                                    "material": [0, 2, 4], "expression": ["neutral", "happiness", "anger"]},
                               size=(400, 300))
        source = "simple drawn faces (no grid stage output found)"
        exp2["stimuli"].pop("levels")  # numeric levels, ordered naturally
    exp2["stimuli"]["manifest"] = str(stim2)
    exp2["stimuli"].pop("grid")
    exp2["anchors"]["if_missing"] = "skip"  # a grid without matching shape/material levels has no baselines
    p2 = out / "exp2_demo.yaml"
    p2.write_text(yaml.safe_dump(exp2, allow_unicode=True))
    _session(p2, out / "exp2", out / "screens_exp2", stim2, seed, window)
    erp_faces = draw_face_grid(out / "faces_erp", {"character": ["james", "lps"], "stylisation": list(range(6)),
                                                   "emotion": ["angry", "happy", "neutral"]}, size=(400, 300))
    _session(protocols_dir() / "erp_stylisation.yaml", out / "erp", out / "screens_erp", erp_faces, seed, window)
    import pandas as pd

    b2 = pd.read_csv(next((out / "exp2").glob("*_beh.tsv")), sep="\t")
    be = pd.read_csv(next((out / "erp").glob("*_beh.tsv")), sep="\t")
    seq = be["stimulus"].tolist()
    repeats = sum(a == b for a, b in zip(seq, seq[1:]))
    fix_ms = be["fixation_frames"] / 60 * 1000
    text = (f"Two sessions of simulated participants in the real runner ({'window, each screen drawn once' if window else 'no window'}; "
            "virtual clock: the clock advances by each screen's intended frames, so the sessions take seconds).\n\n"
            f"- **Experiment 2** on {source}: {len(b2)} trials ({(b2['phase'] == 'main').sum()} rated for realism and "
            f"appeal, 4 s each). Data: `exp2/*_beh.tsv`; session report: [exp2/report/index.html](exp2/report/index.html).\n"
            f"- **ERP study** (`protocols/erp_stylisation.yaml`) on drawn faces: {len(be)} trials, {repeats} immediate "
            f"repeats, fixation {fix_ms.min():.0f}-{fix_ms.max():.0f} ms, {be['trigger'].notna().sum()} triggers "
            "(one per onset). Session report: [erp/report/index.html](erp/report/index.html).")
    figures = [out / "erp" / "report" / "timing.png"]
    for d in ("screens_exp2", "screens_erp"):
        for name in ("stimulus", "realism", "fixation"):
            if (out / d / f"{name}.png").is_file():
                figures.append(out / d / f"{name}.png")
    tables = [out / "erp" / "report" / "summary.csv", out / "exp2" / "report" / "frames_intended_vs_shown.csv"]
    return ReportSection(title="Experiments (simulated sessions)", text=text, figures=figures, tables=tables,
                         links=[next((out / "exp2").glob("*_beh.tsv")), next((out / "erp").glob("*_beh.tsv")),
                                out / "exp2" / "report" / "index.html", out / "erp" / "report" / "index.html"])


STAGE = DemoStage(name="experiment", title="Experiments (simulated sessions)", order=200, run=_run)
