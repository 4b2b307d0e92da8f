"""The whole analysis of a rating study (``kind: ratings``): every scale, every effect, post-hocs
of significant effects, contrasts, Cronbach's alpha between scales, figures and a report.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.stats.anova import fit_design
from analysis.stats.contrasts import compare_trends, contrasts_from_design
from analysis.stats.covariates import MIXED_HINT, CovariateSet, ancova_adjust, check_estimable, prepare_covariates
from analysis.stats.design import keep_rows, prepare_design, read_ratings
from analysis.stats.intervals import within_ci_from_design
from analysis.stats.mixed import mixed_model_anova
from analysis.stats.plots import bar_plot, interaction_plot, realism_vs_appeal_plot, reference_plot
from analysis.stats.posthoc import pairwise_comparisons
from analysis.stats.records import json_records, write_csv
from analysis.stats.reference import reference_table
from analysis.stats.reliability import cronbach_alpha
from analysis.stats.reporting import anova_text, format_comparison, markdown_table, sphericity_corrected
from appeal.atomic import atomic_write_text
from appeal.errors import AppealInputError
from appeal.labels import shown
from appeal.logs import logger
from appeal.outputs import require_inside
from appeal.progress import progress
from appeal.report import ReportSection, write_index_html

__all__ = ["scale_columns", "analyze_rating_study", "StudyResult", "json_records"]

#: A scale name found in the data (``response_<name>``), as the protocol's response names.
_SCALE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,39}")


@dataclass
class StudyResult:
    """What :func:`analyze_rating_study` wrote."""

    sections: list[ReportSection] = field(default_factory=list)
    report_md: Path | None = None
    index_html: Path | None = None
    summary: dict = field(default_factory=dict)


def scale_columns(data: pd.DataFrame, requested: list[str] | None, source: str) -> dict[str, str]:
    """Map scale names to columns: ``response_<name>`` (runner files) or ``<name>`` (long tables).

    Without ``requested`` every ``response_*`` column is a scale.
    """
    if requested is None:
        found = {str(c).removeprefix("response_"): c for c in data.columns if str(c).startswith("response_")}
        if not found:
            raise AppealInputError(f"{source}: scales: no response_* columns found; name the DV columns under 'scales:'")
        bad = [c for c in found if not _SCALE_NAME.fullmatch(c)]
        if bad:  # the name of an output folder: a column of the data must not name ../../x
            raise AppealInputError(f"{source}: scales: column {shown('response_' + bad[0], 60)}: expected "
                                   "response_<name> with a name of letters, digits and _ (at most 40, starting with "
                                   "a letter: it names an output folder); name the DV columns under 'scales:'")
        return found
    out, missing = {}, []
    for name in requested:
        col = f"response_{name}" if f"response_{name}" in data.columns else name
        (out.__setitem__(name, col) if col in data.columns else missing.append(name))
    if missing:
        raise AppealInputError(f"{source}: scales: no column response_<name> or <name> for {', '.join(missing)}")
    return out


def _reference(cfg, raw: pd.DataFrame, main: pd.DataFrame, col: str, name: str, sec_dir: Path,
               ylim: tuple | None, source: str) -> tuple[list[str], list[Path], list[Path], list[dict]]:
    """The reference's ratings beside the matched levels: text, figure, table, records."""
    ref = cfg.reference
    rows = keep_rows(raw, ref.rows)
    if rows.empty or rows[col].isna().all():  # e.g. Exp. 2 run without photographs (if_missing: skip)
        logger.warning("%s: reference: no %s ratings (rows %s): the comparison is left out", source, ref.name, ref.rows)
        return [f"No {ref.name} ratings in the data (rows {ref.rows}): the comparison is left out.", ""], [], [], []
    table = reference_table(rows, main, col, cfg.subject, ref.matched, cfg.levels, ref.name, source)
    safe = ref.name.replace(" ", "_")
    tables = [write_csv(table, sec_dir / f"reference_{safe}.csv")]
    figs = [reference_plot(table, name, sec_dir / f"reference_{safe}", ylim)[0]]
    r = table.iloc[0]
    lines = [f"{ref.name}: mean {r['mean']:.2f} (SD {r['sd']:.2f}, n = {int(r['n'])}); matched "
             f"{' / '.join(ref.matched)} levels (paired t-tests, Holm):", ""]
    for _, row in table.iloc[1:].iterrows():
        test = (f"; {ref.name} − level = {row['diff']:+.2f}, t({int(row['df'])}) = {row['t']:.2f}, "
                f"p_Holm = {row['p_holm']:.3g}") if np.isfinite(row["p"]) else ""
        lines.append(f"- {row['condition']}: {row['mean']:.2f} (SD {row['sd']:.2f}){test}")
    return lines + [""], figs, tables, json_records(table)


