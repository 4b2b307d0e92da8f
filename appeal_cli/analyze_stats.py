"""``appeal analyze anova | posthoc | contrasts | ratings``: rating-study statistics (issue 3)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import click

from appeal_cli.groups import CONTEXT, analyze
from appeal_cli.options import out_options
from appeal.errors import AppealInputError


class _Many(click.Option):
    """An option that takes every following word up to the next option: ``--within A B C``."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("multiple", False)
        super().__init__(*args, **kwargs)
        self._previous_parser_process = None
        self._eat_all_parser = None

    def add_to_parser(self, parser, ctx):
        def parser_process(value, state):
            values = [value]
            while state.rargs and not state.rargs[0].startswith("-"):
                values.append(state.rargs.pop(0))
            self._previous_parser_process(tuple(values), state)

        retval = super().add_to_parser(parser, ctx)
        for name in self.opts:
            our_parser = parser._long_opt.get(name) or parser._short_opt.get(name)
            if our_parser:
                self._eat_all_parser = our_parser
                self._previous_parser_process = our_parser.process
                our_parser.process = parser_process
                break
        return retval

    def type_cast_value(self, ctx, value):
        if value is None:
            return ()
        if isinstance(value, str):
            value = (value,)
        out = []
        for v in value:
            out.extend(x for x in str(v).replace(",", " ").split() if x)
        return tuple(out)


def _data_options(f):
    f = click.option("--drop-incomplete", is_flag=True, help="Drop participants missing a cell (reported) instead of failing.")(f)
    f = click.option("--aggregate", type=click.Choice(["mean"]), default=None,
                     help="Average repeated trials of a participant x cell (otherwise they are an error).")(f)
    f = click.option("--between", cls=_Many, metavar="G ...", default=None, help="Between-subject factor columns.")(f)
    f = click.option("--within", cls=_Many, metavar="A B ...", required=True, help="Within-subject factor columns.")(f)
    f = click.option("--subject", default="participant_id", show_default=True, metavar="COL", help="Participant id column.")(f)
    f = click.option("--dv", required=True, metavar="COL", help="Dependent variable (a rating column).")(f)
    f = click.argument("data", metavar="DATA")(f)
    return f


def _load(data: str):
    from analysis.stats.design import read_ratings

    return read_ratings(data) if any(ch in data for ch in "*?[") else _read_one(data)


def _read_one(data: str):
    from analysis.stats.design import read_table

    return read_table(data)


def _dump(path: Path | None, key: str, df) -> None:
    if path is None:
        return
    from analysis.stats.study import json_records
    from appeal.atomic import atomic_write_text

    atomic_write_text(Path(path), json.dumps({key: json_records(df)}, indent=1))
    click.echo(f"wrote {path}", err=True)


def _print(df) -> None:
    import pandas as pd

    with pd.option_context("display.width", 200, "display.max_columns", 30, "display.max_rows", 400):
        click.echo(df.to_string(index=False, float_format=lambda v: "" if math.isnan(v) else f"{v:.6g}"))


@analyze.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal analyze anova ratings.csv --dv appeal --subject id --within shape material
  appeal analyze anova 'data/sub-*/ses-*/beh/*_beh.tsv' --dv response_appeal \\
      --within character shape material expression --aggregate mean --json anova.json
  appeal analyze anova obk.csv --dv value --subject id --within phase hour --between treatment gender""")
@_data_options
@click.option("--json", "json_out", type=click.Path(path_type=Path), metavar="OUT.json", help="Also write the table as JSON.")
def anova(data, dv, subject, within, between, aggregate, drop_incomplete, json_out):
    """Repeated-measures ANOVA of DATA (CSV, TSV, Parquet or a quoted glob of BIDS *_beh.tsv).

    Any number of within factors and optional between factors (type III, as car/afex),
    with Mauchly's test, Greenhouse-Geisser and Huynh-Feldt epsilons and corrected p,
    partial and generalised eta squared. Prints the table; --json writes
    {"effects": [{"effect", "SS", "error_SS", "num_df", "den_df", "F", "p", "mauchly_W",
    "mauchly_p", "gg_eps", "hf_eps", "p_gg", "p_hf", "pes", "ges"}, ...]} (null where undefined).
    """
    from analysis.stats.anova import fit_design
    from analysis.stats.design import prepare_design
    from analysis.stats.reporting import anova_text

    design = prepare_design(_load(data), dv, subject, within, between or (), aggregate, drop_incomplete)
    table = fit_design(design).table
    if design.dropped:
        click.echo(f"dropped incomplete participants: {', '.join(design.dropped)}", err=True)
    _print(table)
    click.echo("\n" + anova_text(table))
    _dump(json_out, "effects", table)


@analyze.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal analyze posthoc ratings.csv --dv appeal --subject id --within shape material --effect shape
  appeal analyze posthoc ratings.csv --dv appeal --subject id --within shape material \\
      --effect shape:material --adjust holm --json pairs.json""")
