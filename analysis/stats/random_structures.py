"""Random-effects structures: the maximal one a design allows (Barr et al., 2013) and the order
in which it is simplified when it does not converge or is singular.

For each grouping factor (participants, stimuli), a fixed term gets a random slope when its
factors vary within that factor's levels (every participant sees every shape: a by-participant
shape slope; each stimulus has one shape: no by-stimulus shape slope). The fallback order,
stopping at the first model that converges without a singular fit:

1. maximal, correlated (``(1 + a * b | participant) + (1 | stimulus)``);
2. the same terms uncorrelated (``(1 + a + b || g)``: one random effect per column, factors
   coded by their sum-to-zero contrasts, as afex's ``expand_re``);
   when that fit is singular, the terms with a variance estimated at zero (any direction of
   the term's covariance) are dropped and the rest refitted (Bates et al., 2015, "parsimonious mixed models");
3. the highest-order slopes dropped, one order at a time, uncorrelated (``a:b``, then ``a`` and ``b``);
4. random intercepts only.

A grouping factor whose levels each lie within one cell of the fixed effects (one stimulus per
condition of a full factorial, as in thesis Exp. 2) is left out: its variance cannot be told
from the fixed effects'. A structure is skipped when it cannot be estimated from the data: more than :data:`MAX_THETA`
covariance parameters, as many random effects per level as observations per level, or as many
random effects per grouping factor as that factor has levels (21 participants cannot inform 74
variances).
If every candidate is singular the last one that converged is kept and the report says so.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.stats.formula import Formula, FormulaError, RandomTerm, model_matrices, parse_formula
from analysis.stats.lmm import LmmFit, confounded_blocks, fit_lmm, lmm_problem

__all__ = ["slope_terms", "fallback_structures", "fit_with_fallback", "identifiable_groups", "structure_table", "Attempt",
           "MAX_THETA"]

#: Most covariance parameters a candidate structure may have.
MAX_THETA = 120


def slope_terms(data: pd.DataFrame, fixed: Sequence[tuple[str, ...]], group: str) -> list[tuple[str, ...]]:
    """The fixed terms whose variables all vary within the levels of ``group``."""
    out = []
    for term in fixed:
        varies = all(data.groupby(group, observed=True)[v].nunique().max() > 1 for v in term)
        if varies:
            out.append(term)
    return out


def fallback_structures(data: pd.DataFrame, formula: Formula, groups: Sequence[str],
                        fixed_only: Sequence[str] = ()) -> list[tuple[str, tuple[RandomTerm, ...]]]:
    """The candidate random parts, most complex first, each with a label; terms naming a variable
    of ``fixed_only`` (covariates) get no random slopes."""
    terms = [t for t in formula.fixed if not set(t) & set(fixed_only)]
    slopes = {g: slope_terms(data, terms, g) for g in groups}
    max_order = max((len(t) for s in slopes.values() for t in s), default=0)
    out = []
    corr = tuple(RandomTerm(True, tuple(slopes[g]), g) for g in groups)
    out.append(("maximal", corr))
    for order in range(max_order, 0, -1):
        terms = []
        for g in groups:
            terms.append(RandomTerm(True, (), g))
            terms += [RandomTerm(False, (t,), g, split=True) for t in slopes[g] if len(t) <= order]
        label = "maximal, uncorrelated" if order == max_order else f"slopes up to order {order}, uncorrelated"
        out.append((label, tuple(terms)))
    out.append(("random intercepts", tuple(RandomTerm(True, (), g) for g in groups)))
    seen, unique = set(), []
    for label, terms in out:
        key = tuple((r.intercept, r.terms, r.group) for r in terms)
        if key not in seen:
            seen.add(key)
            unique.append((label, terms))
    return unique


@dataclass
class Attempt:
    """One candidate structure and what happened to it."""

    label: str
    formula: str
    outcome: str
    fit: LmmFit | None = None


def _size_problem(mm) -> str | None:
    n_rows = mm.n
    n_theta = sum(b.k * (b.k + 1) // 2 for b in mm.blocks)
    if n_theta > MAX_THETA:
        return f"skipped: {n_theta} covariance parameters (more than {MAX_THETA})"
    per_group: dict[str, int] = {}
    for b in mm.blocks:
        per_level = n_rows / b.n_levels
        if b.k >= per_level:
            return f"skipped: {b.k} random effects per {b.group} for {per_level:.0f} observations per level"
        per_group[b.group] = per_group.get(b.group, 0) + b.k
    for b in mm.blocks:
        if per_group[b.group] >= b.n_levels:
            return (f"skipped: {per_group[b.group]} random effects per {b.group} for {b.n_levels} levels of it "
                    "(their variances need more levels than effects)")
    return None


def fit_with_fallback(data: pd.DataFrame, formula: str, *, random: str = "maximal", groups: Sequence[str] = (),
                      factors=(), levels=None, source: str = "data", reml: bool = True,
                      fixed_only: Sequence[str] = ()) -> tuple[LmmFit, list[Attempt]]:
    """Fit ``formula`` (its fixed part) with ``random`` effects, simplifying a maximal structure
    in the documented order until a fit converges without a singular fit.

    Parameters
    ----------
    data : DataFrame
        Trial-level observations.
    formula : str
        ``response ~ fixed`` (random terms in it are used when ``random`` is ``"formula"``).
    random : str
        ``"maximal"`` (with ``groups``), or lme4 random terms such as
        ``"(1 + shape | participant) + (1 | stimulus)"`` (fitted as written, no fallback).
    groups : sequence of str
        Grouping factors of the maximal structure.
    fixed_only : sequence of str
        Fixed-part variables without random slopes in the maximal structure (covariates).

    Returns
    -------
    (LmmFit, list of Attempt)
        The chosen fit and every candidate tried (with why it was passed over).

    Raises
    ------
    FormulaError
        When no candidate could be fitted (the message names the last problem).
    """
    base = parse_formula(formula)
    if random != "maximal":
        full = parse_formula(f"{base.text} + {random}")
        fit = fit_lmm(full, data, factors=factors, levels=levels, source=source, reml=reml)
        return fit, [Attempt("as written", full.text, _outcome(fit), fit)]
    if not groups:
        raise FormulaError(f"{source}: random: maximal needs grouping factors (participant, stimulus)")
    used = data.dropna(subset=[v for v in base.variables if v in data.columns] + list(groups))
    groups, dropped = identifiable_groups(data, base, groups, factors, levels, source)
    attempts: list[Attempt] = []
    chosen = None
    queue = fallback_structures(used, base, groups, fixed_only)
    while queue:
        label, terms = queue.pop(0)
        f = base.with_random(terms)
        try:
            mm = model_matrices(f, data, factors, levels, source)
        except FormulaError as exc:
            attempts.append(Attempt(label, f.text, f"not fitted: {exc}"))
            continue
        skip = _size_problem(mm)
        if skip:
            attempts.append(Attempt(label, f.text, skip))
            continue
        fit = fit_lmm(mm, reml=reml, source=source)
        attempts.append(Attempt(label, f.text, _outcome(fit), fit))
        if fit.converged:
            chosen = fit
            if not fit.singular:
                break
            pruned = _drop_zero_terms(fit, terms) if "uncorrelated" in label else None
            if pruned is not None:
                queue.insert(0, (f"{label}, zero-variance terms dropped", pruned))
    if chosen is None:
        raise FormulaError(f"{source}: no random-effects structure could be fitted ({attempts[-1].outcome})")
    for g in dropped:
        attempts.insert(0, Attempt(f"(1 | {g})", f"(1 | {g})", f"left out: every {g} lies within one cell of the "
                                   "fixed effects (its variance cannot be told from theirs)"))
    return chosen, attempts


def identifiable_groups(data: pd.DataFrame, formula: Formula | str, groups: Sequence[str], factors=(), levels=None,
                        source: str = "data") -> tuple[list[str], list[str]]:
    """The grouping factors whose random intercepts can be told from the fixed effects, and the
    others (each level within one cell of the fixed effects: one stimulus per condition).

    Raises
    ------
    FormulaError
        When no grouping factor is left.
    """
    base = parse_formula(formula) if isinstance(formula, str) else formula
    dropped = []
    for g in groups:
        probe = base.with_random([RandomTerm(True, (), g)])
        if confounded_blocks(lmm_problem(model_matrices(probe, data, factors, levels, source))):
            dropped.append(g)
    kept = [g for g in groups if g not in dropped]
    if not kept:
        raise FormulaError(f"{source}: every grouping factor ({', '.join(dropped)}) is confounded with the fixed effects")
    return kept, dropped


def _drop_zero_terms(fit: LmmFit, terms: tuple[RandomTerm, ...]) -> tuple[RandomTerm, ...] | None:
    """The terms without those with a variance estimated at zero (None: nothing to drop)."""
    zero = {blk.term for blk, T in zip(fit.mm.blocks, fit.problem.factors(fit.theta)) if np.any(np.abs(np.diag(T)) < 1e-4)}
    keep = [term for i, term in enumerate(terms) if i not in zero]
    return tuple(keep) if 0 < len(keep) < len(terms) else None


def _outcome(fit: LmmFit) -> str:
    if not fit.converged:
        return "did not converge"
    return "singular fit" if fit.singular else "converged"


def structure_table(attempts: Sequence[Attempt], chosen: LmmFit) -> pd.DataFrame:
    """The attempts as a table (label, formula, outcome, used)."""
    return pd.DataFrame([{"structure": a.label, "formula": a.formula, "outcome": a.outcome,
                          "used": a.fit is chosen} for a in attempts])

