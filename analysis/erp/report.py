"""Writing a run: amplitudes.csv, single_trials.csv, sme.csv, qc.csv, stats/, figures/, source/ and report.md."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from appeal.atomic import atomic_write_text
from appeal.cells import write_table
from appeal.errors import AppealInputError
from appeal.logs import logger

from analysis.erp.quality import flag_sme, sme_rms
from analysis.erp.results import ErpResult
from analysis.erp_schema import ErpConfig


__all__ = ["ErpOutputs", "grand_averages", "level_peaks", "source_contrasts", "measures_section", "quality_section",
           "write_erp_outputs"]


@dataclass
class ErpOutputs:
    """Paths written and the main tables."""

    out: Path
    amplitudes: Path
    qc: Path
    report: Path
    tables: list[Path] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)
    source_table: pd.DataFrame | None = None
    single_trials: Path | None = None
    sme: Path | None = None


def _csv(df: pd.DataFrame, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    write_table(df, path, float_format="%.6g")
    return path


def grand_averages(result: ErpResult) -> tuple[dict, list[str], np.ndarray, object]:
    """Mean over subjects of each cell's average, on the channels all subjects share."""
    common = [c for c in result.subjects[0].info.ch_names if all(c in s.info.ch_names for s in result.subjects)]
    grand = {}
    for cell in result.emap.cells:
        parts = [s.evokeds[cell][[s.info.ch_names.index(c) for c in common]] for s in result.subjects if cell in s.evokeds]
        if parts:
            grand[cell] = np.mean(parts, axis=0)
    info = result.subjects[0].info.copy()
    import mne

    info = mne.pick_info(info, [info.ch_names.index(c) for c in common])
    return grand, common, result.subjects[0].times, info


def _contrast_pairs(cfg: ErpConfig, levels: list) -> list[tuple]:
    if cfg.source.contrasts:
        from appeal.levels import level_value

        return [(level_value(a), level_value(b)) for a, b in cfg.source.contrasts]
    return [(levels[-1], levels[0]), (levels[0], levels[-1])]


def source_contrasts(result: ErpResult, cfg: ErpConfig, seed: int = 0) -> tuple[pd.DataFrame, dict]:
    """Voxel-wise paired contrasts of window-mean source maps, one table for all contrasts.

    Returns
    -------
    table : pandas.DataFrame
        component, contrast, cluster, then :func:`analysis.erp.source.contrast_clusters` columns.
    tmaps : dict
        (component, a, b) -> t map.
    """
    from appeal.errors import AppealInputError

    from analysis.erp.source import contrast_clusters

    src = cfg.source
    factor = src.factor or result.emap.factors[0]
    levels = result.emap.levels[factor]
    pairs = _contrast_pairs(cfg, levels)
    for a, b in pairs:
        for lv in (a, b):
            if lv not in levels:
                raise AppealInputError(f"source.contrasts: level {lv!r} is not a level of {factor} (expected one of {levels})")
    comps = src.components or list(cfg.components)
    rows, tmaps = [], {}
    for comp in comps:
        for a, b in pairs:
            subs = [s for s in result.subjects if (comp, a) in s.source_maps and (comp, b) in s.source_maps]
            if len(subs) < 3:
                logger.warning("source %s %s>%s: fewer than 3 subjects with both levels; skipped", comp, a, b)
                continue
            diff = np.array([s.source_maps[(comp, a)] - s.source_maps[(comp, b)] for s in subs], float)
            t, table = contrast_clusters(diff, result.head, p_threshold=src.p_threshold,
                                         min_voxels=src.min_cluster_voxels, n_permutations=src.n_permutations, seed=seed,
                                         min_volume_mm3=src.min_cluster_mm3, smoothing_fwhm_mm=src.smoothing_fwhm_mm)
            tmaps[(comp, a, b)] = t
            table.insert(0, "cluster", np.arange(1, len(table) + 1))
            table.insert(0, "contrast", f"{factor} {a} > {b}")
            table.insert(0, "component", comp)
            table["n_subjects"] = len(subs)
            rows.append(table)
    cols = ["component", "contrast", "cluster", "n_voxels", "volume_mm3", "peak_t", "peak_p_uncorrected", "p_fwe", "peak_difference",
            "x_mm", "y_mm", "z_mm", "hemisphere", "area", "brodmann", "region", "n_subjects"]
    table = pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=cols)
    return table, tmaps


