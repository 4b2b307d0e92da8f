"""``appeal analyze erp CONFIG.yaml --out DIR``: the MNE ERP pipeline (issue 8)."""

from __future__ import annotations

from pathlib import Path

import click

from appeal_cli.groups import CONTEXT, analyze
from appeal_cli.options import out_options, parallel_options, seed_option
from appeal.errors import AppealInputError


@analyze.command("erp", context_settings=CONTEXT, epilog="""\b
Examples:
  appeal analyze erp protocols/analysis/erp_stylisation.yaml --out results/erp
  appeal analyze erp study.yaml --out results/erp --n-jobs 2 --permutations 200
  appeal analyze erp protocols/analysis/erp_biosemi_sample.yaml --out results/sample   # BioSemi's sample file
  appeal analyze erp study.yaml --out results/erp --scheduler tcp://10.0.0.5:8786
  appeal validate study.yaml            # check the config without running it

\b
Writes DIR/amplitudes.csv (subject, factors, component, cluster, mean_uV, peak_uV,
peak_latency_ms, frac_peak_latency_ms, frac_area_latency_ms, n_trials),
DIR/single_trials.csv (one row per kept trial x component x cluster, with its stimulus
when `beh:` names the runner's files), DIR/sme.csv and sme_rms.csv (standardized
measurement error, flagged above quality.sme_threshold_uV), DIR/qc.csv, DIR/stats/
(anova.csv, contrasts.csv; lmm/ with `mixed: {enabled: true}`), DIR/figures/ (PNG + SVG,
sme included), DIR/source/ (clusters.csv, level_peaks.csv, t maps) and DIR/report.md.
A subject that fails is listed in DIR/failures.csv; the rest go on.""")
@click.argument("config", type=click.Path(path_type=Path, dir_okay=False))
@out_options()
@seed_option()
@parallel_options
@click.option("--permutations", "n_permutations", type=click.IntRange(min=10), default=None, metavar="N",
              help="Override source.n_permutations (sign flips for FWE cluster p-values).")
@click.option("--strict", is_flag=True, help="Exit with status 2 when any subject failed (outputs are still written).")
def erp(config: Path, out: Path, force: bool, resume: bool, seed: int, n_jobs: int | None, scheduler: str | None,
        n_permutations: int | None, strict: bool) -> None:
    """Scalp ERPs, window amplitudes, rm-ANOVAs and source summaries from EEG recordings.

    \b
    CONFIG is a `kind: erp` YAML file (see docs/erp.md): recordings (glob or BIDS root),
    montage, channels.rename (e.g. BioSemi's A1.. labels to a montage's names), events
    (inline code -> levels, or {protocol: FILE}), reference, filters, epochs, EOG
    correction, bad channels, rejection, components (windows + clusters in 10-5 names or
    channel labels) and source settings. Defaults follow thesis §7.3.
    """
    from appeal.outputs import output_run

    from analysis.erp.config import load_erp_config
    from analysis.erp.pipeline import run_erp

    cfg = load_erp_config(config)  # bad config: one-line errors before any output folder is made
    with output_run(out, force=force, resume=resume, seed=seed, inputs=[config]) as run:
        result, outputs = run_erp(cfg, run.out, source=config, seed=seed, n_jobs=n_jobs, scheduler=scheduler,
                                  n_permutations=n_permutations)
        run.add_inputs(s.path for s in result.subjects)
        run.extra["failed_subjects"] = [f"{f.label}: {f.error}" for f in result.failures]
    click.echo(f"{len(result.subjects)} subjects analysed; report: {outputs.report}")
    for f in result.failures:
        click.echo(f"failed: {f.label}: {f.error}", err=True)
    if strict and result.failures:
        raise AppealInputError([f"{f.label}: {f.error}" for f in result.failures])
