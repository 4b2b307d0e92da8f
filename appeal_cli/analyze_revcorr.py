"""``appeal analyze revcorr DATA``: each participant's AU model of each expression (reverse correlation)."""

from __future__ import annotations

from pathlib import Path

import click

from appeal.errors import AppealInputError
from appeal_cli.groups import CONTEXT, analyze
from appeal_cli.options import out_options


@analyze.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal analyze revcorr 'data/sub-*/ses-*/beh/*_task-revcorr_beh.tsv' --level shape --out results/revcorr
  appeal analyze revcorr trials.csv --permutations 2000 --alpha 0.01 --out results/revcorr_strict

\b
DATA, one row per trial:
  participant_id   (or sub-<id> in the file name)
  response         happy | surprise | fear | disgust | anger | sad | dont_know (n/a: left out)
  intensity        1-5 (optional)
  revcorr_seed, revcorr_trial   the grammar's seed and trial number: the AUs and their
                                motions are drawn again from them, as the stimulus was""")
@click.argument("data", metavar="DATA")
@click.option("--subject", default="participant_id", show_default=True, help="The participant column.")
@click.option("--level", "levels", multiple=True, metavar="COLUMN",
              help="A stimulus-level column (e.g. shape): one model per participant x level; repeat for several.")
@click.option("--permutations", default=1000, show_default=True, type=click.IntRange(0, 100_000),
              help="Shuffles of the answers for the permutation test (family-wise over the AUs).")
@click.option("--alpha", default=0.05, show_default=True, type=click.FloatRange(0, 1, min_open=True, max_open=True),
              help="An AU is in a model at p < alpha (and when it makes the answer likelier).")
@click.option("--seed", default=0, show_default=True, type=int, help="Seed of the shuffles.")
@out_options()
def revcorr(data: str, subject: str, levels: tuple[str, ...], permutations: int, alpha: float, seed: int, out: Path,
            force: bool, resume: bool) -> None:
    """Reverse correlation (Jack et al. 2012): which AUs make each answer likelier, per participant.

    \b
    For every participant (x level) and emotion, the mutual information between each AU's
    presence and the answer, its permutation p corrected across the AUs (max statistic),
    the model (AUs at p < alpha that make the answer likelier) and a logistic classification
    image; for the model's AUs their temporal parameters on the trials so answered and the
    correlation of their amplitude with the intensity; across participants the share whose
    model holds each AU and the models' pairwise Hamming distance; with one --level column,
    a mixed model per emotion x AU of whether the level changes MI, and each participant's
    changes between levels. Writes models.csv, logistic.csv, temporal.csv, consensus.csv,
    agreement.csv, level_effects.csv, level_agreement.csv, consensus*.png, a figure per
    participant under figures/, report.md and index.html in DIR (docs/revcorr.md).
    """
    from analysis.revcorr.study import analyze_revcorr
    from analysis.revcorr.trials import read_revcorr_trials
    from appeal.outputs import output_run

    trials = read_revcorr_trials(data, subject, levels)  # every problem a one-line error before DIR exists
    if permutations and 1 / (1 + permutations) >= alpha:
        raise AppealInputError(f"--permutations {permutations}: too few for alpha {alpha} (the smallest p is "
                               f"1 / (1 + shuffles); expected more than {1 / alpha - 1:g})")
    with output_run(out, force=force, resume=resume, seed=seed) as run:
        run.add_inputs(sorted(set(trials.table["source_file"])))
        run.extra.update({"participants": int(trials.table[subject].nunique()), "trials": len(trials.table),
                          "permutations": permutations, "alpha": alpha})
        res = analyze_revcorr(trials, run.out, subject=subject, n_permutations=permutations, alpha=alpha, seed=seed)
    click.echo(f"{res.models[subject].nunique()} participants' models -> {res.index_html}")