def level_maps(result: ErpResult, cfg: ErpConfig, seed: int = 0) -> tuple[pd.DataFrame, dict]:
    """Per component and level, the FWE-corrected activation map (window above baseline):
    a table (significant voxels, their volume, peak t and position with its label) and the t maps."""
    from analysis.erp.source import BASELINE, level_activation, with_labels

    mni = result.head.mni
    keys = [k for k in dict.fromkeys(k for s in result.subjects for k in s.source_maps) if k[0] != BASELINE]
    rows, tmaps = [], {}
    for comp, level in keys:
        subs = [s for s in result.subjects if (comp, level) in s.source_maps and (BASELINE, level) in s.source_maps]
        if len(subs) < 3:
            continue
        win = np.array([s.source_maps[(comp, level)] for s in subs])
        base = np.array([s.source_maps[(BASELINE, level)] for s in subs])
        t, p, thr = level_activation(win, base, n_permutations=cfg.source.n_permutations, seed=seed)
        tmaps[(comp, level)] = (t, thr)
        # the peak: the largest mean activation among the significant voxels (the maximum t wanders
        # with few subjects, see contrast_clusters)
        effect = np.where(p < 0.05, (win - base).mean(axis=0), -np.inf)
        i = int(np.argmax(effect)) if np.isfinite(effect).any() else int(np.argmax(t))
        n_sig = int((p < 0.05).sum())
        rows.append(dict(component=comp, level=level, n_significant=n_sig, volume_mm3=round(n_sig * result.head.voxel_mm3, 1),
                         peak_t=float(t[i]), peak_p_fwe=float(p[i]), x_mm=round(float(mni[i, 0]), 1),
                         y_mm=round(float(mni[i, 1]), 1), z_mm=round(float(mni[i, 2]), 1), n_subjects=len(subs)))
    cols = ["component", "level", "n_significant", "volume_mm3", "peak_t", "peak_p_fwe", "x_mm", "y_mm", "z_mm", "n_subjects"]
    return with_labels(pd.DataFrame(rows, columns=cols)), tmaps


def level_peaks(result: ErpResult, n_peaks: int = 3) -> pd.DataFrame:
    """Peaks of the grand-mean window map of every component and level (thesis Fig. 7.8/7.9 top rows),
    with their anatomical labels."""
    from analysis.erp.source import map_peaks, with_labels

    mni = result.head.mni
    keys = [k for k in dict.fromkeys(k for s in result.subjects for k in s.source_maps) if not k[0].startswith("_")]
    rows = []
    for comp, level in keys:
        maps = [s.source_maps[(comp, level)] for s in result.subjects if (comp, level) in s.source_maps]
        grand = np.mean(maps, axis=0)
        for rank, i in enumerate(map_peaks(grand, mni, n_peaks), start=1):
            rows.append(dict(component=comp, level=level, peak=rank, value=float(grand[i]), x_mm=round(float(mni[i, 0]), 1),
                             y_mm=round(float(mni[i, 1]), 1), z_mm=round(float(mni[i, 2]), 1)))
    return with_labels(pd.DataFrame(rows, columns=["component", "level", "peak", "value", "x_mm", "y_mm", "z_mm"]))


def _fmt(df: pd.DataFrame, cols: list[str]) -> str:
    d = df[cols].copy()
    for c in d.columns:
        if d[c].dtype.kind == "f":
            d[c] = d[c].map(lambda v: f"{v:.3g}" if pd.notna(v) else "")
    head = "| " + " | ".join(cols) + " |\n|" + "---|" * len(cols) + "\n"
    return head + "".join("| " + " | ".join(str(v) for v in row) + " |\n" for row in d.itertuples(index=False))


def thesis_table(table: pd.DataFrame) -> str:
    """The clusters as the thesis's Table 7.1: per component and contrast, the cluster's voxels,
    peak t and uncorrected p, MNI x/y/z and the peak's area (AAL, :mod:`analysis.erp.atlas`)."""
    if not len(table):
        return ""
    lines = ["| Cluster voxels (mm³) | Peak t | Peak p-uncor | x (mm) | y (mm) | z (mm) | Area | BA |",
             "|---|---|---|---|---|---|---|---|"]
    for (comp, contrast), g in table.groupby(["component", "contrast"], sort=False):
        lines.append(f"| **{comp}: {contrast}** | | | | | | | |")
        for r in g.itertuples(index=False):
            p = r.peak_p_uncorrected
            ptxt = "< .001" if p < 0.001 else ("< .005" if p < 0.005 else f"{p:.3f}")
            lines.append(f"| {int(r.n_voxels)} ({r.volume_mm3:g}) | {r.peak_t:.2f} | {ptxt} | {r.x_mm:g} | {r.y_mm:g} | "
                         f"{r.z_mm:g} | {r.area if isinstance(r.area, str) else ''} | "
                         f"{r.brodmann if isinstance(r.brodmann, str) else ''} |")
    return "\n".join(lines) + "\n"


