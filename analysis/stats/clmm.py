"""Cumulative-link mixed models for ordinal (Likert) ratings, fitted as R's ``ordinal::clmm``.

The model (Christensen 2019, *ordinal — regression models for ordinal data*, R package; the
``clmm`` defaults: flexible thresholds, Laplace approximation, ``nAGQ = 1``) for a response with
ordered categories ``1 < 2 < … < J`` is

    P(Y_i ≤ j) = F(θ_j − x_i'β − z_i'b),    b = (τ_1 u_1, …, τ_K u_K),  u ~ N(0, I),

with ``F`` the logistic (``link="logit"``) or standard normal (``link="probit"``) distribution
function, ``θ_1 < … < θ_{J−1}`` the thresholds (they take the intercept's place, so ``X`` has no
intercept column), ``β`` the fixed effects (sum-to-zero coded factors, as
:mod:`analysis.stats.formula` builds them; note the minus sign: a positive ``β`` moves ratings
up), and one random intercept per level of each grouping factor, with standard deviation
``τ_k`` per random term (crossed, e.g. ``(1 | participant) + (1 | stimulus)``, or nested,
``(1 | site/participant)``).

The marginal likelihood is approximated as ``clmm`` does (Laplace): for given parameters
φ = (θ, β, τ) the conditional modes û of the standardised random effects minimise

    h(u) = −Σ_i log[F(η_i1) − F(η_i2)] + ½ u'u,    η_i1 = θ_{y_i} − x_i'β − b_i,  η_i2 = θ_{y_i−1} − …

(Newton iterations on the q × q Hessian ``H = I + ΛZ'WZΛ``, W the rows' curvatures; with random
intercepts each term's own block of ``Z'WZ`` is diagonal and the cross blocks are ``bincount``
tables, so H is factorised through the Schur complement over the levels of all but the term with
most levels: 40 participants × 250 stimuli factorise a 40 × 40 matrix), and

    −log L(φ) ≈ h(û) + ½ log det H(û).

The outer optimisation over φ uses the exact gradient of that approximation (envelope terms,
the derivative of ``log det H`` through W and the implicit derivative of û; third derivatives of
the log-likelihood of each row, no finite differences), L-BFGS-B (thresholds through their
log-gaps, so they stay ordered; τ ≥ 0) and then Newton steps whose Hessian is the central
difference of that gradient. That Hessian, over (θ, β, τ) with any τ < 10⁻³ left out, is the one
``clmm`` computes with ``deriv12`` (the difference of function values) for ``summary``: the
standard errors are the square roots of the diagonal of its inverse (``vcov.clmm``,
Cholesky), ``cond_H`` the ratio of its extreme eigenvalues. ``clmm`` optimises over the SDs
themselves when there are two or more random terms and over ``log τ`` with one; ``cond_H`` and
``max_grad`` are reported in the same parametrisation (the standard errors of θ and β do not
depend on it).

One difference, by design: with a single random term ``clmm`` takes its C code path (``NRalgv3``),
whose Laplace determinant uses the Hessian of the last-but-one Newton iterate of the modes rather
than of the modes themselves; its log-likelihood then differs from the Laplace approximation by
~10⁻⁶–10⁻⁵ (its estimates by ~10⁻⁶). Here the determinant is always at the modes, as ``clmm`` computes it
for two or more terms, and for one with ``clmm.control(useMatrix = TRUE)``.

As ``clmm``, response categories absent from the data are dropped (the thresholds are those
between the categories observed, e.g. ``3|5`` when no one answered 4), grouping factors need at
least 3 levels and the response at least 2 categories. The dense Schur complement suits designs
whose random terms other than the largest have up to a few thousand levels together.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import linalg, stats

from analysis.stats.clmm_laplace import (BOUNDARY, LaplaceProblem, OptimResult, category_probabilities, optimise,
                                        pdf_derivs)
from analysis.stats.formula import Formula, FormulaError, ModelMatrices, model_matrices, parse_formula
from analysis.stats.lmm import blas_threads

__all__ = ["ClmmFit", "fit_clmm", "likelihood_ratio_tests", "LINKS", "MAX_RANDOM_EFFECTS"]

#: The links fitted (``ordinal`` also has cloglog, loglog and cauchit).
LINKS = ("logit", "probit")
#: Most levels of the random terms other than the largest (the Schur complement's size).
MAX_RANDOM_EFFECTS = 5000
#: The offset that stands for ±∞ above the top and below the bottom threshold (as ``ordinal``).


@dataclass
class ClmmFit:
    """A fitted cumulative-link mixed model, in ``ordinal::clmm``'s terms.

    Attributes
    ----------
    formula : Formula
        The model.
    link : str
        ``"logit"`` or ``"probit"``.
    categories : list
        The response categories observed, in order (those without a rating are dropped, as clmm).
    threshold_names : list of str
        ``"1|2"``, ``"2|3"`` … (clmm's names).
    columns : list of str
        The fixed-effect columns (sum-to-zero coded, no intercept).
    theta, beta, tau : ndarray
        Thresholds, fixed effects and random-intercept SDs (one per random term).
    groups : list of str
        The grouping factor of each random term.
    loglik : float
        The Laplace-approximated log-likelihood (clmm's ``logLik``).
    n : int
        Observations.
    vcov : ndarray
        Covariance of (θ, β) (the leading block of the inverse Hessian, as ``vcov(clmm)``).
    hessian : ndarray
        Hessian of −logLik over (θ, β, τ) (τ on the boundary left out), in the τ scale.
    max_grad : float
        max|gradient| at the estimates, in clmm's parametrisation (log τ for one random term).
    cond_H : float
        Condition number of the Hessian in clmm's parametrisation (``summary(fit)$info$cond.H``).
    converged : bool
        Whether the gradient is below the tolerance.
    """

    formula: Formula
    link: str
    categories: list
    threshold_names: list[str]
    columns: list[str]
    theta: np.ndarray
    beta: np.ndarray
    tau: np.ndarray
    groups: list[str]
    group_levels: list[list[str]]
    loglik: float
    n: int
    vcov: np.ndarray
    hessian: np.ndarray
    hessian_free: np.ndarray
    gradient: np.ndarray
    max_grad: float
    cond_H: float
    converged: bool
    message: str
    n_evals: int
    n_iter: int
    u: np.ndarray
    cond_var: np.ndarray
    y_codes: np.ndarray = field(repr=False)
    mm: ModelMatrices = field(repr=False)
    term_columns: dict[str, list[int]] = field(repr=False, default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def n_params(self) -> int:
        """Estimated parameters (clmm's ``edf``): thresholds, fixed effects, SDs."""
        return len(self.theta) + len(self.beta) + len(self.tau)

    @property
    def aic(self) -> float:
        """−2 logLik + 2 edf (``AIC(clmm)``)."""
        return -2 * self.loglik + 2 * self.n_params

    @property
    def bic(self) -> float:
        """−2 logLik + log(n) edf."""
        return -2 * self.loglik + math.log(self.n) * self.n_params

    def _table(self, names: list[str], est: np.ndarray, se: np.ndarray) -> pd.DataFrame:
        z = est / se
        return pd.DataFrame({"term": names, "estimate": est, "se": se, "z": z,
                             "p": 2 * stats.norm.sf(np.abs(z))})

    def coefficients(self) -> pd.DataFrame:
        """Fixed effects: estimate, SE, z and two-sided p (``summary(clmm)``'s coefficients)."""
        se = np.sqrt(np.diag(self.vcov))[len(self.theta):]
        return self._table(self.columns, self.beta, se)

    def thresholds(self) -> pd.DataFrame:
        """Thresholds θ_j (``"1|2"`` …): estimate, SE, z (``summary(clmm)``'s threshold table)."""
        se = np.sqrt(np.diag(self.vcov))[: len(self.theta)]
        out = self._table(self.threshold_names, self.theta, se).drop(columns="p")
        return out.rename(columns={"term": "threshold"})

    def variance_components(self) -> pd.DataFrame:
        """``VarCorr(clmm)``: each random intercept's variance and SD."""
        return pd.DataFrame({"group": self.groups, "term": "(Intercept)", "variance": self.tau ** 2, "sd": self.tau})

    def random_effects(self) -> dict[str, pd.DataFrame]:
        """``ranef(clmm, condVar = TRUE)``: conditional modes b = τ û and their conditional variances."""
        out, off = {}, 0
        for g, lv, t in zip(self.groups, self.group_levels, self.tau):
            sl = slice(off, off + len(lv))
            out[g] = pd.DataFrame({"(Intercept)": t * self.u[sl], "cond_var": self.cond_var[sl]},
                                  index=pd.Index(lv, name=g))
            off += len(lv)
        return out

    def summary(self) -> str:
        """A text summary in the layout of ``print(summary(clmm))``."""
        lines = [f"Cumulative link mixed model (Laplace approximation), link = {self.link}",
                 f"formula: {self.formula.text}",
                 f"nobs {self.n}  logLik {self.loglik:.2f}  AIC {self.aic:.2f}  max.grad {self.max_grad:.2e}  "
                 f"cond.H {self.cond_H:.1e}", "", "Random effects:"]
        for g, lv, t in zip(self.groups, self.group_levels, self.tau):
            lines.append(f"  {g:<20} (Intercept)  variance {t ** 2:.4f}  SD {t:.4f}  ({len(lv)} levels)")
        lines += ["", "Coefficients:", self.coefficients().to_string(index=False), "", "Thresholds:",
                  self.thresholds().to_string(index=False)]
        if self.warnings:
            lines += ["", *self.warnings]
        return "\n".join(lines)

    # -- predicted probabilities ------------------------------------------------------------------
    def reference_grid(self, factors: Sequence[str] | None = None) -> pd.DataFrame:
        """Every combination of the levels of the fixed-effect factors (covariates at their means)."""
        fixed_vars = list(dict.fromkeys(v for t in self.formula.fixed for v in t))
        fac = [v for v in fixed_vars if v in self.mm.levels]
        cov = [v for v in fixed_vars if v not in self.mm.levels]
        if factors is not None:
            bad = [f for f in factors if f not in fac]
            if bad:
                raise FormulaError(f"{', '.join(bad)}: not a factor of the fixed effects of '{self.formula.text}' "
                                   f"(factors: {', '.join(fac) or 'none'})")
        if fac:
            grid = pd.MultiIndex.from_product([self.mm.levels[f] for f in fac], names=fac).to_frame(index=False)
        else:
            grid = pd.DataFrame(index=[0])
        for c in cov:
            grid[c] = float(self.mm.data[c].mean())
        return grid

    def _grid_X(self, grid: pd.DataFrame) -> np.ndarray:
        if not self.formula.fixed:
            return np.zeros((len(grid), 0))
        g = grid.copy()
        g[self.formula.response] = 1.0
        fixed_only = Formula(self.formula.response, True, self.formula.fixed, (), "")
        mm = model_matrices(fixed_only, g, factors=self.mm.factors, levels=self.mm.levels, source="reference grid")
        return mm.X[:, 1:]

    def predicted_probabilities(self, factors: Sequence[str] | None = None, level: float = 0.95) -> pd.DataFrame:
        """Predicted probability of each response category per condition, at random effects = 0.

        This is what ``emmeans(fit, ~ factors | rating, mode = "prob")`` gives for a ``clmm``:
        ``P(Y = j) = F(θ_j − x'β) − F(θ_{j−1} − x'β)`` for a typical participant and stimulus
        (all random effects 0, not averaged over their distribution), per cell of the fixed
        factors (covariates at their means); factors left out of ``factors`` are averaged over
        with equal weights (on the probability scale), as emmeans does. Standard errors by the
        delta method from :attr:`vcov`, intervals ``probability ± z·se`` (emmeans' asymptotic
        limits).

        Parameters
        ----------
        factors : sequence of str, optional
            The factors to keep (default: every factor of the fixed effects).
        level : float
            Confidence level of the intervals.

        Returns
        -------
        DataFrame
            The factor columns, ``category``, ``probability``, ``se``, ``lower``, ``upper``.
        """
        grid = self.reference_grid(factors)
        fac = [c for c in grid.columns if c in self.mm.levels]
        keep = list(fac if factors is None else factors)
        X = self._grid_X(grid)
        eta = X @ self.beta if len(self.beta) else np.zeros(len(grid))
        th = np.concatenate([[-np.inf], self.theta, [np.inf]])
        J, nt, p = len(self.categories), len(self.theta), len(self.beta)
        up = th[None, 1:] - eta[:, None]          # cells × J
        lo = th[None, :-1] - eta[:, None]
        prob = category_probabilities(up.ravel(), lo.ravel(), self.link).reshape(up.shape)
        fu = np.where(np.isfinite(up), pdf_derivs(np.where(np.isfinite(up), up, 0.0), self.link, 0)[0], 0.0)
        fl = np.where(np.isfinite(lo), pdf_derivs(np.where(np.isfinite(lo), lo, 0.0), self.link, 0)[0], 0.0)
        # Jacobian of each (cell, category) probability over (θ, β)
        jac = np.zeros((len(grid), J, nt + p))
        for j in range(J):
            if j < nt:
                jac[:, j, j] += fu[:, j]
            if j > 0:
                jac[:, j, j - 1] -= fl[:, j]
            jac[:, j, nt:] = -(fu[:, j] - fl[:, j])[:, None] * X
        if keep:
            key = grid[keep].astype(object).apply(tuple, axis=1)
            cells = list(dict.fromkeys(key))
            member = np.array([[k == c for k in key] for c in cells], float)
            member /= member.sum(1, keepdims=True)
            out_grid = pd.DataFrame(cells, columns=keep)
        else:
            member = np.full((1, len(grid)), 1.0 / len(grid))
            out_grid = pd.DataFrame(index=[0])
        prob_m = member @ prob
        jac_m = np.einsum("mc,cjk->mjk", member, jac)
        se = np.sqrt(np.maximum(np.einsum("mjk,kl,mjl->mj", jac_m, self.vcov, jac_m), 0.0))
        zq = stats.norm.ppf(0.5 + level / 2)
        rows = []
        for m in range(len(out_grid)):
            base = {c: out_grid.iloc[m][c] for c in keep}
            for j, cat in enumerate(self.categories):
                rows.append({**base, "category": cat, "probability": prob_m[m, j], "se": se[m, j],
                             "lower": prob_m[m, j] - zq * se[m, j], "upper": prob_m[m, j] + zq * se[m, j]})
        return pd.DataFrame(rows)


def _response(data: pd.DataFrame, response: str, source: str) -> tuple[pd.DataFrame, list | None]:
    """An ordered Categorical response → its codes 1..k (labels kept); other non-numbers refused."""
    if response not in data.columns:
        return data, None
    col = data[response]
    if isinstance(col.dtype, pd.CategoricalDtype):
        if not col.cat.ordered:
            raise FormulaError(f"{source}: the response {response} is an unordered categorical: clmm needs ordered "
                               "categories (integers such as 1..7, or an ordered Categorical)")
        codes = col.cat.codes.astype(float).where(col.cat.codes >= 0)
        return data.assign(**{response: codes + 1}), list(col.cat.categories)
    if pd.api.types.is_bool_dtype(col):
        raise FormulaError(f"{source}: the response {response} holds True/False: clmm needs ordered categories "
                           "(integers such as 1..7, or an ordered Categorical)")
    if not pd.api.types.is_numeric_dtype(col):
        bad = next((v for v in col.dropna() if not isinstance(v, (int, float, np.integer, np.floating))), None)
        if bad is not None:
            raise FormulaError(f"{source}: the response {response} holds '{bad}': clmm needs ordered categories "
                               "(integers such as 1..7, or an ordered Categorical)")
    return data, None


def _label(v) -> str:
    if isinstance(v, (float, np.floating)) and float(v).is_integer():
        return str(int(v))
    return str(v)


def _build(mm: ModelMatrices, link: str, source: str, labels: list | None,
           response_order: Sequence | None) -> tuple[LaplaceProblem, list, list[str]]:
    f = mm.formula
    for r in f.random:
        if r.terms or not r.intercept:
            lhs = " + ".join((["1"] if r.intercept else ["0"]) + [":".join(t) for t in r.terms])
            raise FormulaError(f"{source}: '{f.text}': clmm here takes random intercepts only, (1 | group), "
                               f"not ({lhs} | {r.group})")
    if not mm.blocks:
        raise FormulaError(f"{source}: '{f.text}' has no random term (write one as (1 | participant))")
    if not f.intercept:
        raise FormulaError(f"{source}: '{f.text}': the thresholds of a cumulative-link model take the intercept's "
                           "place: drop the '0 +' / '- 1'")
    y = mm.y
    if not np.all(np.isfinite(y)) or not np.all(y == np.round(y)):
        bad = y[~(y == np.round(y))][0]
        raise FormulaError(f"{source}: the response {f.response} holds {bad:g}: clmm needs ordered categories "
                           "(integers such as 1..7, or an ordered Categorical)")
    present = sorted(np.unique(y))
    if response_order is not None:
        from analysis.stats.design import level_key
        keys = {level_key(v): i for i, v in enumerate(response_order)}
        missing = [v for v in present if level_key(v) not in keys]
        if missing:
            raise FormulaError(f"{source}: the response {f.response} holds {_label(missing[0])}, "
                               "not among its given levels")
        present = sorted(present, key=lambda v: keys[level_key(v)])
    if len(present) < 2:
        raise FormulaError(f"{source}: the response {f.response} has one category ({_label(present[0])}) in the data: "
                           "an ordinal model needs at least 2")
    order = np.argsort(present)                       # rank among the values → category index
    yc = order[np.searchsorted(np.asarray(present)[order], y)].astype(np.int64)
    cats = [labels[int(v) - 1] for v in present] if labels is not None else [
        int(v) if float(v).is_integer() else v for v in present]
    X = mm.X[:, 1:]
    n, p = X.shape
    rank = np.linalg.matrix_rank(mm.X)
    if rank < p + 1:
        raise FormulaError(f"{source}: the fixed effects of '{f.text}' cannot be identified (the design matrix has "
                           f"rank {rank} < {p + 1} columns with the thresholds: empty cells or a term that repeats "
                           "another)")
    for blk in mm.blocks:
        if blk.n_levels < 3:
            raise FormulaError(f"{source}: the grouping factor {blk.group} has {blk.n_levels} levels: clmm needs at "
                               "least 3 for a random intercept")
    q = sum(b.n_levels for b in mm.blocks)
    if q - max(b.n_levels for b in mm.blocks) > MAX_RANDOM_EFFECTS:
        raise FormulaError(f"{source}: {q - max(b.n_levels for b in mm.blocks)} levels in the random terms besides the "
                           f"largest; the dense fit takes at most {MAX_RANDOM_EFFECTS}")
    if q >= n:
        raise FormulaError(f"{source}: {q} random effects for {n} observations: the model cannot be identified")
    names = [f"{_label(a)}|{_label(b)}" for a, b in zip(cats[:-1], cats[1:])]
    prob = LaplaceProblem(yc, X, [b.codes for b in mm.blocks], [b.n_levels for b in mm.blocks], link, len(present))
    return prob, cats, names


def _finish(prob: LaplaceProblem, res: OptimResult, mm: ModelMatrices, link: str, cats: list, names: list[str],
            columns: list[str], term_columns: dict[str, list[int]]) -> ClmmFit:
    nt, p, K = prob.nt, prob.p, prob.K
    phi, free, H = res.phi, res.free, res.hessian
    theta, beta, tau = phi[:nt], phi[nt: nt + p], phi[nt + p:]
    msgs = []
    try:
        cH = linalg.cholesky(H, lower=False, check_finite=False)
        inv = linalg.cho_solve((cH, False), np.eye(len(H)), check_finite=False)
        vcov = inv[: nt + p, : nt + p]
    except linalg.LinAlgError:
        vcov = np.full((nt + p, nt + p), np.nan)
        msgs.append("Variance-covariance matrix of the parameters is not defined "
                    "(the Hessian is not positive definite)")
    # clmm's parametrisation: the SDs themselves with two or more random terms, log τ with one
    g_free = res.grad[free]
    Hc = H.copy()
    if K == 1 and free[-1]:
        j = len(H) - 1
        Hc[j, :] *= tau[0]
        Hc[:, j] *= tau[0]
        Hc[j, j] += res.grad[-1] * tau[0]
        g_free = g_free.copy()
        g_free[-1] *= tau[0]
    ev = np.linalg.eigvalsh(Hc)
    cond = float(abs(ev[-1] / ev[0])) if ev[0] != 0 else np.inf
    max_grad = float(np.max(np.abs(g_free))) if len(g_free) else 0.0
    if not res.converged:
        msgs.append(f"Model may not have converged: max|grad| = {max_grad:.2g} ({res.message})")
    if np.any(tau < BOUNDARY):
        msgs.append("boundary fit: a random-effect SD is 0 (left out of the Hessian, as clmm)")
    s = res.state
    u = np.concatenate(prob.user_terms(s.u))
    lam = np.repeat(tau, [b.n_levels for b in mm.blocks])
    cond_var = np.concatenate(prob.user_terms(s.H.diagonal_of_inverse())) * lam ** 2
    return ClmmFit(mm.formula, link, cats, names, columns, theta.copy(), beta.copy(), tau.copy(),
                   [b.group for b in mm.blocks], [list(map(str, b.levels)) for b in mm.blocks], -res.nll, prob.n,
                   vcov, H, free, res.grad, max_grad, cond, res.converged, res.message, res.n_evals, res.n_iter,
                   u, cond_var, prob.y, mm, term_columns, msgs)


def fit_clmm(formula: str | Formula, data: pd.DataFrame, *, link: str = "logit", factors: Iterable[str] = (),
             levels: Mapping[str, Sequence] | None = None, source: str = "data", start: np.ndarray | None = None,
             gtol: float = 1e-8, max_iter: int = 1000) -> ClmmFit:
    """Fit a cumulative-link mixed model by the Laplace approximation, as ``ordinal::clmm``.

    ``clmm(rating ~ shape * material + (1 | participant) + (1 | stimulus), data, link = link)``
    with ``options(contrasts = c("contr.sum", "contr.poly"))`` and the response an ordered
    factor; the default flexible thresholds and ``nAGQ = 1``.

    Parameters
    ----------
    formula : str or Formula
        An lme4-style formula with random intercepts only: ``(1 | g)``, crossed ``(1 | g) + (1 | h)``
        or nested ``(1 | g/h)``.
    data : DataFrame
        One row per rating. The response holds ordered categories: integers (a 1..7 Likert item)
        or an ordered ``pandas.Categorical``; its categories are ordered by value (or by
        ``levels[response]``), and those never used are dropped, as clmm does.
    link : {"logit", "probit"}
        The cumulative distribution function F.
    factors : iterable of str
        Numeric columns to treat as factors (see :func:`~analysis.stats.formula.model_matrices`).
    levels : mapping, optional
        Level order per factor (names the coefficients), and optionally of the response.
    source : str
        Named in error messages.
    start : ndarray, optional
        Starting (θ, β, τ) (default: thresholds from the marginal proportions, β = 0, τ = 1).
    gtol : float
        Convergence tolerance on max|gradient| of −logLik (θ, β, τ scale).
    max_iter : int
        Most L-BFGS-B iterations before the Newton steps.

    Returns
    -------
    ClmmFit

    Raises
    ------
    FormulaError
        One line: random slopes, a response that is not ordinal or has one category, a
        grouping factor with fewer than 3 levels, an unidentifiable fixed-effects design, no
        random term, an unknown link.
    """
    if link not in LINKS:
        raise FormulaError(f"{source}: link '{link}' is not one of {', '.join(LINKS)}")
    f = parse_formula(formula) if isinstance(formula, str) else formula
    data, labels = _response(data, f.response, source)
    lv = dict(levels or {})
    response_order = lv.pop(f.response, None)
    if labels is not None:
        response_order = None
    mm = model_matrices(f, data, factors, lv, source)
    prob, cats, names = _build(mm, link, source, labels, response_order)
    with blas_threads(prob.m):
        res = optimise(prob, start, gtol, max_iter)
        term_cols = {t: [c - 1 for c in cols] for t, cols in mm.term_columns.items()}
        return _finish(prob, res, mm, link, cats, names, mm.columns[1:], term_cols)


def _refit(fit: ClmmFit, keep: np.ndarray, gtol: float = 1e-8) -> tuple[float, LaplaceProblem]:
    """−logLik of the model with only the fixed-effect columns ``keep`` (started at the full fit)."""
    mm = fit.mm
    X = mm.X[:, 1:][:, keep]
    prob = LaplaceProblem(fit.y_codes, X, [b.codes for b in mm.blocks], [b.n_levels for b in mm.blocks], fit.link,
                    len(fit.categories))
    start = np.concatenate([fit.theta, fit.beta[keep], np.maximum(fit.tau, 0.05)])
    with blas_threads(prob.m):
        res = optimise(prob, start, gtol, 1000, polish=False)
    return res.nll, prob


def likelihood_ratio_tests(fit: ClmmFit) -> pd.DataFrame:
    """Likelihood-ratio test of each fixed term: refit without the term's columns.

    With sum-to-zero coding, leaving out a term's columns (and keeping every other column,
    interactions included) tests the term's type-III (marginal) hypothesis. For the
    highest-order terms this is exactly ``drop1(clmm_fit, test = "Chisq")`` in R; ``drop1``
    respects marginality and does not test a main effect that is part of an interaction (its
    formula update would re-code the interaction), which these refits do.

    Returns
    -------
    DataFrame
        ``term``, ``df`` (columns left out), ``loglik`` and ``aic`` of the reduced model, ``lr_chisq``
        (2 × the log-likelihood difference) and ``p`` (χ² upper tail) — drop1's Df, AIC, LRT, Pr(>Chi).
    """
    rows = []
    for term, cols in fit.term_columns.items():
        keep = np.setdiff1d(np.arange(len(fit.columns)), cols)
        nll, _ = _refit(fit, keep)
        lr = max(2 * (fit.loglik + nll), 0.0)
        df = len(cols)
        rows.append({"term": term, "df": df, "loglik": -nll, "aic": 2 * nll + 2 * (fit.n_params - df),
                     "lr_chisq": lr, "p": float(stats.chi2.sf(lr, df))})
    return pd.DataFrame(rows)


# ---------------------------------------------------------------------------------------- figure
