"""``appeal analyze psychometric STUDY.yaml``: psychometric functions fitted to psychophysics data."""

from __future__ import annotations

from pathlib import Path

import click

from appeal_cli.groups import CONTEXT, analyze
from appeal_cli.options import out_options


@analyze.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal analyze psychometric protocols/analysis/realism_threshold.yaml --out results/realism
  appeal analyze psychometric my_thresholds.yaml            # writes results/my_thresholds
  appeal validate protocols/analysis/realism_threshold.yaml # check the file without fitting

\b
A minimal STUDY.yaml:
  kind: psychometric
  data: ../../data/sub-*/ses-*/beh/*_task-realism2afc_beh.tsv
  conditions: [expression]         # one fit per participant x expression
  fit: {family: logistic, method: bayes, nafc: 2, threshold_pc: 0.75}
  compare: [expression]            # rm-ANOVA of the thresholds across expressions""")
@click.argument("study", type=click.Path(path_type=Path), metavar="STUDY.yaml")
@out_options(required=False)
def psychometric(study: Path, out: Path | None, force: bool, resume: bool) -> None:
    """Fit psychometric functions to the trials of a psychophysics study (kind: psychometric).

    Reads the runner's *_beh.tsv files (main trials; n/a answers dropped), bins each
    participant x condition's answers by the stimulus variable x (default: difference, the
    distance from the reference face) and fits a psychometric function: psignifit-4-style
    Bayesian (MAP, credible intervals) or maximum likelihood; logistic, norm or weibull;
    n-AFC or yes/no. Writes fits.csv (threshold, width, lapse, guess, eta with intervals,
    x_at_pc: x at P(correct) = threshold_pc, continuum points, deviance), pooled.csv (one fit
    per condition over all participants), comparison_anova.csv and comparison_posthoc.csv
    (rm-ANOVA of the per-participant thresholds across the compare factors), one figure per
    participant, a group figure, report.md and index.html in DIR (default results/<STUDY>).
    """
    from analysis.psychometric.schema import PsychometricAnalysis
    from analysis.psychometric.study import analyze_psychometric_study, count_problems, read_trials
    from appeal.errors import AppealInputError
    from appeal.outputs import output_run
    from appeal.studyfile import load_study_file

    cfg = load_study_file(study, PsychometricAnalysis)
    trials = read_trials(cfg)  # every data problem is a one-line error before DIR exists
    problems = count_problems(trials, cfg)
    if problems:
        raise AppealInputError(problems)
    with output_run(out or Path("results") / study.stem, force=force, resume=resume, inputs=[study]) as run:
        run.add_inputs(sorted(set(trials["source_file"])))
        res = analyze_psychometric_study(cfg, run.out, trials)
    click.echo(f"report: {res.index_html}")