def measures_section(cfg: ErpConfig) -> str:
    """The report's paragraph on what ``amplitudes.csv`` and ``single_trials.csv`` measure."""
    comps = "; ".join(f"{k} {v.window_s[0] * 1e3:g}-{v.window_s[1] * 1e3:g} ms, {v.polarity}, fractions "
                      f"{v.peak_fraction:g} (peak) / {v.area_fraction:g} (area)" for k, v in cfg.components.items())
    return ("Per cell average and cluster (`amplitudes.csv`): window mean (`mean_uV`), peak and its latency "
            "(`mne.stats.erp.compute_peak`), fractional-peak latency on the onset side (the first sample of the window "
            "reaching the fraction of the peak, `compute_frac_peak_latency`) and fractional-area latency (the sample "
            "where the area of the component's sign reaches the fraction, `compute_frac_area_latency`); windows include "
            f"both ends. Components: {comps}. Per kept trial (`single_trials.csv`): window mean, peak and latency.\n")


def quality_section(sme: pd.DataFrame, factors: list[str], threshold_uV: float | None, stimuli: bool,
                    max_listed: int = 6) -> str:
    """The report's SME section: RMS across subjects per cell, the flagged values by subject.

    Parameters
    ----------
    sme : pandas.DataFrame
        ``sme.csv`` (with ``flagged``).
    factors : list of str
        The condition factors.
    threshold_uV : float | None
        ``quality.sme_threshold_uV``.
    stimuli : bool
        Whether the trials' stimuli came from behavioural files.
    max_listed : int
        Flagged values named per subject (the rest are counted).
    """
    rms = sme_rms(sme, factors)
    rms["measure"] = rms["component"] + "/" + rms["cluster"].astype(str)
    wide = rms.pivot_table(index=factors, columns="measure", values="rms_sme_uV", sort=False).reset_index()
    wide.columns.name = None
    text = ("Standardized measurement error of each mean amplitude (analytic SME, Luck et al. 2021, as in ERP CORE): the SD "
            "of the single-trial window means / √n (`mne.stats.erp.compute_sme`) per subject, cell, component and "
            "cluster, in `sme.csv`; the single-trial values are in `single_trials.csv`"
            + (" with each trial's stimulus from the behavioural files (`beh`)" if stimuli else
               " (no `beh` files in the config: the stimulus column is empty)")
            + ". Root mean square across subjects per cell (µV; also `sme_rms.csv`):\n\n"
            + (_fmt(wide, list(wide.columns)) if len(rms) else "No SME: no cell has two trials.\n"))
    if threshold_uV is None:
        return text + "\nNo threshold set (`quality.sme_threshold_uV`): nothing flagged.\n"
    flagged = sme[sme["flagged"]]
    text += (f"\nThreshold {threshold_uV:g} µV: {len(flagged)} of {int(sme['sme_uV'].notna().sum())} values above it"
             + (", from these subjects:\n\n" if len(flagged) else ".\n"))
    for subj, g in flagged.groupby("subject", sort=False):
        rows = g.sort_values("sme_uV", ascending=False)[[*factors, "component", "cluster", "sme_uV"]]
        items = [f"{'/'.join(f'{f}={v}' for f, v in zip(factors, cell))} {comp}/{cluster} ({value:.2f} µV)"
                 for *cell, comp, cluster, value in rows.itertuples(index=False)]
        more = f" and {len(items) - max_listed} more" if len(items) > max_listed else ""
        text += f"- **{subj}** ({len(items)}, largest first): {'; '.join(items[:max_listed])}{more}\n"
    return text


