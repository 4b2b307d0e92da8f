"""The whole psychometric analysis of a psychophysics study (``kind: psychometric``).

The runner's trials (BIDS ``*_beh.tsv``, one row per trial) are read and checked, binned per
participant × condition by the stimulus variable ``x``, and fitted (:func:`fit_bayes` or
:func:`fit_ml`); the same per condition with every participant's trials pooled. The
per-participant thresholds are then compared across within factors with the rm-ANOVA and
post-hocs of :mod:`analysis.stats`. Outputs: ``fits.csv``, ``pooled.csv``, ``comparison_anova.csv``,
``comparison_posthoc.csv``, one figure per participant and one of the group, ``report.md``,
``results.json`` and ``index.html``.
"""

from __future__ import annotations

import difflib
import glob
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from scipy import stats

from analysis.psychometric.figures import Curve, group_figure, participant_figure
from analysis.psychometric.fit import MIN_LEVELS, FitResult, fit_bayes, fit_ml, fit_table, log_likelihood
from analysis.psychometric.schema import FitOptions, PsychometricAnalysis
from analysis.stats.anova import fit_design, single_thread_blas
from analysis.stats.design import factor_levels, keep_rows, prepare_design, read_ratings, rows_text
from analysis.stats.posthoc import pairwise_comparisons
from analysis.stats.records import json_records, write_csv
from analysis.stats.reporting import anova_text, format_comparison, markdown_table
from appeal.atomic import atomic_write_text
from appeal.errors import AppealInputError
from appeal.labels import label_problem
from appeal.logs import logger
from appeal.outputs import require_inside
from appeal.progress import progress
from appeal.report import ReportSection, write_index_html

__all__ = ["FittedCell", "PsychometricResult", "data_files", "read_trials", "bin_trials", "count_problems",
           "fit_cells", "fits_frame", "compare_thresholds", "condition_summary", "analyze_psychometric_study"]

#: Decimals x is rounded to before binning (|level - reference| carries float noise).
X_DECIMALS = 9
_ANSWERS = {"1": 1.0, "0": 0.0, "1.0": 1.0, "0.0": 0.0, "true": 1.0, "false": 0.0}
_MISSING = {"", "n/a", "na", "nan", "none"}


@dataclass
class FittedCell:
    """One fitted participant × condition (or one pooled condition).

    Attributes
    ----------
    key : dict
        ``{subject column: id, condition column: level, ...}`` (no subject when pooled).
    data : numpy.ndarray
        The binned trials, rows ``(x, n_correct, n_trials)``.
    fit : FitResult
    """

    key: dict[str, Any]
    data: NDArray
    fit: FitResult


@dataclass
class PsychometricResult:
    """What :func:`analyze_psychometric_study` wrote and found."""

    fits: pd.DataFrame
    pooled: pd.DataFrame
    anova: pd.DataFrame | None = None
    posthoc: pd.DataFrame | None = None
    skipped: list[str] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)
    report_md: Path | None = None
    index_html: Path | None = None


# --------------------------------------------------------------------------- reading
def data_files(patterns: Sequence[str]) -> list[str]:
    """The files the data globs match, sorted; a one-line error for a glob that matches nothing."""
    files: list[str] = []
    for pattern in patterns:
        found = sorted(glob.glob(pattern)) if any(ch in pattern for ch in "*?[") else [pattern]
        if not found:
            raise AppealInputError(f"{pattern}: data: no file matches this pattern (expected the runner's "
                                   "*_beh.tsv files; run the study first or fix the glob)")
        files.extend(f for f in found if f not in files)
    return files


