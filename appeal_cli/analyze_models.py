"""``appeal analyze lmm | clmm``: mixed models of any table from an lme4-style formula (issue 30)."""

from __future__ import annotations

from pathlib import Path

import click

from appeal_cli.analyze_stats import _Many, _load, _print
from appeal_cli.groups import CONTEXT, analyze
from appeal.errors import AppealInputError


@analyze.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal analyze lmm ratings.csv \\
      --formula "rating ~ shape * material + (1 + shape | participant) + (1 | stimulus)" \\
      --factors shape material --emmeans shape
  appeal analyze lmm 'data/sub-*/ses-*/beh/*_beh.tsv' \\
      --formula "response_appeal ~ shape * material + (1 | participant_id)" \\
      --factors shape material --ddf kenward-roger --json lmm.json
  appeal analyze lmm amplitudes.csv --formula "y ~ condition * group + (1 | lab/participant)"

\b
The formula is lme4's: (1 | g) random intercepts, (1 + a | g) correlated random slopes,
(1 + a || g) uncorrelated ones (one per column, as afex's expand_re), (1 | g/h) h nested
in g, (1 | g:h) an interaction group.
Factors use sum-to-zero contrasts (afex's default), so the F tests are type III.""")
@click.argument("data", metavar="DATA")
@click.option("--formula", required=True, metavar="'Y ~ FIXED + (RANDOM | GROUP)'", help="The model, written as for lme4::lmer.")
@click.option("--factors", cls=_Many, metavar="A B ...", default=None,
              help="Numeric columns that are factors (e.g. shape levels 0, 0.25 ...); text columns always are.")
@click.option("--ddf", type=click.Choice(["satterthwaite", "kenward-roger"]), default="satterthwaite", show_default=True,
              help="Denominator dfs (lmerTest's Satterthwaite or pbkrtest's Kenward-Roger).")
@click.option("--ml", is_flag=True, help="Maximum likelihood instead of REML (for likelihood-ratio comparisons).")
@click.option("--emmeans", "emm", cls=_Many, metavar="A [B]", default=None,
              help="Estimated marginal means of these factors and their Tukey-adjusted pairwise differences.")
@click.option("--json", "json_out", type=click.Path(path_type=Path), metavar="OUT.json", help="Also write the tables as JSON.")
def lmm(data, formula, factors, ddf, ml, emm, json_out):
    """Linear mixed model of DATA (CSV, TSV, Parquet or a quoted glob of BIDS *_beh.tsv).

    Fitted as lme4 does (profiled REML or ML), tested as lmerTest and afex::mixed do (type-III F
    with Satterthwaite or Kenward-Roger dfs); equal to R's numbers to 1e-6 (tests/test_stats_lmm.py).
    Prints the fit (REML criterion, singular-fit and convergence warnings), the type-III table,
    the fixed effects, the variance components and, with --emmeans, the marginal means and
    pairwise comparisons. --json writes {"anova", "coefficients", "variance_components",
    "emmeans", "pairs"}.
    """
    import json

    from analysis.stats.formula import FormulaError
    from analysis.stats.lmm import fit_lmm
    from analysis.stats.lmm_anova import coefficient_table, inference, lmm_anova
    from analysis.stats.records import json_records
    from appeal.atomic import atomic_write_text

    if emm:  # scipy.stats (the studentized range) loads only for the marginal means
        from analysis.stats.lmm_emmeans import emm_pairs, emmeans

    table = _load(data)
    source = table.attrs.get("source", data)
    try:
        fit = fit_lmm(formula, table, factors=factors or (), reml=not ml, source=source)
        tests = inference(fit, ddf)
        anova = lmm_anova(fit, ddf, tests=tests)
        coefs = coefficient_table(fit, tests)
        emm = emmeans(fit, list(emm), tests) if emm else None
    except (FormulaError, ValueError) as exc:
        raise AppealInputError(str(exc)) from None
    crit = "REML criterion" if fit.reml else "deviance (ML)"
    click.echo(f"{fit.formula.text}\n{fit.n} observations; {crit} {fit.deviance:.4f}; "
               f"{'converged' if fit.converged else 'NOT converged'}" + (f"; {'; '.join(fit.warnings)}" if fit.warnings else ""))
    click.echo("\nType III F tests:")
    _print(anova)
    click.echo("\nFixed effects:")
    _print(coefs)
    click.echo("\nVariance components:")
    _print(fit.variance_components())
    out = {"anova": json_records(anova), "coefficients": json_records(coefs),
           "variance_components": json_records(fit.variance_components())}
    if emm is not None:
        pairs = emm_pairs(fit, emm, tests)
        click.echo("\nEstimated marginal means:")
        _print(emm)
        click.echo("\nPairwise differences (Tukey):")
        _print(pairs)
        out["emmeans"], out["pairs"] = json_records(emm), json_records(pairs)
    if json_out:
        atomic_write_text(Path(json_out), json.dumps(out, indent=1))
        click.echo(f"wrote {json_out}", err=True)



@analyze.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal analyze clmm ratings.csv \\
      --formula "rating ~ shape * material + (1 | participant) + (1 | stimulus)" --factors shape material
  appeal analyze clmm 'data/sub-*/ses-*/beh/*_beh.tsv' \\
      --formula "response_appeal ~ shape + (1 | participant_id)" --link probit --probabilities shape \\
      --figure probs --json clmm.json

\b
The response holds ordered categories (a 1..7 Likert item); categories nobody used are
dropped, as ordinal::clmm does. Random intercepts only: (1 | g), crossed or nested (1 | g/h).""")
@click.argument("data", metavar="DATA")
@click.option("--formula", required=True, metavar="'Y ~ FIXED + (1 | GROUP)'", help="The model, written as for ordinal::clmm.")
@click.option("--factors", cls=_Many, metavar="A B ...", default=None,
              help="Numeric columns that are factors; text columns always are.")
@click.option("--link", type=click.Choice(["logit", "probit"]), default="logit", show_default=True)
@click.option("--probabilities", "prob_factors", cls=_Many, metavar="A [B]", default=None,
              help="Predicted probability of each category per cell of these factors (random effects at 0).")
@click.option("--figure", "figure", type=click.Path(path_type=Path), metavar="STEM",
              help="With --probabilities: draw them as stacked bars into STEM.png and STEM.svg.")
@click.option("--json", "json_out", type=click.Path(path_type=Path), metavar="OUT.json", help="Also write the tables as JSON.")
def clmm(data, formula, factors, link, prob_factors, figure, json_out):
    """Cumulative-link mixed model of ordinal ratings in DATA (CSV, TSV, Parquet or a BIDS glob).

    Fitted as ordinal::clmm does (flexible thresholds, Laplace approximation), equal to R's
    numbers to ~1e-7 (tests/test_stats_clmm.py). Prints clmm's summary (coefficients with z
    tests, thresholds, random-intercept SDs, logLik, max gradient, condition number) and the
    likelihood-ratio test of each fixed term. --json writes {"coefficients", "thresholds",
    "lr_tests", "probabilities"}.
    """
    import json

    from analysis.stats.clmm import fit_clmm, likelihood_ratio_tests
    from analysis.stats.formula import FormulaError
    from analysis.stats.study import json_records
    from appeal.atomic import atomic_write_text

    table = _load(data)
    try:
        fit = fit_clmm(formula, table, link=link, factors=factors or (), source=table.attrs.get("source", data))
        lr = likelihood_ratio_tests(fit)
        probs = fit.predicted_probabilities(list(prob_factors)) if prob_factors else None
    except (FormulaError, ValueError) as exc:
        raise AppealInputError(str(exc)) from None
    if figure and probs is None:
        raise AppealInputError("--figure: name the factors to draw with --probabilities")
    click.echo(fit.summary())
    click.echo("\nLikelihood-ratio tests (each term's columns left out):")
    _print(lr)
    out = {"coefficients": json_records(fit.coefficients()), "thresholds": json_records(fit.thresholds()),
           "lr_tests": json_records(lr)}
    if probs is not None:
        click.echo("\nPredicted probabilities (random effects at 0):")
        _print(probs)
        out["probabilities"] = json_records(probs)
        if figure:
            from analysis.stats.clmm_figures import probability_plot

            paths = probability_plot(probs, figure, x=prob_factors[0], panel=prob_factors[1] if len(prob_factors) > 1 else None)
            click.echo(f"wrote {paths[0]}", err=True)
    if json_out:
        atomic_write_text(Path(json_out), json.dumps(out, indent=1))
        click.echo(f"wrote {json_out}", err=True)
