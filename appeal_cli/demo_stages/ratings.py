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
    cov_text, cov_links = _covariate_study(out, seed)
    return ReportSection(title="Rating statistics (simulated Experiment 2)", text=text + cov_text, figures=figures,
                         tables=tables, links=[study, out / "analysis" / "report.md", *cov_links])


#: The simulated raters' preference for fine detail: appeal points per unit of face edge density.
EDGE_EFFECT = 25.0


def _covariate_study(out: Path, seed: int) -> tuple[str, list[Path]]:
    """Simulated appeal ratings of the grid stage's rendered scan images, analysed with one of their
    audited measures (face edge density) as a covariate: the mixed model's slope recovers the
    simulated preference, the shape effect is tested at the mean edge density."""
    import pandas as pd

    from analysis.ratings_schema import RatingsAnalysis
    from analysis.stats.simulate import ScaleModel, simulate_ratings, write_bids
    from analysis.stats.study import analyze_rating_study
    from appeal.atomic import atomic_write_text
    from appeal.levels import level_key, sort_levels
    from appeal.studyfile import load_study_file

    audit_csv = out.parent / "grid" / "scan" / "audit" / "audit.csv"
    if not audit_csv.is_file():
        return ("\n*Audit covariate example skipped: it rates the grid stage's images (run the grid stage too).*\n", [])
    audit = pd.read_csv(audit_csv)
    names = ["shape", "material", "expression"]
    levels = {f: [level_key(v) for v in sort_levels(audit[f].unique())] for f in names}
    key = {tuple(level_key(r[f]) for f in names): r for r in audit.to_dict("records")}
    mean_edge = float(audit["face_edge_density"].mean())

    def appeal(c: dict) -> float:
        row = key[tuple(levels[f][c[f]] for f in names)]
        return 4.6 - 0.6 * c["shape"] + EDGE_EFFECT * (row["face_edge_density"] - mean_edge)

    data = simulate_ratings(levels, {"appeal": ScaleModel(mean=appeal, subject_sd=0.6, slope_sd=0.1, noise_sd=0.8)},
                            n_subjects=21, seed=seed + 7)
    data["stimulus"] = [key[tuple(r)]["file"] for r in data[names].itertuples(index=False)]
    write_bids(data, out / "scan_data", task="scan")
    study = out / "scan_covariates.yaml"
    atomic_write_text(study, f"""kind: ratings
title: "Appeal of the rendered scan, adjusted for face edge density (simulated raters)"
data: scan_data/sub-*/ses-*/beh/*_task-scan_beh.tsv
within: [shape]            # material and expression left out: each shape level holds 12 images that differ in edge density
scales: [appeal]
model: both                # rm-ANOVA on ANCOVA-adjusted cell means + linear mixed model with the covariate
mixed: {{random: "(1 | participant_id) + (1 | stimulus)"}}
covariates: {{audit: {audit_csv.resolve()}, measures: [face_edge_density]}}
""")
    res = analyze_rating_study(load_study_file(study, RatingsAnalysis), out / "analysis_covariates")
    info = res.summary["scales"]["appeal"]
    cov = info["lmm"]["covariates"][0]
    shape = {r["effect"]: r for r in info["lmm"]["anova"]}["shape"]
    from analysis.stats.reporting import format_p

    text = (f"\n**Audit measures as covariates.** 21 simulated raters judged the appeal of the grid stage's "
            f"{len(audit)} rendered scan images; they like fine detail ({EDGE_EFFECT:g} appeal points per unit of "
            "face edge density, the measure `appeal stimuli audit` wrote for every image). "
            "`covariates: {audit: .../scan/audit/audit.csv, measures: [face_edge_density]}` in the analysis file "
            f"([scan_covariates.yaml](scan_covariates.yaml)) joins the audit to the trials by stimulus: the mixed "
            f"model's slope is b = {cov['estimate']:.1f} (SE {cov['se']:.1f}, {format_p(cov['p'])}; simulated "
            f"{EDGE_EFFECT:g}), and shape is tested at the mean edge density: F({shape['num_df']}, "
            f"{shape['den_df']:.1f}) = {shape['F']:.2f}, {format_p(shape['p'])}; the rm-ANOVA gets an ANCOVA-style "
            f"adjustment (b = {info['ancova']['slopes']['face_edge_density']:.1f}). Report: "
            "[analysis_covariates/report.md](analysis_covariates/report.md).\n")
    return text, [study, out / "analysis_covariates" / "report.md"]


STAGE = DemoStage(name="ratings", title="Rating statistics (simulated Experiment 2)", order=300, run=_run)