def _check_columns(data: pd.DataFrame, source: str, cfg: PsychometricAnalysis) -> None:
    """One line per column a data file lacks, naming the role the study file gave it."""
    expected = {"x": (cfg.x, "the psychometric function's stimulus variable"),
                "correct": (cfg.correct, "1 = correct, 0 = not, n/a = no answer")}
    expected.update({f"conditions[{i}]": (c, "a condition to fit separately") for i, c in enumerate(cfg.conditions)})
    problems = []
    for role, (name, what) in expected.items():
        if name not in data.columns:
            close = difflib.get_close_matches(name, [str(c) for c in data.columns], n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            problems.append(f"{source}: {role}: column '{name}' not found (expected {what}{hint})")
    if problems:
        raise AppealInputError(problems)


def _where(data: pd.DataFrame, mask: NDArray) -> str:
    """'rows f.tsv:3, f.tsv:9' for the True rows of ``mask``."""
    sub = data.loc[mask]
    return rows_text([f"{Path(f).name}:{r}" for f, r in zip(sub["source_file"], sub["source_row"])])


def _answers(data: pd.DataFrame, col: str, source: str) -> NDArray:
    """The ``correct`` column as 1.0 / 0.0 / NaN (no answer); other values are an error."""
    text = data[col].astype(str).str.strip().str.lower()
    values = text.map(_ANSWERS).to_numpy(dtype=float)
    bad = np.isnan(values) & ~(data[col].isna().to_numpy() | text.isin(_MISSING).to_numpy())
    if bad.any():
        eg = ", ".join(repr(v) for v in pd.unique(data.loc[bad, col])[:3])
        raise AppealInputError(f"{source}: correct: values other than 1, 0 or n/a in {_where(data, bad)} "
                               f"(e.g. {eg}); expected 1 = correct, 0 = not, n/a = no answer")
    return values


def _stimulus(data: pd.DataFrame, col: str, source: str) -> NDArray:
    """The stimulus variable as numbers (rounded to :data:`X_DECIMALS`); text is an error."""
    values = pd.to_numeric(data[col], errors="coerce").to_numpy(dtype=float)
    text = data[col].astype(str).str.strip().str.lower()
    bad = np.isnan(values) & ~(data[col].isna().to_numpy() | text.isin(_MISSING).to_numpy())
    if bad.any():
        eg = ", ".join(repr(v) for v in pd.unique(data.loc[bad, col])[:3])
        raise AppealInputError(f"{source}: x: non-numeric values of '{col}' in {_where(data, bad)} (e.g. {eg}); "
                               "expected numbers")
    return np.round(values, X_DECIMALS)


def _order_conditions(data: pd.DataFrame, cfg: PsychometricAnalysis, source: str) -> pd.DataFrame:
    """Condition columns as ordered categoricals (``levels`` order, else sorted); empty values are an error."""
    for col in cfg.conditions:
        empty = data[col].isna().to_numpy()
        if empty.any():
            raise AppealInputError(f"{source}: {col}: empty values in {_where(data, empty)}; expected a level in "
                                   "every main trial")
        try:
            order = factor_levels(data[col], cfg.levels.get(col))
        except ValueError as exc:
            raise AppealInputError(f"{source}: levels.{col}: {exc}") from None
        data[col] = pd.Categorical(data[col], categories=order, ordered=True)
    return data


def participant_label(value: Any) -> str:
    """A participant id as its BIDS label: ``sub-01`` and ``01`` are both ``01``."""
    text = value if isinstance(value, str) else str(value)
    return text.removeprefix("sub-")


def _check_subjects(data: pd.DataFrame, source: str, subject: str) -> None:
    """Every participant id of a file is a BIDS label (after an optional ``sub-``): a figure's file name
    is built from it, so ``x/../../escaped`` must not reach one; a one-line error naming the row."""
    col = data[subject]
    for value, row in zip(*np.unique(col.astype(str).to_numpy(), return_index=True)):
        raw = col.iloc[int(row)]
        if raw is None or (isinstance(raw, float) and np.isnan(raw)):
            problem = "expected a participant label (letters and digits), got an empty cell"
        else:
            problem = label_problem(participant_label(raw))
        if problem is not None:
            line = int(data["source_row"].iloc[int(row)])
            raise AppealInputError(f"{source}: row {line}: column '{subject}': {problem}"
                                   + (" (after its 'sub-')" if str(raw).startswith("sub-") else ""))


def read_trials(cfg: PsychometricAnalysis) -> pd.DataFrame:
    """The answered main trials of every data file, checked.

    Each file is checked for the columns the analysis names; ``rows`` (default: ``phase: main``)
    drops practice trials; trials without an answer (``correct`` n/a) or without ``x`` are dropped.

    Returns
    -------
    pandas.DataFrame
        The trials with ``x`` and ``correct`` as numbers, condition columns as ordered categoricals,
        the subject as text, ``source_file``/``source_row``; ``attrs["source"]`` names the data,
        ``attrs["unanswered"]`` counts the main trials dropped for want of an answer or an x.
    """
    files = data_files(cfg.patterns)
    frames = []
    for f in files:
        frame = read_ratings([f], subject=cfg.subject)
        _check_columns(frame, f, cfg)
        _check_subjects(frame, f, cfg.subject)
        frames.append(frame)
    data = keep_rows(pd.concat(frames, ignore_index=True), cfg.rows)
    source = files[0] if len(files) == 1 else f"{files[0]} (+{len(files) - 1} more files)"
    if data.empty:
        raise AppealInputError(f"{source}: rows: no trials left after keeping {cfg.rows}")
    data[cfg.correct] = _answers(data, cfg.correct, source)
    data[cfg.x] = _stimulus(data, cfg.x, source)
    keep = data[cfg.correct].notna() & data[cfg.x].notna()
    data = data.loc[keep].reset_index(drop=True)
    if data.empty:
        raise AppealInputError(f"{source}: correct: no answered trials (every value is n/a)")
    data[cfg.subject] = data[cfg.subject].astype(str)
    data = _order_conditions(data, cfg, source)
    data.attrs.update(source=source, unanswered=int((~keep).sum()))
    return data


# --------------------------------------------------------------------------- fitting
def bin_trials(trials: pd.DataFrame, x: str, correct: str) -> NDArray:
    """Trials binned by level: rows ``(x, n_correct, n_trials)`` in increasing ``x``."""
    g = trials.groupby(x, sort=True)[correct].agg(["sum", "count"])
    return np.column_stack([g.index.to_numpy(float), g["sum"].to_numpy(float), g["count"].to_numpy(float)])


def _fit(data: NDArray, opts: FitOptions) -> FitResult:
    """One fit with the analysis file's options."""
    if opts.method == "ml":
        return fit_ml(data, opts.family, opts.nafc, opts.sigmoid_pc, opts.width_alpha)
    return fit_bayes(data, opts.family, opts.nafc, opts.sigmoid_pc, opts.width_alpha,
                     grid_steps=opts.grid or None, ci_level=opts.ci_level)


def cell_label(key: Mapping[str, Any], subject: str | None = None) -> str:
    """``participant 03, expression=happiness`` (or ``all trials`` for a pooled fit without conditions)."""
    parts = [f"participant {key[subject]}"] if subject and subject in key else []
    parts += [f"{k}={v}" for k, v in key.items() if k != subject]
    return ", ".join(parts) or "all trials"


def _too_few(data: NDArray, cfg: PsychometricAnalysis, label: str) -> str | None:
    """Why ``data`` is too little for a fit, or None."""
    n, k = int(data[:, 2].sum()), len(data)
    if n >= cfg.fit.min_trials and k >= MIN_LEVELS:
        return None
    return (f"{label}: {n} answered trials over {k} level{'s' if k != 1 else ''} of {cfg.x}; a fit needs at least "
            f"{cfg.fit.min_trials} trials over {MIN_LEVELS} levels (fit.min_trials; fit.too_few: skip leaves it out)")


def _groups(trials: pd.DataFrame, by: Sequence[str]) -> list[tuple[dict[str, Any], pd.DataFrame]]:
    """``({column: value}, rows)`` per group of ``by`` (one group of every row when ``by`` is empty)."""
    if not by:
        return [({}, trials)]
    return [(dict(zip(by, v if isinstance(v, tuple) else (v,))), rows)
            for v, rows in trials.groupby(list(by), observed=True, sort=True)]


def count_problems(trials: pd.DataFrame, cfg: PsychometricAnalysis) -> list[str]:
    """One line per participant × condition with too few trials for a fit (none with ``fit.too_few: skip``).

    Checked before an output folder exists; :func:`fit_cells` checks again as it fits.
    """
    if cfg.fit.too_few == "skip":
        return []
    source = trials.attrs.get("source", "<data>")
    lines = [_too_few(bin_trials(rows, cfg.x, cfg.correct), cfg, cell_label(key, cfg.subject))
             for key, rows in _groups(trials, [cfg.subject, *cfg.conditions])]
    return [f"{source}: {line}" for line in lines if line]


def fit_cells(trials: pd.DataFrame, by: Sequence[str], cfg: PsychometricAnalysis,
              subject: str | None = None) -> tuple[list[FittedCell], list[str]]:
    """Fit one function per group of ``by`` columns.

    Parameters
    ----------
    trials : pandas.DataFrame
        From :func:`read_trials`.
    by : sequence of str
        Grouping columns (the subject and the conditions, or the conditions alone for pooled fits).
    cfg : PsychometricAnalysis
    subject : str, optional
        The subject column (for messages).

    Returns
    -------
    cells : list of FittedCell
    skipped : list of str
        Groups with too few trials (``fit.too_few: skip``), as text.

    Raises
    ------
    AppealInputError
        One line per group with too few trials (``fit.too_few: error``) or that cannot be fitted.
    """
    source = trials.attrs.get("source", "<data>")
    cells, skipped, problems = [], [], []
    for key, rows in progress(_groups(trials, by), desc="psychometric fits"):
        label = cell_label(key, subject)
        data = bin_trials(rows, cfg.x, cfg.correct)
        few = _too_few(data, cfg, label)
        if few:
            (skipped.append(few) if cfg.fit.too_few == "skip" else problems.append(f"{source}: {few}"))
            continue
        try:
            with single_thread_blas():  # small problems: a threaded BLAS only synchronises
                cells.append(FittedCell(key, data, _fit(data, cfg.fit)))
        except AppealInputError as exc:
            problems.append(f"{source}: {label}: {exc.lines[0]}")
    if problems:
        raise AppealInputError(problems)
    for msg in skipped:
        logger.warning("%s: skipped %s", source, msg)
    return cells, skipped


def _deviance(cell: FittedCell) -> float:
    """Binomial deviance of the fit against the saturated model (as psignifit)."""
    x, k, n = cell.data.T
    saturated = float(log_likelihood(k / n, k, n))
    return 2.0 * (saturated - cell.fit.log_likelihood)


def _x_at_pc(fit: FitResult, pc: float) -> float:
    """The x at which the fitted function reaches ``pc``; NaN where it never does."""
    try:
        return fit.level_at(pc)
    except AppealInputError:
        return float("nan")


def _on_continuum(table: pd.DataFrame, cfg: PsychometricAnalysis) -> pd.DataFrame:
    """Add ``point`` (with CI) and ``point_at_pc``: x at the threshold and at threshold_pc on the continuum."""
    ref, sign = cfg.continuum.reference, cfg.continuum.direction
    xt = "x_threshold" if "x_threshold" in table else "threshold"
    lo, hi = ref + sign * table[f"{xt}_lo"], ref + sign * table[f"{xt}_hi"]
    return table.assign(point=ref + sign * table[xt], point_lo=np.minimum(lo, hi), point_hi=np.maximum(lo, hi),
                        point_at_pc=ref + sign * table["x_at_pc"])


def fits_frame(cells: Sequence[FittedCell], cfg: PsychometricAnalysis) -> pd.DataFrame:
    """The tidy table of fits: one row per cell.

    Columns: the key columns, ``n_trials``, ``n_levels``, ``family``, ``method``, ``nafc``,
    ``threshold``, ``width``, ``lambda``, ``gamma``, ``eta`` each with ``_lo``/``_hi`` (credible
    interval; NaN for ML fits), ``x_at_pc`` (x where P(correct) = ``fit.threshold_pc``),
    ``x_threshold`` with CI (Weibull only: the threshold in x units, ``exp(threshold)``),
    ``point`` with CI and ``point_at_pc`` (with ``continuum``), ``log_likelihood`` and ``deviance``.
    """
    if not cells:
        return pd.DataFrame()
    keys = pd.DataFrame([c.key for c in cells])
    table = fit_table([c.fit for c in cells]).drop(columns="fit")
    table["n_levels"] = [len(c.data) for c in cells]
    table["x_at_pc"] = [_x_at_pc(c.fit, cfg.fit.threshold_pc) for c in cells]
    if cfg.fit.family == "weibull":
        for col in ("threshold", "threshold_lo", "threshold_hi"):
            table[col.replace("threshold", "x_threshold")] = np.exp(table[col])
    if cfg.continuum is not None:
        table = _on_continuum(table, cfg)
    table["deviance"] = [_deviance(c) for c in cells]
    front, back = ["n_trials", "n_levels", "family", "method", "nafc"], ["log_likelihood", "deviance"]
    table = table[front + [c for c in table.columns if c not in front + back] + back]
    return pd.concat([keys, table], axis=1)


# --------------------------------------------------------------------------- comparison
def compare_thresholds(fits: pd.DataFrame, cfg: PsychometricAnalysis,
                       source: str) -> tuple[pd.DataFrame, pd.DataFrame, list[str]] | None:
    """rm-ANOVA of the per-participant ``compare_measure`` across ``compare``, and post-hocs.

    Conditions not compared are averaged; participants missing a compared cell are dropped.

    Returns
    -------
    (anova, posthoc, dropped) or None
        None when nothing is compared or fewer than 2 participants have every cell.
    """
    dv = cfg.compare_measure
    if not cfg.compare or fits.empty:
        return None
    usable = fits.dropna(subset=[dv])
    cells_per = usable[[cfg.subject, *cfg.compare]].drop_duplicates().groupby(cfg.subject).size()
    if int((cells_per == len(fits[cfg.compare].drop_duplicates())).sum()) < 2:
        logger.warning("%s: compare: fewer than 2 participants with every cell; no comparison", source)
        return None
    design = prepare_design(usable, dv, cfg.subject, cfg.compare, aggregate="mean", drop_incomplete=True,
                            levels={c: cfg.levels[c] for c in cfg.compare if c in cfg.levels}, source=source)
    fit = fit_design(design)
    posthocs = [pairwise_comparisons(fit, effect, cfg.posthoc.adjust) for effect in fit.table["effect"]
                if len(effect.split(":")) <= cfg.posthoc.max_order
                and np.prod([len(design.within[f]) for f in effect.split(":")]) <= cfg.posthoc.max_cells]
    posthoc = pd.concat(posthocs, ignore_index=True) if posthocs else pd.DataFrame()
    return fit.table, posthoc, design.dropped


def condition_summary(fits: pd.DataFrame, conditions: Sequence[str], measure: str,
                      level: float = 0.95) -> pd.DataFrame:
    """Mean, t-based confidence interval and n of ``measure`` across participants per condition."""
    groups = fits.groupby(list(conditions), observed=True, sort=True) if conditions else [((), fits)]
    rows = []
    for values, g in groups:
        v = g[measure].dropna().to_numpy(float)
        n = len(v)
        half = stats.t.ppf(0.5 + level / 2, n - 1) * v.std(ddof=1) / np.sqrt(n) if n > 1 else np.nan
        key = dict(zip(conditions, values if isinstance(values, tuple) else (values,)))
        rows.append({**key, "n": n, "mean": v.mean() if n else np.nan, "lower": v.mean() - half if n else np.nan,
                     "upper": v.mean() + half if n else np.nan})
    return pd.DataFrame(rows)


# --------------------------------------------------------------------------- figures
def _participant_figures(cells: Sequence[FittedCell], cfg: PsychometricAnalysis, out: Path) -> list[Path]:
    """One PNG (+ SVG) per participant: binned data and fitted curves of every condition."""
    paths = []
    for sid in dict.fromkeys(c.key[cfg.subject] for c in cells):
        mine = [c for c in cells if c.key[cfg.subject] == sid]
        curves = [Curve(cell_label({k: v for k, v in c.key.items() if k != cfg.subject}), c.data, c.fit)
                  for c in mine]
        continuum = (cfg.continuum.reference, cfg.continuum.direction) if cfg.continuum else None
        stem = out / "figures" / f"sub-{participant_label(sid)}_psychometric"
        require_inside(out, stem, f"participant {sid}: figure")
        paths.append(participant_figure(curves, stem, cfg.fit.threshold_pc, cfg.x, f"participant {sid}",
                                        continuum)[0])
    return paths


def condition_labels(table: pd.DataFrame, conditions: Sequence[str]) -> pd.Series:
    """Each row's condition as text (``happiness / 0.5``), ``all trials`` without conditions."""
    if not conditions:
        return pd.Series("all trials", index=table.index)
    return table[list(conditions)].astype(str).agg(" / ".join, axis=1)


def _condition_order(trials: pd.DataFrame, conditions: Sequence[str]) -> list[str]:
    """Condition labels in the conditions' level order."""
    combos = trials[list(conditions)].drop_duplicates().sort_values(list(conditions)) if conditions else trials.iloc[:1]
    return list(dict.fromkeys(condition_labels(combos, conditions)))


def _measure_long(fits: pd.DataFrame, trials: pd.DataFrame, cfg: PsychometricAnalysis) -> pd.DataFrame:
    """Subject, condition label (ordered categorical) and the compared measure of every fit."""
    order = _condition_order(trials, cfg.conditions)
    label = pd.Categorical(condition_labels(fits, cfg.conditions), categories=order, ordered=True)
    return fits.assign(condition=label)[[cfg.subject, "condition", cfg.compare_measure]]


def _group_figure(long: pd.DataFrame, summary: pd.DataFrame, cfg: PsychometricAnalysis, out: Path) -> Path:
    unit = f"log {cfg.x}" if cfg.fit.family == "weibull" else cfg.x
    ylabel = {"x_at_pc": f"{cfg.x} at P(correct) = {cfg.fit.threshold_pc:g}",
              "threshold": f"threshold ({unit})", "width": f"width ({unit})"}[cfg.compare_measure]
    return group_figure(long, summary, cfg.subject, cfg.compare_measure, ylabel, out / "group_thresholds",
                        title=cfg.title)[0]


# --------------------------------------------------------------------------- report
def _methods_text(cfg: PsychometricAnalysis, trials: pd.DataFrame) -> list[str]:
    o = cfg.fit
    task = f"{o.nafc}-AFC (guess rate 1/{o.nafc})" if o.nafc else "yes/no (guess rate fitted)"
    how = ("psignifit-4-style Bayesian fit (default priors, beta-binomial overdispersion η, MAP estimates, "
           f"{o.ci_level:.0%} credible intervals)" if o.method == "bayes" else
           "binomial maximum-likelihood fit (no intervals)")
    cond = f" × {' × '.join(cfg.conditions)}" if cfg.conditions else ""
    dropped = trials.attrs.get("unanswered", 0)
    return [f"Data: `{trials.attrs.get('source')}` — {trials[cfg.subject].nunique()} participants, "
            f"{len(trials)} answered main trials" + (f" ({dropped} without an answer left out)." if dropped else "."),
            "",
            f"One psychometric function per participant{cond}: {o.family} sigmoid in psignifit's parameterisation "
            f"(threshold where the sigmoid reaches {o.sigmoid_pc:g}, width from {o.width_alpha:g} to "
            f"{1 - o.width_alpha:g}), {task}, lapse rate λ fitted; {how}. Stimulus variable: `{cfg.x}`; "
            f"`x_at_pc` is the {cfg.x} at which the fitted function reaches P(correct) = {o.threshold_pc:g}."
            + (f" On the continuum: point = {cfg.continuum.reference:g} {'+' if cfg.continuum.direction > 0 else '−'}"
               f" {cfg.x}." if cfg.continuum else ""), ""]


def _fits_preview(fits: pd.DataFrame, cfg: PsychometricAnalysis) -> str:
    cols = [c for c in [cfg.subject, *cfg.conditions, "n_trials", "threshold", "threshold_lo", "threshold_hi",
                        "width", "lambda", "x_at_pc", "point"] if c in fits]
    return markdown_table(fits[cols]) if not fits.empty else "(no fits)"


def _comparison_text(anova: pd.DataFrame, posthoc: pd.DataFrame, dropped: list[str],
                     cfg: PsychometricAnalysis) -> list[str]:
    lines = [f"Per-participant `{cfg.compare_measure}` across {' × '.join(cfg.compare)}: repeated-measures ANOVA "
             "(Greenhouse–Geisser when Mauchly is significant; with one two-level factor F = t² of the paired "
             f"t-test); post-hocs {cfg.posthoc.adjust}.", ""]
    if dropped:
        lines += [f"Left out (a compared cell without an estimate): {', '.join(dropped)}.", ""]
    lines += [anova_text(anova, cfg.alpha), ""]
    if not posthoc.empty:
        sig = posthoc[posthoc["p"] < cfg.alpha]
        lines += [f"Post-hoc pairs with p < {cfg.alpha}: "
                  + ("; ".join(format_comparison(r) for _, r in sig.iterrows()) if len(sig) else "none") + ".", ""]
    return lines


def _write_report(out: Path, cfg: PsychometricAnalysis, trials: pd.DataFrame, res: PsychometricResult,
                  tables: Mapping[str, Path], group_fig: Path | None, summary: pd.DataFrame,
                  comparison: list[str]) -> None:
    intro = _methods_text(cfg, trials)
    skipped = ([f"Skipped (too few trials): {'; '.join(res.skipped)}.", ""] if res.skipped else [])
    fits_text = ["Per participant and condition (full table: `fits.csv`; pooled over participants: `pooled.csv`):",
                 "", _fits_preview(res.fits, cfg), "", *skipped]
    group_text = [f"`{cfg.compare_measure}` per condition: mean and 95% t interval across participants.", "",
                  markdown_table(summary), ""]
    sections = [ReportSection("Fits", "\n".join(fits_text), res.figures, [tables["fits"], tables["pooled"]]),
                ReportSection("Group", "\n".join(group_text), [group_fig] if group_fig else [])]
    if comparison:
        sections.append(ReportSection("Comparison", "\n".join(comparison),
                                      tables=[tables[k] for k in ("comparison_anova", "comparison_posthoc")
                                              if k in tables]))
    md = [f"# {cfg.title}", "", *intro]
    for sec in sections:
        md += [f"## {sec.title}", "", sec.text, ""]
        md += [f"![{p.stem}]({p.relative_to(out).as_posix()})" for p in sec.figures] + [""]
    res.report_md = atomic_write_text(out / "report.md", "\n".join(md) + "\n")
    res.index_html = write_index_html(out / "index.html", cfg.title, sections,
                                      intro="\n".join(intro) + "\n\n[report.md](report.md) · "
                                                               "[results.json](results.json)")


def _comparison(res: PsychometricResult, cfg: PsychometricAnalysis, source: str, out: Path,
                tables: dict[str, Path]) -> list[str]:
    """Compare the thresholds (``compare``): fill ``res.anova``/``res.posthoc``, write their tables
    into ``tables``, return the report's text (empty when nothing is compared)."""
    compared = compare_thresholds(res.fits, cfg, source)
    if compared is None:
        return ([f"Not compared: fewer than 2 participants have a `{cfg.compare_measure}` in every cell of "
                 f"{' × '.join(cfg.compare)}.", ""] if cfg.compare else [])
    res.anova, res.posthoc, dropped = compared
    tables["comparison_anova"] = write_csv(res.anova, out / "comparison_anova.csv")
    tables["comparison_posthoc"] = write_csv(res.posthoc, out / "comparison_posthoc.csv")
    return _comparison_text(res.anova, res.posthoc, dropped, cfg)


def _participants_per_condition(trials: pd.DataFrame, pooled: pd.DataFrame, cfg: PsychometricAnalysis) -> NDArray:
    """How many participants each pooled fit's trials come from."""
    if not cfg.conditions:
        return np.full(len(pooled), trials[cfg.subject].nunique())
    n = trials.groupby(list(cfg.conditions), observed=True)[cfg.subject].nunique()
    return np.array([n.loc[tuple(r) if len(r) > 1 else r[0]] for r in pooled[list(cfg.conditions)].to_numpy()])


def analyze_psychometric_study(cfg: PsychometricAnalysis, out: Path,
                               trials: pd.DataFrame | None = None) -> PsychometricResult:
    """Run the analysis a ``kind: psychometric`` file describes.

    Parameters
    ----------
    cfg : PsychometricAnalysis
        The validated analysis file.
    out : Path
        Output folder (exists; the caller manages it with ``appeal.outputs.output_run``).
    trials : pandas.DataFrame, optional
        Use these trials (as :func:`read_trials` returns them) instead of reading ``cfg.data``.

    Returns
    -------
    PsychometricResult
    """
    trials = read_trials(cfg) if trials is None else trials
    source = trials.attrs.get("source", "<data>")
    if trials.attrs.get("unanswered"):
        logger.info("%s: %d main trials without an answer (or x) left out", source, trials.attrs["unanswered"])
    cells, skipped = fit_cells(trials, [cfg.subject, *cfg.conditions], cfg, cfg.subject)
    pooled_cells, _ = fit_cells(trials, cfg.conditions, cfg)
    fits, pooled = fits_frame(cells, cfg), fits_frame(pooled_cells, cfg)
    if not pooled.empty:
        pooled.insert(len(cfg.conditions), "n_participants", _participants_per_condition(trials, pooled, cfg))
    res = PsychometricResult(fits, pooled, skipped=skipped)
    tables = {"fits": write_csv(fits, out / "fits.csv"), "pooled": write_csv(pooled, out / "pooled.csv")}
    comparison = _comparison(res, cfg, source, out, tables)
    res.figures = _participant_figures(cells, cfg, out)
    summary, group_fig = pd.DataFrame(), None
    if not fits.empty:
        long = _measure_long(fits, trials, cfg)
        summary = condition_summary(long, ["condition"], cfg.compare_measure)
        group_fig = _group_figure(long, summary, cfg, out)
    results = {"title": cfg.title, "n_participants": int(trials[cfg.subject].nunique()), "n_fits": len(fits),
               "skipped": skipped, "fits": json_records(fits), "pooled": json_records(pooled),
               "anova": json_records(res.anova) if res.anova is not None else None}
    atomic_write_text(out / "results.json", json.dumps(results, indent=1, default=str))
    _write_report(out, cfg, trials, res, tables, group_fig, summary, comparison)
    logger.info("psychometric analysis written to %s", out)
    return res