def single_trial_models(trials: pd.DataFrame, factors: list[str], cfg: ErpConfig, out: Path, o: ErpOutputs) -> str:
    """Mixed models of the single-trial window means, one per component x cluster (the report's text)."""
    from analysis.stats.formula import FormulaError
    from analysis.stats.lmm_report import lmm_section

    has_stim = "stimulus" in trials.columns and trials["stimulus"].notna().any()
    text = ["### Linear mixed models of the single-trial window means", ""]
    from analysis.stats.covariates import centre_covariates, join_audit, read_audit

    measures, audit = [], None
    if cfg.covariates is not None:
        measures, audit = list(cfg.covariates.measures), read_audit(cfg.covariates.audit, cfg.covariates.measures)
        text += [f"Covariates: stimulus audit measures {', '.join(measures)} from `{cfg.covariates.audit}`, joined by "
                 "each trial's stimulus and centred at their grand mean per component × cluster (fixed main effects; "
                 "the rm-ANOVA of amplitudes.csv is not adjusted).", ""]
    for (comp, cluster), part in trials.groupby(["component", "cluster"], sort=False):
        src = f"single_trials.csv: {comp} {cluster}"
        means = None
        if audit is not None:  # a stimulus missing from the audit is the user's error: it stops the run
            part, means = centre_covariates(join_audit(part, audit, measures, "stimulus", src)[0], measures)
        try:  # a covariate these trials cannot separate from the factors: this model is not fitted
            sec = lmm_section(part, "mean_uV", f"{comp} {cluster} (µV)", factors, ["subject"] + (["stimulus"] if has_stim else []),
                              out / f"{comp}_{cluster}", random=cfg.mixed.random, ddf=cfg.mixed.ddf,
                              levels=cfg.levels or None, source=src, covariates=measures, covariate_means=means)
        except (FormulaError, AppealInputError) as exc:
            text += [f"#### {comp}, {cluster}", "", f"Not fitted: {exc}", ""]
            continue
        o.tables += sec.tables
        o.figures += sec.figures
        text += [f"#### {comp}, {cluster}", "", *sec.text]
    return "\n".join(text) + "\n"