def _trials(cfg, data: pd.DataFrame, col: str) -> pd.DataFrame:
    """The trial-level rows a mixed model uses (the response as numbers)."""
    return data.assign(**{col: pd.to_numeric(data[col], errors="coerce")})


def _lmm(cfg, data: pd.DataFrame, col: str, name: str, sec_dir: Path, source: str,
         covariates: Sequence[str] = (), means: dict | None = None) -> tuple[list[str], list, list, dict]:
    """The linear mixed model of one scale (``model: mixed | both | all``)."""
    from analysis.stats.formula import FormulaError
    from analysis.stats.lmm_report import lmm_section

    groups = [cfg.subject] + ([cfg.stimulus] if cfg.stimulus and cfg.stimulus in data.columns else [])
    try:
        sec = lmm_section(_trials(cfg, data, col), col, name, list(cfg.within) + list(cfg.between), groups,
                          sec_dir, random=cfg.mixed.random, ddf=cfg.mixed.ddf, levels=cfg.levels, alpha=cfg.alpha,
                          max_order=cfg.posthoc.max_order, max_cells=cfg.posthoc.max_cells,
                          figures=[(f.x, f.trace) for f in cfg.figures.interactions],
                          ylim=tuple(cfg.scale_range) if cfg.scale_range else None, source=f"{source}: mixed",
                          covariates=covariates, covariate_means=means)
    except FormulaError as exc:
        raise AppealInputError(str(exc)) from None
    return ["### Linear mixed model", "", *sec.text], sec.figures, sec.tables, sec.records


def _ordinal(cfg, data: pd.DataFrame, col: str, name: str, sec_dir: Path, source: str,
             covariates: Sequence[str] = ()) -> tuple[list[str], list, list, dict]:
    """The cumulative-link mixed model of one scale (``model: ordinal | all``)."""
    from analysis.stats.clmm import fit_clmm, likelihood_ratio_tests
    from analysis.stats.clmm_figures import probability_plot
    from analysis.stats.formula import FormulaError
    from analysis.stats.lmm_report import model_formula
    from analysis.stats.random_structures import identifiable_groups

    factors = list(cfg.within) + list(cfg.between)
    trials = _trials(cfg, data, col)
    groups = [g for g in [cfg.subject] + ([cfg.stimulus] if cfg.stimulus and cfg.stimulus in data.columns else [])
              if trials[g].nunique() >= 3]
    src = f"{source}: ordinal"
    if covariates:
        check_estimable(trials.dropna(subset=[col]), covariates, [factors], source=src, hint=MIXED_HINT)
    try:
        groups, dropped = identifiable_groups(trials, model_formula(col, factors, covariates), groups, factors + groups,
                                              cfg.levels, src)
        formula = model_formula(col, factors, covariates) + "".join(f" + (1 | {g})" for g in groups)
        fit = fit_clmm(formula, trials, link=cfg.ordinal.link, factors=factors + groups, levels=cfg.levels, source=src)
        lr = likelihood_ratio_tests(fit)
    except FormulaError as exc:
        raise AppealInputError(str(exc)) from None
    shown = [f.x for f in cfg.figures.interactions][:1] or factors[:1]
    panel = next((f.trace for f in cfg.figures.interactions if f.trace), None)
    keep = [f for f in dict.fromkeys(shown + ([panel] if panel else []))]
    probs = fit.predicted_probabilities(keep)
    tables = [write_csv(fit.coefficients(), sec_dir / "clmm_coefficients.csv"), write_csv(fit.thresholds(), sec_dir / "clmm_thresholds.csv"),
              write_csv(lr, sec_dir / "clmm_lr_tests.csv"), write_csv(probs, sec_dir / "clmm_probabilities.csv")]
    figs = [probability_plot(probs, sec_dir / "clmm_probabilities", x=shown[0], panel=panel, scale_label=name)[0]]
    sds = "; ".join(f"{r.group} SD {r.sd:.3f}" for r in fit.variance_components().itertuples())
    text = ["### Ordinal (cumulative-link) mixed model", "",
            f"**Cumulative-link mixed model** ({cfg.ordinal.link} link, flexible thresholds, Laplace approximation, "
            f"as ordinal::clmm) of the ratings as ordered categories, {fit.n} trials: `{formula}`; "
            f"log-likelihood {fit.loglik:.2f}, random intercepts: {sds}."
            + (f" Left out: {', '.join(dropped)} (each level within one cell of the fixed effects)." if dropped else ""),
            "", "Likelihood-ratio tests of the fixed terms (each term's columns left out, sum-to-zero coding):", "",
            markdown_table(lr), "",
            f"Predicted probability of each rating per {' × '.join(keep)} (random effects at 0): "
            f"`{(sec_dir / 'clmm_probabilities.csv').name}`.", ""]
    info = {"formula": formula, "link": cfg.ordinal.link, "loglik": fit.loglik, "lr_tests": json_records(lr),
            "converged": fit.converged, "max_grad": fit.max_grad}
    return text, figs, tables, info


