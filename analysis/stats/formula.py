"""Mixed-model formulas written the lme4 way, and the matrices they stand for.

``rating ~ shape * material + (1 + shape | participant) + (1 | stimulus)`` is parsed into a
:class:`Formula` (fixed terms, random terms), and :func:`model_matrices` turns a formula and a
table into the fixed-effects matrix ``X``, the response ``y`` and one :class:`RandomBlock` per
random term (its per-level model matrix and the level of every row), the inputs of
:func:`analysis.stats.lmm.fit_lmm` and :func:`analysis.stats.clmm.fit_clmm`.

Factors are coded with sum-to-zero contrasts (R's ``contr.sum``; afex's default), so type-III
tests are tests of a term's coefficients; columns follow R's order (terms by order, the first
factor varying fastest within an interaction). A factor is a column that is not numeric, or one
named in ``factors`` (a design's ``shape`` levels 0, 0.25 ... are levels, not a covariate); other
numeric columns enter as covariates. Supported: ``a * b``, ``a:b``, ``a + b``, ``0 +``/``- 1``,
``(1 | g)``, ``(1 + a | g)``, ``(0 + a | g)``, ``(1 | g/h)`` (nested: ``g`` and ``g:h``),
``(1 | g:h)`` and ``(1 + a || g)`` (uncorrelated: one random effect per column, factors
sum-coded, as afex's ``expand_re``).
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from analysis.stats.anova import contr_sum
from analysis.stats.design import factor_levels, level_key

__all__ = ["Formula", "RandomTerm", "RandomBlock", "ModelMatrices", "parse_formula", "model_matrices",
           "expand_terms", "term_name", "term_matrix", "fixed_matrix", "FormulaError"]


class FormulaError(ValueError):
    """A formula that cannot be read or does not fit the data (the message is one line)."""


Term = tuple[str, ...]


@dataclass(frozen=True)
class RandomTerm:
    """``(intercept + terms | group)``; ``group`` may be an interaction ``g:h``."""

    intercept: bool
    terms: tuple[Term, ...]
    group: str
    #: Written with ``||``: one uncorrelated random effect per column of the term, factors coded
    #: by their sum-to-zero contrasts (afex's ``expand_re = TRUE``; lme4's own ``||`` codes a
    #: factor by indicators and keeps its columns correlated).
    split: bool = False


@dataclass(frozen=True)
class Formula:
    """A parsed mixed-model formula."""

    response: str
    intercept: bool
    fixed: tuple[Term, ...]
    random: tuple[RandomTerm, ...] = ()
    text: str = ""

    @property
    def variables(self) -> list[str]:
        """Every column the formula names (response, fixed, random, grouping)."""
        names = [self.response, *[v for t in self.fixed for v in t]]
        for r in self.random:
            names += [v for t in r.terms for v in t] + r.group.split(":")
        return list(dict.fromkeys(names))

    def with_random(self, random: Iterable[RandomTerm]) -> "Formula":
        """The same fixed part with other random terms."""
        random = tuple(random)
        return Formula(self.response, self.intercept, self.fixed, random, _formula_text(self, random))


def term_name(term: Term) -> str:
    """``('shape', 'material')`` → ``'shape:material'``."""
    return ":".join(term)


def _split_top(text: str, sep: str) -> list[str]:
    parts, depth, cur = [], 0, ""
    for ch in text:
        depth += ch == "("
        depth -= ch == ")"
        if ch == sep and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    return parts + [cur]


def expand_terms(text: str) -> tuple[bool, list[Term]]:
    """The terms of a fixed-effects expression: ``'a * b'`` → ``(True, [('a',), ('b',), ('a', 'b')])``.

    Returns whether the expression keeps the intercept and the terms in R's order (by order of
    interaction, then as written).
    """
    intercept, terms = True, []
    text = re.sub(r"\s+", "", text)
    text = text.replace("-1", "+0").replace("-0", "+1")
    for part in [p for p in _split_top(text, "+") if p]:
        if part in {"0", "1"}:
            intercept = part == "1"
            continue
        if part.startswith("(") and part.endswith(")"):
            terms += expand_terms(part[1:-1])[1]
            continue
        if not re.fullmatch(r"[A-Za-z_.][A-Za-z0-9_.]*([*:][A-Za-z_.][A-Za-z0-9_.]*)*", part):
            raise FormulaError(f"cannot read the term '{part}' (expected names joined by * or :)")
        if "*" in part:
            factors = part.split("*")
            groups = [tuple(f.split(":")) for f in factors]
            for r in range(1, len(groups) + 1):
                for combo in itertools.combinations(groups, r):
                    terms.append(tuple(v for g in combo for v in g))
        else:
            terms.append(tuple(part.split(":")))
    seen, out = set(), []
    for t in terms:
        key = frozenset(t)
        if key not in seen and len(set(t)) == len(t):
            seen.add(key)
            out.append(t)
    out.sort(key=len)  # stable: R orders terms by their order, then as written
    return intercept, out


def _random_terms(inner: str) -> list[RandomTerm]:
    double = "||" in inner
    lhs, _, group = inner.partition("||" if double else "|")
    group = re.sub(r"\s+", "", group)
    if not lhs.strip() or not group:
        raise FormulaError(f"cannot read the random term '({inner.strip()})' (expected (terms | group))")
    if not re.fullmatch(r"[A-Za-z_.][A-Za-z0-9_.]*([/:][A-Za-z_.][A-Za-z0-9_.]*)*", group):
        raise FormulaError(f"cannot read the grouping '{group}' of '({inner.strip()})'")
    intercept, terms = expand_terms(lhs)
    groups = []
    if "/" in group:
        nest = group.split("/")
        groups = [":".join(nest[: i + 1]) for i in range(len(nest))]
    else:
        groups = [group]
    out = []
    for g in groups:
        if double:
            if intercept:
                out.append(RandomTerm(True, (), g))
            out += [RandomTerm(False, (t,), g, split=True) for t in terms]
        else:
            out.append(RandomTerm(intercept, tuple(terms), g))
    return out


def _formula_text(f: Formula, random: Sequence[RandomTerm]) -> str:
    fixed = " + ".join(term_name(t) for t in f.fixed) or "1"
    if not f.intercept:
        fixed = "0 + " + fixed
    rand, i, random = [], 0, list(random)
    while i < len(random):
        r = random[i]
        if r.split or (r.intercept and not r.terms and i + 1 < len(random) and random[i + 1].split
                       and random[i + 1].group == r.group):
            lhs = ["1"] if not r.split else ["0"]
            j = i + (0 if r.split else 1)
            while j < len(random) and random[j].split and random[j].group == r.group:
                lhs += [term_name(t) for t in random[j].terms]
                j += 1
            rand.append(f"({' + '.join(lhs)} || {r.group})")
            i = j
            continue
        lhs = " + ".join((["1"] if r.intercept else ["0"]) + [term_name(t) for t in r.terms])
        rand.append(f"({lhs} | {r.group})")
        i += 1
    return f"{f.response} ~ " + " + ".join([fixed, *rand])


def parse_formula(text: str) -> Formula:
    """Read an lme4 formula (``y ~ fixed + (random | group)``).

    Raises
    ------
    FormulaError
        With a one-line message when the formula cannot be read.
    """
    if text.count("~") != 1:
        raise FormulaError(f"'{text}' is not a formula (expected response ~ terms)")
    lhs, rhs = (s.strip() for s in text.split("~"))
    if not re.fullmatch(r"[A-Za-z_.][A-Za-z0-9_.]*", lhs):
        raise FormulaError(f"the response of '{text}' must be one column name, not '{lhs}'")
    if rhs.count("(") != rhs.count(")"):
        raise FormulaError(f"unbalanced parentheses in '{text}'")
    random, fixed_parts = [], []
    for part in _split_top(rhs, "+"):
        p = part.strip()
        if p.startswith("(") and p.endswith(")") and "|" in p:
            random += _random_terms(p[1:-1])
        elif p:
            fixed_parts.append(p)
    intercept, fixed = expand_terms("+".join(fixed_parts) if fixed_parts else "1")
    f = Formula(lhs, intercept, tuple(fixed), tuple(random))
    return Formula(f.response, f.intercept, f.fixed, f.random, _formula_text(f, f.random))


@dataclass
class RandomBlock:
    """One random term: ``Xr`` (n × k, the term's model matrix) and ``codes`` (n, the level of
    each row) over ``levels`` (length L); its random effects are L × k."""

    name: str
    group: str
    columns: list[str]
    Xr: np.ndarray
    codes: np.ndarray
    levels: list[str]
    term: int = 0  #: index of the formula's random term it comes from

    @property
    def k(self) -> int:
        return self.Xr.shape[1]

    @property
    def n_levels(self) -> int:
        return len(self.levels)


@dataclass
class ModelMatrices:
    """What a formula stands for on a table (rows with missing values left out)."""

    formula: Formula
    y: np.ndarray
    X: np.ndarray
    columns: list[str]
    term_columns: dict[str, list[int]]
    blocks: list[RandomBlock]
    levels: dict[str, list]
    factors: list[str]
    data: pd.DataFrame = field(repr=False, default=None)

    @property
    def n(self) -> int:
        return len(self.y)


def _coding(data: pd.DataFrame, var: str, levels: Mapping[str, list], coding: str) -> tuple[np.ndarray, list[str]]:
    lv = levels[var]
    keys = {level_key(v): i for i, v in enumerate(lv)}
    uniq, inverse = np.unique(data[var].astype(str).to_numpy(), return_inverse=True)
    first = pd.Series(data[var].to_numpy()).groupby(inverse).first()
    codes = np.array([keys.get(level_key(first[i]), -1) for i in range(len(uniq))], int)[inverse.ravel()]
    if (codes < 0).any():
        raise FormulaError(f"{var}: value {data[var][codes < 0].iloc[0]} is not among the levels {lv}")
    if coding == "indicator":
        return np.eye(len(lv))[codes], [f"{var}{v}" for v in lv]
    if coding == "treatment":
        return np.eye(len(lv))[codes][:, 1:], [f"{var}{v}" for v in lv[1:]]
    return contr_sum(len(lv))[codes], [f"{var}{i + 1}" for i in range(len(lv) - 1)]


def term_matrix(data: pd.DataFrame, term: Term, levels: Mapping[str, list], factors: Iterable[str],
                coding: str = "sum", full_first: bool = False) -> tuple[np.ndarray, list[str]]:
    """The columns of one term: products of its variables' codings, the first varying fastest.

    ``coding`` is ``"sum"`` (contr.sum), ``"treatment"`` (contr.treatment) or ``"indicator"``
    (every level); ``full_first`` codes the first factor by indicators (R's rule for a model
    without an intercept).
    """
    mats, names = [np.ones((len(data), 1))], [""]
    for i, var in enumerate(term):
        if var in factors:
            m, nm = _coding(data, var, levels, "indicator" if full_first and i == 0 else coding)
        else:
            m, nm = data[var].to_numpy(float)[:, None], [var]
        mats = [np.einsum("ni,nj->nji", mats[0], m).reshape(len(data), -1)]
        names = [f"{a}:{b}" if a else b for b in nm for a in names]
    return mats[0], names


def fixed_matrix(mm: "ModelMatrices", data: pd.DataFrame | None = None, coding: str = "sum") -> tuple[np.ndarray, list[str], dict[str, list[int]]]:
    """The fixed-effects matrix of a model on ``data`` (default: its own rows) in a coding.

    Returns the matrix, its column names and each term's columns.
    """
    data = mm.data if data is None else data
    f = mm.formula
    cols, names, term_cols = [], [], {}
    if f.intercept:
        cols.append(np.ones((len(data), 1)))
        names.append("(Intercept)")
    for t in f.fixed:
        m, nm = term_matrix(data, t, mm.levels, mm.factors, coding, full_first=not f.intercept and not names)
        term_cols[term_name(t)] = list(range(len(names), len(names) + len(nm)))
        cols.append(m)
        names += nm
    return (np.hstack(cols) if cols else np.zeros((len(data), 0))), names, term_cols


def model_matrices(formula: Formula | str, data: pd.DataFrame, factors: Iterable[str] = (),
                   levels: Mapping[str, Sequence] | None = None, source: str = "data") -> ModelMatrices:
    """The response, fixed-effects matrix and random-effect blocks of ``formula`` on ``data``.

    Parameters
    ----------
    formula : Formula or str
        An lme4 formula.
    data : DataFrame
        One row per observation; rows with a missing value in a named column are left out.
    factors : iterable of str
        Numeric columns to treat as factors (non-numeric ones always are).
    levels : mapping, optional
        Level order per factor (default: sorted; the order only names the coefficients).
    source : str
        Named in error messages.

    Raises
    ------
    FormulaError
        A column the data lack, a factor with one level, a grouping factor with one level.
    """
    f = parse_formula(formula) if isinstance(formula, str) else formula
    missing = [v for v in f.variables if v not in data.columns]
    if missing:
        raise FormulaError(f"{source}: the formula '{f.text}' names column(s) {', '.join(missing)} that the data "
                           f"lack (columns: {', '.join(map(str, data.columns[:12]))}{' ...' if len(data.columns) > 12 else ''})")
    data = data.dropna(subset=f.variables).reset_index(drop=True)
    if data.empty:
        raise FormulaError(f"{source}: no row has values in every column of '{f.text}'")
    factors = set(factors)
    group_vars = {v for r in f.random for v in r.group.split(":")}
    for v in f.variables:
        if v == f.response or v in group_vars:
            continue
        if not pd.api.types.is_numeric_dtype(data[v]) or isinstance(data[v].dtype, pd.CategoricalDtype):
            factors.add(v)
    levels = dict(levels or {})
    lv = {}
    for v in sorted(factors & set(f.variables) - {f.response}):
        try:
            lv[v] = factor_levels(data[v], levels.get(v))
        except ValueError as exc:
            raise FormulaError(f"{source}: {v}: {exc}") from None
        if len(lv[v]) < 2:
            raise FormulaError(f"{source}: the factor {v} has one level ({lv[v][0]}) in the data: it cannot be estimated")
    y = pd.to_numeric(data[f.response], errors="coerce")
    if y.isna().any():
        raise FormulaError(f"{source}: the response {f.response} holds non-numbers (e.g. '{data[f.response][y.isna()].iloc[0]}')")
    blocks = []
    for ti, r in enumerate(f.random):
        gkey = data[r.group.split(":")[0]].astype(str)
        for v in r.group.split(":")[1:]:
            gkey = gkey + ":" + data[v].astype(str)
        glevels = list(pd.unique(gkey))
        if len(glevels) < 2:
            raise FormulaError(f"{source}: the grouping factor {r.group} has one level ({glevels[0]}): "
                               "a random effect needs at least 2")
        codes = pd.Categorical(gkey, categories=glevels).codes.astype(np.int64)
        if r.split:  # one block per column, sum-coded
            m, nm = term_matrix(data, r.terms[0], lv, factors)
            for c, name in enumerate(nm):
                blocks.append(RandomBlock(f"(0 + {name} || {r.group})", r.group, [name], m[:, [c]], codes, glevels, ti))
            continue
        parts, cn = ([np.ones((len(data), 1))], ["(Intercept)"]) if r.intercept else ([], [])
        for t in r.terms:
            m, nm = term_matrix(data, t, lv, factors, full_first=not r.intercept and not cn)
            parts.append(m)
            cn += nm
        lhs = " + ".join((["1"] if r.intercept else ["0"]) + [term_name(t) for t in r.terms])
        blocks.append(RandomBlock(f"({lhs} | {r.group})", r.group, cn, np.hstack(parts), codes, glevels, ti))
    mm = ModelMatrices(f, y.to_numpy(float), np.zeros((len(data), 0)), [], {}, blocks, lv, sorted(factors), data)
    mm.X, mm.columns, mm.term_columns = fixed_matrix(mm)
    return mm