def write_erp_outputs(result: ErpResult, cfg: ErpConfig, out: Path, *, seed: int = 0, config_name: str = "config") -> ErpOutputs:
    """Write every table, figure and the Markdown report of a run into ``out``."""
    from analysis.erp import figures as figs
    from analysis.erp.stats import component_anovas, component_contrasts

    out = Path(out)
    emap = result.emap
    amps = result.amplitudes
    o = ErpOutputs(out=out, amplitudes=_csv(amps, out / "amplitudes.csv"), qc=_csv(result.qc, out / "qc.csv"),
                   report=out / "report.md")
    # single trials and their data quality
    sme = flag_sme(result.sme, cfg.quality.sme_threshold_uV)
    o.single_trials = _csv(result.single_trials, out / "single_trials.csv")
    o.sme = _csv(sme, out / "sme.csv")
    o.tables.append(_csv(sme_rms(sme, emap.factors), out / "sme_rms.csv"))
    quality_text = quality_section(sme, emap.factors, cfg.quality.sme_threshold_uV, cfg.beh is not None)
    if result.failures:
        fail = pd.DataFrame([{"subject": f.label, "error": f.error} for f in result.failures])
        o.tables.append(_csv(fail, out / "failures.csv"))
    # statistics
    stats_text = ""
    n_subj = amps["subject"].nunique()
    if n_subj >= 2:
        anova = component_anovas(amps, emap.factors)
        contr = component_contrasts(amps, emap.factors, emap.levels)
        o.tables += [_csv(anova, out / "stats" / "anova.csv"), _csv(contr, out / "stats" / "contrasts.csv")]
        stats_text = ("### rm-ANOVA (window means; Greenhouse-Geisser p in p_gg)\n\n"
                      + _fmt(anova, ["component", "effect", "num_df", "den_df", "F", "p", "p_gg", "pes"])
                      + "\n### Linear vs quadratic contrasts\n\n"
                      + _fmt(contr, ["component", "factor", "contrast", "F", "num_df", "den_df", "p", "pes"]))
        if cfg.mixed.enabled:
            stats_text += single_trial_models(result.single_trials, emap.factors, cfg, out / "stats" / "lmm", o)
    else:
        stats_text = "Statistics need at least two subjects; skipped.\n"
    # figures
    grand, common, times, info = grand_averages(result)
    windows = {k: tuple(v.window_s) for k, v in cfg.components.items()}
    try:
        from analysis.erp.channels import resolve_cluster

        chans = {}
        for name in cfg.figures.channels:
            ch = resolve_cluster([name], common, None if cfg.montage == "none" else cfg.montage, where="figures.channels")[0]
            chans[name] = ch
        o.figures += figs.plot_waveforms(grand, times, common, chans, emap.factors, emap.levels, windows,
                                         out / "figures" / "waveforms")
    except Exception as exc:  # noqa: BLE001 - a figure must not sink the run; the report says why
        logger.warning("waveform figure skipped: %s", exc)
    topo_f = cfg.figures.topomap_factor or (emap.factors[1] if len(emap.factors) > 1 else emap.factors[0])
    ref = "neutral" if "neutral" in emap.levels[topo_f] else emap.levels[topo_f][0]
    topo_windows = {k: w for k, w in windows.items() if k != "LPP"} or windows
    o.figures += figs.plot_difference_topomaps(grand, info, emap.factors, emap.levels, topo_f, ref, topo_windows, times,
                                               out / "figures" / f"topomaps_{topo_f}")
    for comp in cfg.components:
        o.figures += figs.plot_window_bars(amps, comp, emap.factors, emap.levels, out / "figures" / f"bars_{comp}")
    o.figures += figs.plot_sme(sme, cfg.quality.sme_threshold_uV, out / "figures" / "sme")
    # source
    src_text = "Source summaries disabled in the config.\n"
    if cfg.source.enabled and result.head is not None:
        if n_subj >= 3:
            from scipy import stats as sst

            table, tmaps = source_contrasts(result, cfg, seed)
            o.source_table = table
            o.tables.append(_csv(table, out / "source" / "clusters.csv"))
            o.tables.append(_csv(level_peaks(result), out / "source" / "level_peaks.csv"))
            thr = float(sst.t.ppf(1 - cfg.source.p_threshold, n_subj - 1))
            mni = result.head.mni
            for (comp, a, b), t in tmaps.items():
                stem = f"tmap_{comp}_{a}_gt_{b}"
                _csv(pd.DataFrame({"x_mm": mni[:, 0], "y_mm": mni[:, 1], "z_mm": mni[:, 2], "t": t}),
                     out / "source" / f"{stem}.csv")
                o.figures += figs.plot_source_map(mni, t, thr, f"{comp}: {a} > {b} ({cfg.source.method}, p < "
                                                  f"{cfg.source.p_threshold} uncorrected)", out / "figures" / stem)
            lv_table, lv_maps = level_maps(result, cfg, seed)
            o.tables.append(_csv(lv_table, out / "source" / "level_fwe.csv"))
            for (comp, level), (t, lthr) in lv_maps.items():
                o.figures += figs.plot_source_map(mni, t, lthr, f"{comp}, {level}: activation above baseline (FWE p < .05)",
                                                  out / "figures" / f"level_{comp}_{level}")
            sc = cfg.source
            extent = f"{sc.min_cluster_mm3:g} mm³" if sc.min_cluster_mm3 else f"{sc.min_cluster_voxels} voxels"
            smooth = f"maps smoothed with a {sc.smoothing_fwhm_mm:g} mm FWHM Gaussian; " if sc.smoothing_fwhm_mm else ""
            src_text = (f"{sc.method} on a {result.head.kind} head model, volume grid {sc.spacing_mm:g} mm "
                        f"({len(mni)} voxels); {smooth}paired t per voxel, one-sided p < {sc.p_threshold}, clusters ≥ "
                        f"{extent}, FWE p by {sc.n_permutations} sign-flip permutations (cluster mass). Coordinates in "
                        "MNI mm.\n\n"
                        + (thesis_table(table) + "\nAll columns: `source/clusters.csv`.\n" if len(table) else
                           "No cluster reached the size threshold.\n")
                        + "\nPer level, the window's magnitude above the baseline's, FWE-corrected (maximum t over "
                        f"{sc.n_permutations} sign flips, p < .05; thesis Fig. 7.8 upper panel): `source/level_fwe.csv`, "
                        "figures `level_*`.\n")
        else:
            src_text = "Source statistics need at least three subjects; skipped.\n"
    qc = result.qc
    fails = "".join(f"- **{f.label}** failed: {f.error}\n" for f in result.failures) or "- none\n"
    text = (f"# ERP analysis: {config_name}\n\n"
            f"{len(result.subjects)} subjects analysed; failed subjects:\n\n{fails}\n"
            "## Quality control (per subject)\n\n"
            + _fmt(qc, ["subject", "n_channels", "pct_channels_interpolated", "n_events", "pct_trials_rejected",
                        "trials_per_cell_mean", "trials_per_cell_min"])
            + f"\nMean over subjects: {qc['pct_channels_interpolated'].mean():.2f}% channels interpolated, "
              f"{qc['pct_trials_rejected'].mean():.2f}% trials rejected, {qc['trials_per_cell_mean'].mean():.2f} trials "
              "per cell (thesis: 4.04%, 5.41%, 28.38).\n\n"
            "## Data quality (SME)\n\n" + quality_text + "\nFigure: `figures/sme.png` (SME per subject and component).\n\n"
            "## Measures\n\n" + measures_section(cfg) + "\n"
            "## Statistics\n\n" + stats_text + "\n## Source space\n\n" + src_text + "\n## Files\n\n"
            + "".join(f"- [{p.relative_to(out)}]({p.relative_to(out)})\n"
                      for p in [o.amplitudes, o.single_trials, o.sme, o.qc, *o.tables, *o.figures] if p.suffix != ".svg"))
    atomic_write_text(o.report, text)
    return o

