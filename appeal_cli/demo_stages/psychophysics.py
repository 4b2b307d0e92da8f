"""Demo stage 220: psychophysics along a rendered continuum — the realism 2AFC protocol run by
simulated observers in the real runner over a dense shape+material continuum of the embedded
scan, then psychometric functions fitted per participant and expression, thresholds compared."""

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

#: Simulated participants, and trials per psi track (one track per expression).
N_PARTICIPANTS, TRIALS = 6, 40


def _render_continuum(out: Path, seed: int) -> Path:
    """11 levels from the realistic scan (0) to the cartoon (1), shape and painted material together,
    happiness and anger: 22 small images."""
    from appeal.studyfile import validate_data
    from stimulus_engine.data import EMBEDDED_SCAN
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile

    spec = {"kind": "grid", "name": "demo_continuum",
            "characters": [{"name": "james", "procedural": {"seed": seed, "texture_size": 512, "resolution": 64},
                            "mesh": {"file": str(EMBEDDED_SCAN), "region": "front", "topology": "scan"}}],
            "shapes": {"levels": 11, "spacing": "even"}, "materials": {"levels": 11, "spacing": "even"},
            "pair_materials_with_shapes": True, "expressions": ["happiness", "anger"],
            "expression_transfer": "aligned", "lighting": ["gi_soft"], "shading": ["pbr"],
            "render": {"width": 320, "height": 240}}
    grid = validate_data(spec, GridFile, source=Path("demo_continuum.yaml"), base_dir=out)
    run_grid(grid, out / "continuum", n_jobs=2)
    return out / "continuum" / "manifest.csv"


def _protocol(out: Path, manifest: Path) -> Path:
    """The shipped realism 2AFC protocol on the demo's continuum, shorter."""
    data = yaml.safe_load((protocols_dir() / "realism_2afc.yaml").read_text())
    data["stimuli"]["manifest"] = str(manifest)
    data["stimuli"].pop("grid")
    data["psychophysics"]["procedure"]["max_trials"] = TRIALS
    data["psychophysics"]["practice_trials"] = 2
    path = out / "realism_2afc_demo.yaml"
    path.write_text(yaml.safe_dump(data, allow_unicode=True, sort_keys=False))
    return path


def _session(protocol: Path, out: Path, participant: str, seed: int, shots: Path | None) -> None:
    cmd = [sys.executable, "-m", "appeal_cli", "-q", "run", str(protocol), "--participant", participant, "--out",
           str(out), "--force", "--simulate", "default", "--seed", str(seed)]
    cmd += ["--screenshots", str(shots)] if shots is not None else ["--no-window"]
    res = subprocess.run(cmd, capture_output=True, text=True, check=False, timeout=600)
    if res.returncode != 0:
        raise AppealInputError(f"{protocol.name}: simulated session failed: {res.stderr.strip()[-300:]}")


def _run(out: Path, seed: int) -> ReportSection:
    import pandas as pd

    from analysis.psychometric import analyze_psychometric_study
    from analysis.psychometric.schema import PsychometricAnalysis
    from analysis.stats.reporting import format_p
    from appeal.studyfile import validate_data

    manifest = _render_continuum(out, seed)
    protocol = _protocol(out, manifest)
    window = bool(os.environ.get("DISPLAY"))
    for k in range(N_PARTICIPANTS):
        pid = f"{k + 1:02d}"
        shots = out / "screens" if window and k == 0 else None  # one session draws its screens in a window
        _session(protocol, out / "data" / f"sub-{pid}" / "ses-1" / "beh", pid, seed + k, shots)
    analysis = yaml.safe_load((protocols_dir() / "analysis" / "realism_threshold.yaml").read_text())
    analysis["data"] = "data/sub-*/ses-*/beh/*_task-realism2afc_beh.tsv"
    cfg = validate_data(analysis, PsychometricAnalysis, source=Path("realism_threshold.yaml"), base_dir=out)
    (out / "analysis").mkdir(exist_ok=True)
    res = analyze_psychometric_study(cfg, out / "analysis")
    pooled = res.pooled.set_index("expression")
    beh = pd.read_csv(next((out / "data" / "sub-01" / "ses-1" / "beh").glob("*_beh.tsv")), sep="\t")
    main = beh[beh["phase"] == "main"]
    sides = main["reference_side"].value_counts()
    anova = res.anova.set_index("effect").iloc[0] if res.anova is not None and len(res.anova) else None
    text = (f"The realism question as psychophysics (`protocols/realism_2afc.yaml`): on each trial the realistic "
            "face and the same face at a stylisation level the psi method picks (shape and painted material "
            "together, 11 levels spaced evenly by value, `shapes: {levels: 11, spacing: even}`; rendered here from "
            "the embedded scan) side by side, \"Which face looks more real?\". One psi track per expression, "
            f"interleaved, {TRIALS} trials each; {N_PARTICIPANTS} simulated observers with known psychometric "
            "functions (the default participant model: happy faces' stylisation noticed from 0.22, angry ones' "
            "from 0.38, ± 0.04 between observers) in the real runner"
            f"{' (the first in a window: its screens below)' if window else ''}. Participant 01's realistic face "
            f"was left {sides.get('left', 0)} and right {sides.get('right', 0)} times. "
            "`appeal analyze psychometric` then fitted a psignifit-style Bayesian logistic per participant and "
            "expression (guess 0.5, lapse and overdispersion free): the stylisation at which the realistic face is "
            "picked 75 % of the time, pooled over observers: "
            + "; ".join(f"{e} {row['x_at_pc']:.2f}" for e, row in pooled.iterrows())
            + (f". The per-observer thresholds differ between the expressions (rm-ANOVA): F({anova['num_df']:.0f}, "
               f"{anova['den_df']:.0f}) = {anova['F']:.1f}, {format_p(anova['p'])}" if anova is not None else "")
            + ". Full report: [analysis/index.html](analysis/index.html).")
    figures = [*res.figures[:1], *(f for f in (out / "analysis").glob("group*.png"))]
    if (out / "screens" / "stimulus.png").is_file():
        figures.append(out / "screens" / "stimulus.png")
    return ReportSection(title="Psychophysics: realism threshold along the continuum", text=text, figures=figures,
                         tables=[out / "analysis" / "pooled.csv", out / "analysis" / "fits.csv"],
                         links=[out / "analysis" / "index.html", protocol])


STAGE = DemoStage(name="psychophysics", title="Psychophysics: realism threshold along the continuum", order=220,
                  run=_run)