@_data_options
@click.option("--effect", required=True, metavar="A[:B]", help="The effect whose levels (or cells) are compared.")
@click.option("--adjust", type=click.Choice(["tukey", "holm", "bonferroni", "none"]), default="tukey", show_default=True,
              help="Multiplicity adjustment.")
@click.option("--json", "json_out", type=click.Path(path_type=Path), metavar="OUT.json", help="Also write the pairs as JSON.")
def posthoc(data, dv, subject, within, between, aggregate, drop_incomplete, effect, adjust, json_out):
    """Pairwise comparisons (Tukey HSD) of an effect's marginal means.

    Equal to emmeans(<afex model>, ~effect, model = "univariate") + pairs(adjust = "tukey"):
    the standard error comes from the effect's own error stratum (Satterthwaite over
    strata for cells of interactions). --json writes {"comparisons": [{"effect", "a", "b",
    "diff", "se", "df", "q", "p"}, ...]}; a/b are level labels joined by ':'.
    """
    from analysis.stats.anova import fit_design
    from analysis.stats.design import prepare_design
    from analysis.stats.posthoc import pairwise_comparisons

    design = prepare_design(_load(data), dv, subject, within, between or (), aggregate, drop_incomplete)
    table = pairwise_comparisons(fit_design(design), effect, adjust)
    _print(table)
    _dump(json_out, "comparisons", table[["effect", "a", "b", "diff", "se", "df", "q", "p"]])


@analyze.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal analyze contrasts n170.csv --dv amplitude --subject id --within stylization emotion --factor stylization
  appeal analyze contrasts ratings.csv --dv appeal --subject id --within shape --factor shape --json trends.json""")
@_data_options
@click.option("--factor", required=True, metavar="A", help="The ordered within factor (levels in sorted order).")
@click.option("--max-degree", type=int, default=None, metavar="K", help="Highest polynomial degree (default k-1).")
@click.option("--json", "json_out", type=click.Path(path_type=Path), metavar="OUT.json", help="Also write the contrasts as JSON.")
def contrasts(data, dv, subject, within, between, aggregate, drop_incomplete, factor, max_degree, json_out):
    """Polynomial (linear, quadratic, ...) contrasts of an ordered within factor.

    Per-participant contrast scores tested with F(1, n - 1) (thesis section 7.4), plus
    which of the linear and the quadratic ("u-shaped") contrast explains more variance.
    --json writes {"contrasts": [{"factor", "contrast", "F", "num_df", "den_df", "p", "pes"}, ...]}.
    """
    from analysis.stats.contrasts import compare_trends, contrasts_from_design
    from analysis.stats.design import prepare_design

    design = prepare_design(_load(data), dv, subject, within, between or (), aggregate, drop_incomplete)
    table = contrasts_from_design(design, factor, max_degree)
    _print(table)
    if len(table) >= 2:
        click.echo("\n" + compare_trends(table)["text"])
    _dump(json_out, "contrasts", table[["factor", "contrast", "F", "num_df", "den_df", "p", "pes"]])


@analyze.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal analyze ratings protocols/analysis/exp2_ratings.yaml --out results/exp2
  appeal analyze ratings my_study.yaml --out results/mine --force""")
@click.argument("study", type=click.Path(path_type=Path), metavar="STUDY.yaml")
@out_options()
def ratings(study, out, force, resume):
    """The whole analysis of a rating study described by STUDY.yaml (kind: ratings).

    Every scale found in the data (response_* columns), every effect of the rm-ANOVA,
    post-hocs for significant effects, polynomial contrasts, Cronbach's alpha between
    scales, interaction / bar / realism-vs-appeal figures (PNG + SVG), report.md,
    results.json and index.html in DIR. Incomplete designs get a linear mixed model.
    """
    from analysis.ratings_schema import RatingsAnalysis
    from analysis.stats.study import analyze_rating_study
    from appeal.outputs import output_run
    from appeal.studyfile import load_study_file

    cfg = load_study_file(study, RatingsAnalysis)
    with output_run(out, force=force, resume=resume, inputs=[study]) as run:
        res = analyze_rating_study(cfg, run.out)
    click.echo(f"report: {res.index_html}")