def analyze_rating_study(cfg, out: Path, data: pd.DataFrame | None = None) -> StudyResult:
    """Run the analysis described by a :class:`analysis.ratings_schema.RatingsAnalysis`.

    Parameters
    ----------
    cfg : RatingsAnalysis
        The validated study file.
    out : Path
        Output folder (exists; the caller manages it with ``appeal.outputs.output_run``).
    data : DataFrame, optional
        Use this table instead of reading ``cfg.data``.

    Returns
    -------
    StudyResult
        Report sections, ``report.md``, ``index.html`` and a summary dict (also in
        ``results.json``).
    """
    data = read_ratings(cfg.data, subject=cfg.subject) if data is None else data
    raw, data = data, keep_rows(data, cfg.rows)
    source = data.attrs.get("source", str(cfg.data))
    scales = scale_columns(data, cfg.scales, source)
    cov: CovariateSet | None = None
    if cfg.covariates is not None:
        spec = cfg.covariates
        cov = prepare_covariates(data, spec.audit, spec.measures, spec.by, source)
        data = cov.data
    measures = cov.measures if cov is not None else []
    result = StudyResult()
    md = [f"# {cfg.title}", "", f"Data: `{source}` — {data[cfg.subject].nunique()} participants, {len(data)} rows. "
          f"Design: within {' × '.join(cfg.within)}" + (f", between {' × '.join(cfg.between)}" if cfg.between else "")
          + f". Scales: {', '.join(scales)}.", "",
          "Repeated-measures ANOVA (type III; Mauchly's test; Greenhouse–Geisser correction, marked F*, "
          f"when Mauchly is significant at α = {cfg.alpha}); Tukey HSD for significant effects "
          "(from each effect's error stratum, as emmeans); 95% within-subject CIs (Cousineau–Morey).", ""]
    if cov is not None:
        md += [f"Covariates: stimulus audit measures {', '.join(cov.measures)} from `{cov.audit}`, joined by "
               f"`{cfg.covariates.by}` and centred at their grand mean"
               + (f" ({cov.dropped} rows without a stimulus left out)" if cov.dropped else "") + ".", ""]
    summary: dict = {"title": cfg.title, "scales": {}, "reliability": []}
    if cov is not None:
        summary["covariates"] = {"audit": cov.audit, "measures": cov.measures, "means": cov.means, "rows_left_out": cov.dropped}
    run_anova = cfg.model in ("anova", "both", "all")
    run_mixed = cfg.model in ("mixed", "both", "all")
    run_ordinal = cfg.model in ("ordinal", "all")
    designs = {}
    for name, col in progress(list(scales.items()), desc="scales"):
        sec_dir = out / name
        require_inside(out, sec_dir, f"scales: {name}")
        figs, tables = [], []
        try:
            design = prepare_design(data, col, cfg.subject, cfg.within, cfg.between, cfg.aggregate,
                                    drop_incomplete=cfg.incomplete != "error", scale=cfg.scale_range,
                                    levels=cfg.levels, source=source)
        except AppealInputError as exc:
            if cfg.incomplete != "mixed" or "at least 2 complete subjects" not in str(exc):
                raise
            design = None
        text = [f"## {name}", ""]
        info: dict = {"column": col}
        if design is None or design.dropped:
            # incomplete design: the linear mixed model on all data is the primary analysis
            n_drop = "all" if design is None else len(design.dropped)
            if cfg.incomplete == "mixed":
                stim = cfg.stimulus if cfg.stimulus and cfg.stimulus in data.columns and cfg.aggregate is None else None
                mixed = mixed_model_anova(data.assign(**{col: pd.to_numeric(data[col], errors="coerce")}), col,
                                          cfg.subject, cfg.within, cfg.between, stimulus=stim, aggregate=cfg.aggregate)
                tables.append(write_csv(mixed, sec_dir / "mixed_model.csv"))
                text += [f"{n_drop} participant(s) miss cells of the design "
                         f"({', '.join(design.dropped) if design else 'every participant'}). Analysis used: **linear mixed "
                         "model** (statsmodels MixedLM, REML, random intercept per participant"
                         + (" and per stimulus" if stim else "") + ", type-III Wald χ²) on all "
                         f"{mixed.attrs['n_obs']} observations, so nobody is dropped. The rm-ANOVA below uses only the "
                         "complete participants, for comparison.", "", markdown_table(mixed.drop(columns="method")), ""]
                info["analysis"] = "mixed model"
                info["mixed_model"] = json_records(mixed)
            else:
                text += [f"Dropped {n_drop} incomplete participant(s): {', '.join(design.dropped)}.", ""]
                info["analysis"] = "rm-ANOVA (incomplete participants dropped)"
            if design is None:
                result.sections.append(ReportSection(title=f"Scale: {name}", text="\n".join(text[2:]), tables=tables))
                md += text
                summary["scales"][name] = info
                continue
        info.setdefault("analysis", "rm-ANOVA")
        adjustment = None
        if run_anova and measures:
            adjusted, adjustment = ancova_adjust(data, col, list(cfg.within) + list(cfg.between), cfg.subject, measures,
                                                 means=cov.means, source=source)
            design = prepare_design(adjusted, col, cfg.subject, cfg.within, cfg.between, cfg.aggregate,
                                    drop_incomplete=cfg.incomplete != "error", levels=cfg.levels, source=source)
            info["ancova"] = {"slopes": adjustment.slopes, "means": adjustment.means, "n_trials": adjustment.n}
        designs[name] = design
        if run_anova:
            fit = fit_design(design)
            table = fit.table
            tables.append(write_csv(table, sec_dir / "anova.csv"))
            text += [anova_text(table, cfg.alpha), ""] + ([adjustment.text, ""] if adjustment else [])
            info["anova"] = json_records(table)
            info["n_subjects"], info["dropped"] = design.n, design.dropped
            # post-hocs for significant effects
            ph_lines = []
            for _, row in table.iterrows():
                p = row["p_gg"] if sphericity_corrected(row, cfg.alpha) else row["p"]
                factors = row["effect"].split(":")
                n_cells = int(np.prod([len({**design.within, **design.between}[f]) for f in factors]))
                if p >= cfg.alpha or len(factors) > cfg.posthoc.max_order or n_cells > cfg.posthoc.max_cells:
                    continue
                ph = pairwise_comparisons(fit, row["effect"], cfg.posthoc.adjust)
                tables.append(write_csv(ph, sec_dir / f"posthoc_{row['effect'].replace(':', '_x_')}.csv"))
                sig = ph[ph.p < cfg.alpha]
                shown = "; ".join(format_comparison(r) for _, r in sig.assign(_abs=sig.t.abs()).nlargest(4, "_abs").iterrows())
                ph_lines.append(f"- {row['effect']}: {len(sig)} of {len(ph)} pairs differ ({cfg.posthoc.adjust}, "
                                f"α = {cfg.alpha})" + (f"; strongest: {shown}" if shown else ""))
            if ph_lines:
                text += ["Post-hoc comparisons:", "", *ph_lines, ""]
            for spec in cfg.contrasts:
                ct = contrasts_from_design(design, spec.factor, spec.max_degree)
                tables.append(write_csv(ct, sec_dir / f"contrasts_{spec.factor}.csv"))
                text += [f"Polynomial contrasts of {spec.factor}:", "", markdown_table(ct), ""]
                if len(ct) >= 2:
                    text += [compare_trends(ct)["text"], ""]
        # figures
        ylim = tuple(cfg.scale_range) if cfg.scale_range else None
        for spec in cfg.figures.interactions:
            fac = [spec.trace, spec.x] if spec.trace else [spec.x]
            ci = within_ci_from_design(design, fac)
            stem = sec_dir / (f"interaction_{spec.x}" + (f"_by_{spec.trace}" if spec.trace else ""))
            figs.append(interaction_plot(ci, spec.x, spec.trace, name, stem, ylim=ylim)[0])
        for factor in cfg.figures.bars:
            ci = within_ci_from_design(design, [factor])
            figs.append(bar_plot(ci, factor, name, sec_dir / f"bars_{factor}", ylim=ylim)[0])
        if cfg.reference is not None:
            rtext, rfigs, rtables, info["reference"] = _reference(cfg, raw, data, col, name, sec_dir, ylim, source)
            text, figs, tables = text + rtext, figs + rfigs, tables + rtables
        if run_mixed:
            mtext, mfigs, mtables, info["lmm"] = _lmm(cfg, data, col, name, sec_dir, source, measures,
                                                      cov.means if cov is not None else None)
            text, figs, tables = text + mtext, figs + mfigs, tables + mtables
        if run_ordinal:
            otext, ofigs, otables, info["ordinal"] = _ordinal(cfg, data, col, name, sec_dir, source, measures)
            text, figs, tables = text + otext, figs + ofigs, tables + otables
        result.sections.append(ReportSection(title=f"Scale: {name}", text="\n".join(text[2:]), figures=figs, tables=tables))
        md += text + [f"![{Path(f).stem}]({Path(f).relative_to(out)})" for f in figs] + [""]
        summary["scales"][name] = info

    # between-scale figure and reliability
    extra_figs, extra_tables, extra_text = [], [], []
    sc = cfg.figures.realism_vs_appeal
    if sc is not None and sc.x_scale in designs and sc.y_scale in designs:
        cx = within_ci_from_design(designs[sc.x_scale], [sc.line, sc.point])
        cy = within_ci_from_design(designs[sc.y_scale], [sc.line, sc.point])
        lim = tuple(cfg.scale_range) if cfg.scale_range else None
        extra_figs.append(realism_vs_appeal_plot(cx, cy, sc.line, sc.point, out / f"{sc.x_scale}_vs_{sc.y_scale}",
                                                 sc.x_scale, sc.y_scale, lim=lim)[0])
    groups = cfg.reliability or ([list(scales)] if len(scales) >= 2 else [])
    by = [cfg.subject] + ([cfg.stimulus] if cfg.stimulus and cfg.stimulus in data.columns else list(cfg.within) + list(cfg.between))
    rel_rows = []
    for group in groups:
        missing = [g for g in group if g not in scales]
        if missing:
            raise AppealInputError(f"{source}: reliability: unknown scale(s) {', '.join(missing)} (scales: {', '.join(scales)})")
        frame = data[by + [scales[g] for g in group]].rename(columns={scales[g]: g for g in group})
        res = cronbach_alpha(frame, group, by=by)
        rel_rows.append({"scales": " + ".join(group), **res.to_dict()})
    if rel_rows:
        rel = pd.DataFrame(rel_rows)
        extra_tables.append(write_csv(rel, out / "reliability.csv"))
        extra_text += ["Cronbach's α between scales (observations = participant × stimulus, Feldt 95% CI):", ""]
        extra_text += [f"- {r['scales']}: α = {r['alpha']:.2f} [{r['ci_low']:.2f}, {r['ci_high']:.2f}]" for r in rel_rows]
        summary["reliability"] = json_records(rel)
    if extra_figs or extra_text:
        result.sections.append(ReportSection(title="Between scales", text="\n".join(extra_text), figures=extra_figs,
                                             tables=extra_tables))
        md += ["## Between scales", "", *extra_text, ""] + [f"![{Path(f).stem}]({Path(f).relative_to(out)})" for f in extra_figs]

    result.report_md = out / "report.md"
    atomic_write_text(result.report_md, "\n".join(md) + "\n")
    atomic_write_text(out / "results.json", json.dumps(summary, indent=1))
    result.index_html = write_index_html(out / "index.html", cfg.title, result.sections,
                                         intro="\n".join(md[2:9]) + f"\n\n[report.md](report.md) · [results.json](results.json)")
    result.summary = summary
    logger.info("rating analysis written to %s", out)
    return result
