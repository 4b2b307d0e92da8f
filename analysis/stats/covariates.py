"""Low-level image measures of the stimuli (``appeal stimuli audit``'s ``audit.csv``) as covariates.

An analysis file names an audit table and some of its measures (``covariates: {audit: ...,
measures: [face_L_mean], by: stimulus}``). The audit has one row per image, keyed by ``file``
(the grid manifest's path, which the runner writes into the ``stimulus`` column of every
trial); :func:`join_audit` gives every trial its stimulus's measures, :func:`centre_covariates`
centres them at their grand mean over the trials (so factor effects are estimated at the mean
covariate), and :func:`check_estimable` refuses a covariate that cannot be told from the fixed
factors (constant within every cell, or collinear with the cells).

A mixed model takes the centred covariates as fixed main effects
(:func:`analysis.stats.lmm_report.lmm_section`'s ``covariates``); the rm-ANOVA on cell means,
which has no place for a trial-level predictor, gets an ANCOVA-style adjustment instead
(:func:`ancova_adjust`): the slopes ``b`` from the trial-level regression with the cells and
participants as fixed effects (so only the covariate's variation within cells, across stimuli,
informs them), then ``y_adj = y − b·(x − x̄)`` before the trials are averaged into cell means.

Everything here is pure (tables in, tables out) except :func:`read_audit`, which reads the file.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

import numpy as np
import pandas as pd

from analysis.confounds.design_tests import DEFAULT_THRESHOLDS
from appeal.errors import AppealInputError

__all__ = ["AUDIT_MEASURES", "MIXED_HINT", "CovariateSet", "read_audit", "stimulus_key", "join_audit", "centre_covariates",
           "check_estimable", "ancova_adjust", "AncovaAdjustment", "prepare_covariates"]

#: The measures ``appeal stimuli audit`` writes (``stimulus_engine.audit.workflow.run_audit``).
AUDIT_MEASURES = tuple(DEFAULT_THRESHOLDS)

#: What to do when a covariate cannot be separated from a model's fixed factors.
MIXED_HINT = ("leave a factor such as character out of the fixed factors so that each cell holds several stimuli, "
              "and keep the stimuli as a random factor")

#: Relative size below which a covariate's variation (left after the cells) counts as none.
TOLERANCE = 1e-8


@dataclass
class CovariateSet:
    """Covariates joined to trial data: the table, the covariate columns and their grand means."""

    data: pd.DataFrame
    measures: list[str]
    means: dict[str, float] = field(default_factory=dict)
    dropped: int = 0  #: rows without a stimulus (anchors, practice) left out
    audit: str = ""


def _measure_list(columns: Sequence[str]) -> str:
    known = [c for c in AUDIT_MEASURES if c in columns]
    return ", ".join(known or [str(c) for c in columns])


def read_audit(path: str | Path, measures: Sequence[str]) -> pd.DataFrame:
    """Read an audit table and keep ``file`` and the named measures.

    Parameters
    ----------
    path : str or Path
        ``audit.csv`` as ``appeal stimuli audit MANIFEST --out DIR`` writes it.
    measures : sequence of str
        The measures to use as covariates.

    Returns
    -------
    DataFrame
        ``file`` (as in the manifest) and one float column per measure; ``attrs["source"]`` is the path.

    Raises
    ------
    AppealInputError
        One line naming the file when it is missing or unreadable, lacks ``file`` or a measure
        (listing those it has), holds a measure that is not numeric, or lists a file twice.
    """
    path = Path(path)
    expected = "expected the audit.csv of `appeal stimuli audit MANIFEST --out DIR`"
    if not path.is_file():
        raise AppealInputError(f"{path}: covariates.audit: file not found ({expected})")
    try:
        table = pd.read_csv(path)
    except Exception as exc:  # noqa: BLE001 - parser errors become one input line
        raise AppealInputError(f"{path}: covariates.audit: cannot read the table ({str(exc).splitlines()[0]}; {expected})") from None
    if "file" not in table.columns:
        raise AppealInputError(f"{path}: covariates.audit: no 'file' column ({expected}: one row per image with its "
                               "manifest path in 'file')")
    missing = [m for m in measures if m not in table.columns]
    if missing:
        raise AppealInputError(f"{path}: covariates.measures: {', '.join(missing)} not in the audit table "
                               f"(available measures: {_measure_list(list(table.columns))})")
    out = pd.DataFrame({"file": table["file"].map(stimulus_key)})
    for m in measures:
        values = pd.to_numeric(table[m], errors="coerce")
        bad = values.isna() & table[m].notna()
        if bad.any():
            raise AppealInputError(f"{path}: covariates.measures: {m} holds non-numbers (e.g. {table[m][bad].iloc[0]!r} "
                                   f"for {table['file'][bad].iloc[0]}); expected numbers")
        out[m] = values.astype(float)
    dup = out["file"][out["file"].duplicated()]
    if len(dup):
        raise AppealInputError(f"{path}: file: {dup.iloc[0]} is listed {int((out['file'] == dup.iloc[0]).sum())} times "
                               "(expected one row per image)")
    out.attrs["source"] = str(path)
    return out


def stimulus_key(value: object) -> str:
    """A stimulus path as a join key: forward slashes, no ``./``; empty for a missing value."""
    if value is None or (isinstance(value, float) and np.isnan(value)) or value is pd.NA:
        return ""
    text = str(value).strip().replace("\\", "/")
    if text.lower() in ("", "n/a", "nan", "none"):
        return ""
    return str(PurePosixPath(text))


def _count(n: int) -> str:
    return f"{n} stimulus" if n == 1 else f"{n} stimuli"


def join_audit(data: pd.DataFrame, audit: pd.DataFrame, measures: Sequence[str], by: str = "stimulus",
               source: str = "data") -> tuple[pd.DataFrame, int]:
    """Give every trial its stimulus's measures.

    Parameters
    ----------
    data : DataFrame
        Trial rows with a stimulus column ``by`` holding the manifest's ``file`` values.
    audit : DataFrame
        :func:`read_audit`'s table.
    measures : sequence of str
        Measure columns to add (under their own names).
    by : str
        The data's stimulus column.
    source : str
        Names the data in messages.

    Returns
    -------
    (DataFrame, int)
        The rows with a stimulus, the measures added; and how many rows had no stimulus (the
        runner's anchors or practice trials when the ``rows:`` filter kept them) and were left out.

    Raises
    ------
    AppealInputError
        When ``by`` is not a column, a measure's name is already a data column, a stimulus of
        the data is not in the audit (naming the audit file, how many and the first), or a
        stimulus's measure is empty in the audit.
    """
    audit_src = audit.attrs.get("source", "the audit table")
    if by not in data.columns:
        raise AppealInputError(f"{source}: covariates.by: no column '{by}' in the data (expected the column with each "
                               "trial's stimulus file, as in the grid manifest)")
    clash = [m for m in measures if m in data.columns]
    if clash:
        raise AppealInputError(f"{source}: covariates.measures: the data already have a column {clash[0]} "
                               "(rename it: the covariate is added under the measure's name)")
    keys = data[by].map(stimulus_key)
    has = (keys != "").to_numpy()
    kept = data.loc[has].reset_index(drop=True)
    keys = keys[has].reset_index(drop=True)
    known = set(audit["file"])
    unknown = pd.unique(keys[~keys.isin(known)])
    if len(unknown):
        raise AppealInputError(f"{audit_src}: {_count(len(unknown))} of {source} (column {by}) not in the audit's file "
                               f"column, the first {unknown[0]} (expected the audit of the manifest the experiment showed)")
    table = audit.set_index("file")[list(measures)]
    values = table.loc[keys.to_numpy()].reset_index(drop=True)
    for m in measures:
        empty = values[m].isna().to_numpy()
        if empty.any():
            raise AppealInputError(f"{audit_src}: {m} is empty for {_count(keys[empty].nunique())} the data show, the first "
                                   f"{keys[empty].iloc[0]} (see the audit's warning column; choose another measure)")
    if kept.empty:
        raise AppealInputError(f"{source}: covariates.by: no row has a stimulus in column {by} (expected the manifest's "
                               "file of each trial)")
    out = pd.concat([kept, values], axis=1)
    out.attrs.update(data.attrs)
    return out, int((~has).sum())


def centre_covariates(data: pd.DataFrame, measures: Sequence[str]) -> tuple[pd.DataFrame, dict[str, float]]:
    """Subtract each covariate's grand mean over the rows (factor effects then hold at the mean).

    Returns
    -------
    (DataFrame, dict)
        The table with centred measure columns, and each measure's mean.
    """
    means = {m: float(data[m].astype(float).mean()) for m in measures}
    out = data.assign(**{m: data[m].astype(float) - means[m] for m in measures})
    out.attrs.update(data.attrs)
    return out, means


def _dummies(data: pd.DataFrame, blocks: Sequence[Sequence[str]]) -> np.ndarray:
    """Indicators of each block's cells (a block's columns combined), side by side."""
    mats = [np.ones((len(data), 1))]
    for cols in blocks:
        if not cols:
            continue
        codes = data.groupby(list(cols), sort=False, observed=True, dropna=False).ngroup().to_numpy()
        mats.append(np.eye(codes.max() + 1)[codes])
    return np.hstack(mats)


def _residuals(D: np.ndarray, M: np.ndarray) -> np.ndarray:
    """``M`` less its least-squares projection on the columns of ``D``."""
    return M - D @ np.linalg.lstsq(D, M, rcond=None)[0]


def check_estimable(data: pd.DataFrame, measures: Sequence[str], blocks: Sequence[Sequence[str]], *,
                    source: str = "data", hint: str = "") -> None:
    """Refuse covariates that cannot be separated from the fixed effects.

    Parameters
    ----------
    data : DataFrame
        Trial rows with the covariate columns.
    measures : sequence of str
        The covariates.
    blocks : sequence of sequence of str
        The fixed effects as groups of columns whose level combinations are cells: ``[factors]``
        for a full-factorial mixed model, ``[factors, [subject]]`` for the ANCOVA regression.
    source, hint : str
        Named in the message; ``hint`` says what to do.

    Raises
    ------
    AppealInputError
        When a covariate is (numerically) constant within every cell, or the covariates together
        add fewer dimensions than their number to the fixed design (rank check).
    """
    if not measures:
        return
    X = data[list(measures)].to_numpy(float)
    X = X - X.mean(axis=0)
    scale = np.linalg.norm(X, axis=0)
    named = " + ".join(" × ".join(b) for b in blocks if b) or "the intercept"
    todo = f" ({hint})" if hint else ""
    R = _residuals(_dummies(data, blocks), X)
    left = np.linalg.norm(R, axis=0)
    for m, s, r in zip(measures, scale, left):
        if s == 0 or r <= TOLERANCE * s:
            raise AppealInputError(f"{source}: covariates: {m} is constant within every cell of {named}, so it cannot be "
                                   f"separated from those factors{todo}")
    if len(measures) > 1:
        sv = np.linalg.svd(R / left, compute_uv=False)
        if sv[-1] <= np.sqrt(TOLERANCE) * sv[0]:
            raise AppealInputError(f"{source}: covariates: {', '.join(measures)} are collinear within the cells of "
                                   f"{named}, so they cannot be separated from each other and those factors (name "
                                   "fewer measures)")


@dataclass
class AncovaAdjustment:
    """What :func:`ancova_adjust` did: the slopes and the words for the report."""

    slopes: dict[str, float]
    means: dict[str, float]
    n: int
    text: str


def ancova_adjust(data: pd.DataFrame, response: str, factors: Sequence[str], subject: str,
                  measures: Sequence[str], *, means: dict[str, float] | None = None,
                  source: str = "data") -> tuple[pd.DataFrame, AncovaAdjustment]:
    """Adjust trial responses for centred covariates before they are averaged into cell means.

    The slopes ``b`` come from the trial-level least-squares regression
    ``y ~ cell + participant + x₁ + …`` (R: ``lm(y ~ cell + participant + x)``), so they are
    estimated from each covariate's variation within the cells of ``factors`` (across stimuli);
    then ``y_adj = y − Σ b·(x − x̄)`` (the columns are already centred).

    Parameters
    ----------
    data : DataFrame
        Trial rows; the covariate columns centred (:func:`centre_covariates`).
    response : str
        The response column (numbers; rows where it is missing are left out of the regression
        and stay missing).
    factors : sequence of str
        Within and between factors (their combinations are the cells).
    subject : str
        The participant column.
    measures : sequence of str
        The covariate columns.
    means : dict, optional
        The covariates' grand means (for the report).
    source : str
        Named in messages.

    Returns
    -------
    (DataFrame, AncovaAdjustment)
        The data with ``response`` replaced by the adjusted values, and the slopes.

    Raises
    ------
    AppealInputError
        When a covariate does not vary within the cells (see :func:`check_estimable`).
    """
    y = pd.to_numeric(data[response], errors="coerce")
    used = data.loc[y.notna().to_numpy()]
    check_estimable(used, measures, [list(factors), [subject]], source=source,
                    hint="the stimuli of a cell must differ: leave a factor such as character out of within/between "
                         "so that each cell holds several stimuli")
    D = _dummies(used, [list(factors), [subject]])
    X = used[list(measures)].to_numpy(float)
    Rx = _residuals(D, X)
    Ry = _residuals(D, y[y.notna()].to_numpy(float)[:, None])
    b = np.linalg.lstsq(Rx, Ry, rcond=None)[0][:, 0]
    slopes = dict(zip(measures, map(float, b)))
    adjusted = y - data[list(measures)].to_numpy(float) @ b
    out = data.assign(**{response: adjusted})
    out.attrs.update(data.attrs)
    means = means or {}
    terms = "; ".join(f"{m}: b = {v:.4g}" + (f" (mean {means[m]:.4g})" if m in means else "") for m, v in slopes.items())
    text = (f"ANCOVA-style adjustment for the audit measure(s) {', '.join(measures)}: slopes from the trial-level "
            f"regression with the cells of {' × '.join(factors)} and the participants as fixed effects ({len(used)} "
            f"trials), then y_adj = y − b·(x − x̄) before averaging into cell means; {terms}. The ANOVA's dfs do not "
            "count the estimated slopes; the mixed model (model: both) tests the factors with the covariates exactly.")
    return out, AncovaAdjustment(slopes, dict(means), len(used), text)


def prepare_covariates(data: pd.DataFrame, audit: str | Path, measures: Sequence[str], by: str = "stimulus",
                       source: str = "data") -> CovariateSet:
    """Read the audit, join it to ``data`` by stimulus and centre the covariates (the usual path).

    Returns
    -------
    CovariateSet
        The joined, centred rows, the measures, their means and the rows left out for having no stimulus.
    """
    table = read_audit(audit, measures)
    joined, dropped = join_audit(data, table, measures, by, source)
    centred, means = centre_covariates(joined, measures)
    return CovariateSet(centred, list(measures), means, dropped, str(audit))
