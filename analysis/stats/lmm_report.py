"""The linear-mixed-model part of a rating (or ERP single-trial) analysis: the model on the
trial-level data with crossed random effects, its type-III tests, variance components, EMMs and
Tukey-adjusted pairwise comparisons of significant effects, and figures of the EMMs.

:func:`lmm_section` returns what the study report shows (text, tables, figures, records); the
maths is in :mod:`analysis.stats.lmm`, :mod:`analysis.stats.lmm_anova`,
:mod:`analysis.stats.lmm_emmeans` and :mod:`analysis.stats.random_structures`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.stats.covariates import MIXED_HINT, check_estimable
from analysis.stats.lmm import LmmFit
from analysis.stats.lmm_anova import coefficient_table, inference, lmm_anova
from analysis.stats.lmm_emmeans import emm_pairs, emmeans
from analysis.stats.plots import interaction_plot
from analysis.stats.random_structures import fit_with_fallback, structure_table
from analysis.stats.records import json_records, write_csv
from analysis.stats.reporting import format_p, markdown_table

__all__ = ["LmmSection", "lmm_section", "coefficient_table", "model_formula", "covariate_text"]


@dataclass
class LmmSection:
    """What the mixed-model part of a report holds."""

    text: list[str] = field(default_factory=list)
    tables: list[Path] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)
    records: dict = field(default_factory=dict)
    fit: LmmFit | None = None


def model_formula(response: str, factors: Sequence[str], covariates: Sequence[str] = ()) -> str:
    """``response ~ a * b * c`` (every interaction of the design's factors) ``+ x₁ + x₂`` (covariates as main effects)."""
    return f"{response} ~ " + (" * ".join(factors) if factors else "1") + "".join(f" + {c}" for c in covariates)


def covariate_text(coefs: pd.DataFrame, covariates: Sequence[str], means: Mapping[str, float] | None = None) -> str:
    """One sentence on the covariates' coefficients (estimate, SE, df, t, p)."""
    means = means or {}
    rows = coefs.set_index("term")
    parts = [f"{c}: b = {rows.at[c, 'estimate']:.4g} (SE {rows.at[c, 'se']:.3g}), t({rows.at[c, 'df']:.1f}) = "
             f"{rows.at[c, 't']:.2f}, {format_p(rows.at[c, 'p'])}" + (f"; mean {means[c]:.4g}" if c in means else "")
             for c in covariates]
    return ("Covariates (stimulus audit measures, centred at their grand mean, so the factor tests and EMMs hold at "
            "the mean covariate): " + "; ".join(parts) + ".")


def lmm_section(data: pd.DataFrame, response: str, label: str, factors: Sequence[str], groups: Sequence[str],
                out_dir: Path, *, random: str = "maximal", ddf: str = "satterthwaite", levels=None, alpha: float = 0.05,
                max_order: int = 2, max_cells: int = 60, figures: Sequence[tuple[str, str | None]] = (),
                ylim: tuple[float, float] | None = None, source: str = "data", covariates: Sequence[str] = (),
                covariate_means: Mapping[str, float] | None = None) -> LmmSection:
    """Fit and report the mixed model ``response ~ factors (all interactions) + covariates + random``.

    Parameters
    ----------
    data : DataFrame
        Trial-level rows (not averaged).
    response, label : str
        The response column and its name in the report.
    factors : sequence of str
        The fixed factors (all coded as factors, sum-to-zero contrasts).
    groups : sequence of str
        Grouping factors of the random part (participants, stimuli) for ``random: maximal``.
    out_dir : Path
        Where the tables and figures go.
    random : str
        ``"maximal"`` (with the documented fallback) or lme4 random terms.
    ddf : {"satterthwaite", "kenward-roger"}
        Denominator dfs of the tests, the coefficients and the EMMs.
    figures : sequence of (x, trace)
        EMM plots to draw.
    covariates : sequence of str
        Numeric columns (centred: :func:`analysis.stats.covariates.centre_covariates`) added as
        fixed main effects, without random slopes; refused when they cannot be separated from
        the factors (:func:`analysis.stats.covariates.check_estimable`).
    covariate_means : mapping, optional
        The covariates' means before centring (for the report).
    """
    sec = LmmSection()
    groups = [g for g in groups if g in data.columns and data[g].nunique() >= 2]
    if covariates:
        check_estimable(data.dropna(subset=[response, *covariates]), covariates, [list(factors)], source=source,
                        hint=MIXED_HINT)
    fit, attempts = fit_with_fallback(data, model_formula(response, factors, covariates), random=random, groups=groups,
                                      factors=list(factors) + list(groups), levels=levels, source=source,
                                      fixed_only=covariates)
    sec.fit = fit
    tests = inference(fit, ddf)
    table = lmm_anova(fit, ddf, tests=tests)
    coefs = coefficient_table(fit, tests)
    vc = fit.variance_components()
    structures = structure_table(attempts, fit)
    sec.tables += [write_csv(table, out_dir / "lmm_anova.csv"), write_csv(coefs, out_dir / "lmm_coefficients.csv"),
                   write_csv(vc, out_dir / "lmm_variance_components.csv"), write_csv(structures, out_dir / "lmm_structures.csv")]
    method = {"satterthwaite": "Satterthwaite", "kenward-roger": "Kenward–Roger"}[ddf]
    sec.text += [f"**Linear mixed model** (REML, lme4's formulation; type-III F tests with {method} dfs, "
                 "sum-to-zero contrasts, as afex::mixed) on all "
                 f"{fit.n} trials: `{fit.formula.text}`.", ""]
    if random == "maximal":
        passed = [f"{a.label} ({a.outcome})" for a in attempts if a.fit is not fit]
        sec.text += [f"Random effects: maximal structure simplified in the documented order until a fit converged "
                     f"without a singular fit; used: *{next(a.label for a in attempts if a.fit is fit)}*"
                     + (f" (passed over: {'; '.join(passed)})" if passed else "") + ".", ""]
    if fit.warnings:
        sec.text += ["Warnings: " + "; ".join(fit.warnings) + ".", ""]
    sec.text += [markdown_table(table.drop(columns="method")), ""]
    if covariates:
        sec.text += [covariate_text(coefs, covariates, covariate_means), ""]
        sec.records["covariates"] = json_records(coefs[coefs.term.isin(list(covariates))])
    sds = [f"{r.group} {r.term} SD {r.sd:.3f}" for r in vc.itertuples() if np.isfinite(r.sd)]
    sec.text += ["Variance components: " + "; ".join(sds) + ".", ""]
    ph_lines = []
    sec.records["pairs"] = {}
    for row in table.itertuples():
        fac = row.effect.split(":")
        if any(f not in fit.mm.levels for f in fac):  # a covariate: its coefficient is in the text
            continue
        n_cells = int(np.prod([len(fit.mm.levels[f]) for f in fac]))
        if row.p >= alpha or len(fac) > max_order or n_cells > max_cells:
            continue
        emm = emmeans(fit, fac, tests)
        pw = emm_pairs(fit, emm, tests)
        safe = row.effect.replace(":", "_x_")
        sec.tables += [write_csv(emm, out_dir / f"lmm_emmeans_{safe}.csv"),
                       write_csv(pw, out_dir / f"lmm_pairs_{safe}.csv")]
        sig = pw[pw.p < alpha]
        ph_lines.append(f"- {row.effect}: {len(sig)} of {len(pw)} pairs differ (Tukey, α = {alpha})" +
                        ("; strongest: " + "; ".join(f"{r.contrast} = {r.estimate:+.2f}, t({r.df:.1f}) = {r.t:.2f}, "
                                                      f"{format_p(r.p)}" for r in sig.reindex(sig.t.abs().sort_values(
                                                          ascending=False).index).head(3).itertuples()) if len(sig) else ""))
        sec.records["pairs"][row.effect] = json_records(pw)
    if ph_lines:
        sec.text += ["Pairwise comparisons of the model's estimated marginal means (emmeans):", "", *ph_lines, ""]
    for x, trace in figures:
        fac = [trace, x] if trace else [x]
        if any(f not in fit.mm.levels for f in fac):
            continue
        emm = emmeans(fit, fac, tests)
        ci = emm.assign(mean=emm.emmean, ci=emm.ci_high - emm.emmean)
        stem = out_dir / (f"lmm_emmeans_{x}" + (f"_by_{trace}" if trace else ""))
        sec.figures.append(interaction_plot(ci, x, trace, label, stem, ylim=ylim, x_levels=fit.mm.levels[x],
                                            trace_levels=fit.mm.levels[trace] if trace else None,
                                            title=f"{label}: mixed-model EMMs", interval="95% CI of the EMM")[0])
    sec.records.update({"formula": fit.formula.text, "n_obs": fit.n, "singular": fit.singular,
                        "converged": fit.converged, "reml_criterion": fit.deviance, "ddf": ddf,
                        "anova": json_records(table), "variance_components": json_records(vc),
                        "structures": json_records(structures)})
    return sec
