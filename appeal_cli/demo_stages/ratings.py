"""Demo stage 300: simulated ratings for an Experiment-2-like design → the full rating analysis."""

from __future__ import annotations

from pathlib import Path

from appeal.demo import DemoStage
from appeal.report import ReportSection


def _run(out: Path, seed: int) -> ReportSection:
    from analysis.ratings_schema import RatingsAnalysis
    from analysis.stats.simulate import exp2_design, simulate_ratings, write_bids
    from analysis.stats.study import analyze_rating_study
    from appeal.atomic import atomic_write_text
    from appeal.studyfile import load_study_file

    factors, scales = exp2_design()
    data = simulate_ratings(factors, scales, n_subjects=21, seed=seed)
    write_bids(data, out / "data", task="exp2")
    study = out / "exp2_ratings.yaml"
    atomic_write_text(study, """kind: ratings
title: "Experiment 2 (simulated): shape x material x expression x character"
data: data/sub-*/ses-*/beh/*_task-exp2_beh.tsv
within: [character, shape, material, expression]
model: all                 # rm-ANOVA + linear mixed model + cumulative-link (ordinal) mixed model
mixed: {random: maximal}
contrasts: [{factor: shape}, {factor: material}]
figures:
  interactions: [{x: material, trace: shape}]
  bars: [expression]
  realism_vs_appeal: {x_scale: realism, y_scale: appeal, line: shape, point: material}
""")
    cfg = load_study_file(study, RatingsAnalysis)
    res = analyze_rating_study(cfg, out / "analysis")
    figures = [f for sec in res.sections for f in sec.figures]
    tables = [t for sec in res.sections for t in sec.tables
              if t.name in ("anova.csv", "lmm_anova.csv", "clmm_lr_tests.csv", "reliability.csv")]
    text = (f"21 simulated participants rated {len(data) // 21} stimuli (2 characters × 5 shape × 5 material × 5 "
            "expression levels, like thesis Experiment 2) for realism and appeal; the files are BIDS "
            "`*_beh.tsv` as the runner writes them. `appeal analyze ratings exp2_ratings.yaml` then ran the whole "
            "analysis: 4-way rm-ANOVA per scale with Mauchly/GG, Tukey post-hocs, trend contrasts, Cronbach's α, "
            "figures; beside it a linear mixed model of the 5,250 trials (participants as a random factor, the "
            "maximal random part simplified until the fit is not singular; each image is one cell, so stimuli "
            "cannot be a random factor here and the report says so) with type-III F tests (Satterthwaite) and "
            "EMMs, and a cumulative-link mixed model of the ratings as ordered categories with likelihood-ratio "
            "tests and predicted rating probabilities. Full report: [analysis/report.md](analysis/report.md), "
            "[analysis/index.html](analysis/index.html).\n\n")
    from analysis.stats.reporting import format_effect, format_p

    for name, info in res.summary["scales"].items():
        rows = {r["effect"]: r for r in info.get("anova", [])}
        lmm = {r["effect"]: r for r in info.get("lmm", {}).get("anova", [])}
        lr = {r["term"]: r for r in info.get("ordinal", {}).get("lr_tests", [])}
        picks = [e for e in ("shape", "material", "shape:material") if e in rows]
        text += f"- **{name}**: " + "; ".join(
            f"{e}: ANOVA {format_effect(rows[e])}" + (f"; LMM F({lmm[e]['num_df']}, {lmm[e]['den_df']:.0f}) = "
                                                     f"{lmm[e]['F']:.2f}, {format_p(lmm[e]['p'])}" if e in lmm else "")
            + (f"; ordinal LR χ²({lr[e]['df']}) = {lr[e]['lr_chisq']:.1f}, {format_p(lr[e]['p'])}" if e in lr else "")
            for e in picks) + "\n"
    return ReportSection(title="Rating statistics (simulated Experiment 2)", text=text, figures=figures, tables=tables,
                         links=[study, out / "analysis" / "report.md"])


STAGE = DemoStage(name="ratings", title="Rating statistics (simulated Experiment 2)", order=300, run=_run)
