"""Linear mixed models fitted as lme4 does (Bates et al. 2015, *J. Stat. Softw.* 67(1)).

The model ``y = Xβ + Zb + ε``, ``b = Λ_θ u``, ``u ~ N(0, σ²I)``, ``ε ~ N(0, σ²I)``: for a value of
the relative covariance parameters θ (the lower triangles of each random term's Cholesky factor,
column by column, as lme4's ``getME(m, "theta")``) the penalised least-squares system

    M(θ) = [Λ'Z'ZΛ + I   Λ'Z'X]
           [X'ZΛ         X'X  ]

is solved once by a dense Cholesky factorisation; the cross products Z'Z, Z'X, X'X, Z'y, X'y and
y'y are computed once, so the cost of a deviance does not grow with the number of rows. The
profiled REML (or ML) deviance is minimised over θ with its exact gradient (L-BFGS-B, then Newton
steps); θ is unbounded — only ΛΛ' enters the model, and negating a column of a factor does not
change it — and each factor's diagonal is made positive afterwards (lme4 bounds it at 0, where a
gradient method that lands stays: the deviance is even in it). σ² and β follow in closed form.

Why our own: statsmodels' MixedLM fits crossed effects only as variance components of one
group (no correlated slopes), with z-tests, and did not converge on 40 × 250 crossed designs; the
Rust ``mixedlm`` package fits the same models but its Satterthwaite differentiates over θ only
(lmerTest over θ and σ), and the inference here (:mod:`analysis.stats.satterthwaite`,
:mod:`analysis.stats.kenward_roger`) needs the deviance as a function of (θ, σ) — which this
module gives (:meth:`LmmFit.deviance_vp`, :meth:`LmmFit.vcov_vp`). Dense factorisations suit
designs with up to a few thousand random effects (40 participants × 3 slopes + 250 stimuli is
370); more raise a one-line error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import linalg, optimize

from analysis.stats.formula import Formula, FormulaError, ModelMatrices, model_matrices

__all__ = ["LmmFit", "fit_lmm", "lmm_problem", "LmmProblem", "MAX_RANDOM_EFFECTS", "blas_threads", "confounded_blocks"]

#: Most random effects (columns of Z) the dense factorisation takes.
MAX_RANDOM_EFFECTS = 6000


def blas_threads(size: int):
    """One BLAS thread for factorisations below ~2000 rows: their threads cost more than they
    give (a 373 × 373 Cholesky: 2 ms on one thread, 20-140 ms on two when the cores are busy)."""
    from contextlib import nullcontext

    from threadpoolctl import threadpool_limits

    return threadpool_limits(1) if size < 2000 else nullcontext()


@dataclass
class LmmProblem:
    """The cross products of one model and the map from θ to Λ (computed once)."""

    mm: ModelMatrices
    ZtZ: np.ndarray
    ZtX: np.ndarray
    Zty: np.ndarray
    XtX: np.ndarray
    Xty: np.ndarray
    yty: float
    offsets: list[int]
    theta_slices: list[slice]
    lower: np.ndarray
    theta_names: list[tuple[str, str, str]]

    @property
    def n(self) -> int:
        return self.mm.n

    @property
    def p(self) -> int:
        return self.XtX.shape[0]

    @property
    def q(self) -> int:
        return self.ZtZ.shape[0]

    def factors(self, theta: np.ndarray) -> list[np.ndarray]:
        """Each random term's k × k lower-triangular factor T (Λ = ⊕ I_L ⊗ T)."""
        out = []
        for blk, sl in zip(self.mm.blocks, self.theta_slices):
            T = np.zeros((blk.k, blk.k))
            rows, cols = _tril_colmajor(blk.k)
            T[rows, cols] = theta[sl]
            out.append(T)
        return out

    def times_lambda(self, M: np.ndarray, theta: np.ndarray, Ts: list[np.ndarray] | None = None) -> np.ndarray:
        """``M @ Λ`` for ``M`` with q columns (block by block, no q × q Λ formed)."""
        Ts = self.factors(theta) if Ts is None else Ts
        out = np.empty_like(M)
        for blk, off, T in zip(self.mm.blocks, self.offsets, Ts):
            sl = slice(off, off + blk.n_levels * blk.k)
            if blk.k == 1:  # a scalar factor: one multiplication, no small matrix products
                np.multiply(M[:, sl], T[0, 0], out=out[:, sl])
            else:  # one (rows x levels, k) @ (k, k) product rather than a stack of small ones
                out[:, sl] = (M[:, sl].reshape(-1, blk.k) @ T).reshape(M.shape[0], -1)
        return out

    def lambda_times(self, v: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """``Λ v`` for a vector of length q (the random effects b = Λu)."""
        out = np.empty_like(v)
        for blk, off, T in zip(self.mm.blocks, self.offsets, self.factors(theta)):
            sl = slice(off, off + blk.n_levels * blk.k)
            out[sl] = (v[sl].reshape(blk.n_levels, blk.k) @ T.T).ravel()
        return out

    def lambda_times_matrix(self, M: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """``Λ M`` for ``M`` with q rows (``lambda_times`` of each column)."""
        out = np.empty_like(M)
        for blk, off, T in zip(self.mm.blocks, self.offsets, self.factors(theta)):
            sl = slice(off, off + blk.n_levels * blk.k)
            out[sl] = np.einsum("ij,ljm->lim", T, M[sl].reshape(blk.n_levels, blk.k, -1)).reshape(-1, M.shape[1])
        return out

    def system(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
        """``M(θ)`` and its right-hand side ``[Λ'Z'y; X'y]``."""
        Ts = self.factors(theta)
        ZtZL = self.times_lambda(self.ZtZ, theta, Ts)
        LZtZL = self.times_lambda(ZtZL.T.copy(), theta, Ts)  # Λ'Z'ZΛ (symmetric)
        LZtX = self.times_lambda(self.ZtX.T.copy(), theta, Ts).T
        LZty = self.times_lambda(self.Zty[None, :], theta, Ts)[0]
        q, p = self.q, self.p
        M = np.empty((q + p, q + p))
        M[:q, :q] = LZtZL
        M[np.arange(q), np.arange(q)] += 1.0
        M[:q, q:] = LZtX
        M[q:, :q] = LZtX.T
        M[q:, q:] = self.XtX
        return M, np.concatenate([LZty, self.Xty]), Ts


def _tril_colmajor(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of a k × k lower triangle, column by column (lme4's θ order)."""
    rows, cols = [], []
    for j in range(k):
        for i in range(j, k):
            rows.append(i)
            cols.append(j)
    return np.array(rows, int), np.array(cols, int)


def lmm_problem(mm: ModelMatrices) -> LmmProblem:
    """Precompute the cross products of a model (the only pass over the rows)."""
    from scipy import sparse

    n = mm.n
    offsets, off = [], 0
    for blk in mm.blocks:
        offsets.append(off)
        off += blk.n_levels * blk.k
    if off > MAX_RANDOM_EFFECTS:
        raise FormulaError(f"{mm.formula.text}: {off} random effects; the dense fit takes at most {MAX_RANDOM_EFFECTS}")
    rows, cidx, vals = [], [], []
    for blk, o in zip(mm.blocks, offsets):
        rows.append(np.repeat(np.arange(n), blk.k))
        cidx.append((blk.codes[:, None] * blk.k + np.arange(blk.k)[None, :] + o).ravel())
        vals.append(blk.Xr.ravel())
    Z = sparse.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cidx))), shape=(n, off))
    X, y = mm.X, mm.y
    slices, lower, names, t0 = [], [], [], 0
    for blk in mm.blocks:
        r, c = _tril_colmajor(blk.k)
        slices.append(slice(t0, t0 + len(r)))
        lower += [0.0 if i == j else -np.inf for i, j in zip(r, c)]
        names += [(blk.group, blk.columns[i], blk.columns[j]) for i, j in zip(r, c)]
        t0 += len(r)
    ZtZ = (Z.T @ Z).toarray()
    return LmmProblem(mm, ZtZ, np.asarray(Z.T @ X), np.asarray(Z.T @ y).ravel(), X.T @ X, X.T @ y, float(y @ y),
                      offsets, slices, np.array(lower), names)


def confounded_blocks(prob: LmmProblem, tol: float = 1e-9) -> list:
    """Random terms whose columns lie in the span of X (e.g. one stimulus per cell of a full
    factorial): the REML criterion does not depend on their variances."""
    out = []
    XtX_inv_XtZ = np.linalg.lstsq(prob.XtX, prob.ZtX.T, rcond=None)[0]
    for blk, off in zip(prob.mm.blocks, prob.offsets):
        sl = slice(off, off + blk.n_levels * blk.k)
        S = prob.ZtZ[sl, sl] - prob.ZtX[sl] @ XtX_inv_XtZ[:, sl]
        if np.max(np.abs(S)) <= tol * max(np.max(np.abs(prob.ZtZ[sl, sl])), 1e-300):
            out.append(blk)
    return out


@dataclass
class _Solution:
    logdet_M: float
    logdet_A: float
    prss: float
    u: np.ndarray
    beta: np.ndarray
    chol: np.ndarray


def _solve(prob: LmmProblem, theta: np.ndarray) -> _Solution:
    M, rhs, _ = prob.system(theta)
    L = linalg.cholesky(M, lower=True, check_finite=False)
    sol = linalg.cho_solve((L, True), rhs, check_finite=False)
    d = np.log(np.diag(L))
    prss = prob.yty - float(rhs @ sol)
    return _Solution(2 * d.sum(), 2 * d[: prob.q].sum(), max(prss, 1e-300), sol[: prob.q], sol[prob.q:], L)


def _deviance(prob: LmmProblem, s: _Solution, reml: bool) -> float:
    n, p = prob.n, prob.p
    if reml:
        return s.logdet_M + (n - p) * (1 + math.log(2 * math.pi * s.prss / (n - p)))
    return s.logdet_A + n * (1 + math.log(2 * math.pi * s.prss / n))


def _lambda_pattern(prob: LmmProblem) -> list[tuple[np.ndarray, np.ndarray]]:
    """For each θ_k, the (row, column) positions of Λ it fills."""
    out = []
    for blk, off, sl in zip(prob.mm.blocks, prob.offsets, prob.theta_slices):
        r, c = _tril_colmajor(blk.k)
        base = off + np.arange(blk.n_levels) * blk.k
        for i, j in zip(r, c):
            out.append((base + i, base + j))
    return out


def _cholesky_inverse(chol: np.ndarray) -> np.ndarray:
    """The symmetric inverse of ``chol @ chol.T`` from its lower Cholesky factor (LAPACK potri:
    a third of the work of solving for as many right-hand sides as it has rows)."""
    inv, info = linalg.lapack.dpotri(chol, lower=1)
    if info != 0:
        raise linalg.LinAlgError(f"potri failed ({info})")
    return np.tril(inv) + np.tril(inv, -1).T


def _gradient_parts(prob: LmmProblem, theta: np.ndarray, s: _Solution, reml: bool) -> tuple[np.ndarray, np.ndarray]:
    """d(log det M or log det A)/dθ and d(prss)/dθ.

    With ``G = [Λ'Z'Z; X'Z]``, ``d log det M / dθ_k = 2 Σ (M⁻¹[:q] G)[c, r]`` over Λ's entries
    ``(r, c)`` that θ_k fills (REML; ML: ``A = M[:q, :q]`` and ``Λ'Z'Z``): only those entries of the
    product are formed, from ``M⁻¹`` (:func:`_cholesky_inverse`), not the whole q × q product.
    """
    q = prob.q
    ZtZL = prob.times_lambda(prob.ZtZ, theta)  # G' = [Z'ZΛ, Z'X]: its rows are G's columns
    W = _cholesky_inverse(s.chol if reml else np.ascontiguousarray(s.chol[:q, :q]))
    b = prob.lambda_times(s.u, theta)
    rZ = prob.Zty - prob.ZtZ @ b - prob.ZtX @ s.beta
    dld, dprss = [], []
    for rows, cols in _lambda_pattern(prob):
        Wc = W[cols]
        tr = np.einsum("lm,lm->", Wc[:, :q], ZtZL[rows])
        if reml:
            tr += np.einsum("lm,lm->", Wc[:, q:], prob.ZtX[rows])
        dld.append(2 * float(tr))
        dprss.append(-2 * float(rZ[rows] @ s.u[cols]))
    return np.array(dld), np.array(dprss)


def _objective(prob: LmmProblem, reml: bool):
    n_eff = prob.n - prob.p if reml else prob.n

    def f(theta):
        try:
            s = _solve(prob, theta)
        except linalg.LinAlgError:
            return np.inf, np.zeros_like(theta)
        dld, dprss = _gradient_parts(prob, theta, s, reml)
        return _deviance(prob, s, reml), dld + n_eff * dprss / s.prss
    return f


@dataclass
class LmmFit:
    """A fitted linear mixed model (what ``lme4::lmer`` returns, in lme4's terms)."""

    problem: LmmProblem
    reml: bool
    theta: np.ndarray
    beta: np.ndarray
    sigma: float
    deviance: float
    vcov: np.ndarray
    grad: np.ndarray
    n_evals: int
    converged: bool
    message: str
    singular: bool
    warnings: list[str] = field(default_factory=list)

    @property
    def mm(self) -> ModelMatrices:
        return self.problem.mm

    @property
    def formula(self) -> Formula:
        return self.mm.formula

    @property
    def n(self) -> int:
        return self.problem.n

    @property
    def loglik(self) -> float:
        """REML criterion / −2 (REML) or the log-likelihood (ML)."""
        return -self.deviance / 2

    @property
    def n_params(self) -> int:
        return len(self.theta) + self.problem.p + 1

    @property
    def aic(self) -> float:
        return self.deviance + 2 * self.n_params

    @property
    def bic(self) -> float:
        return self.deviance + math.log(self.n) * self.n_params

    def coefficients(self) -> pd.DataFrame:
        """Fixed effects: estimate and standard error (z-free; tests add the dfs)."""
        se = np.sqrt(np.diag(self.vcov))
        return pd.DataFrame({"term": self.mm.columns, "estimate": self.beta, "se": se})

    def random_covariances(self) -> list[np.ndarray]:
        """Each random term's covariance matrix σ² T T'."""
        return [self.sigma ** 2 * T @ T.T for T in self.problem.factors(self.theta)]

    def variance_components(self) -> pd.DataFrame:
        """lme4's ``VarCorr``: one row per variance and per correlation, and the residual."""
        rows = []
        for blk, C in zip(self.mm.blocks, self.random_covariances()):
            sd = np.sqrt(np.diag(C))
            for i, name in enumerate(blk.columns):
                rows.append({"group": blk.group, "term": name, "term2": "", "variance": C[i, i], "sd": sd[i], "corr": np.nan})
            for j in range(blk.k):
                for i in range(j + 1, blk.k):
                    corr = C[i, j] / (sd[i] * sd[j]) if sd[i] > 0 and sd[j] > 0 else np.nan
                    rows.append({"group": blk.group, "term": blk.columns[i], "term2": blk.columns[j],
                                 "variance": np.nan, "sd": np.nan, "corr": corr})
        rows.append({"group": "Residual", "term": "", "term2": "", "variance": self.sigma ** 2, "sd": self.sigma, "corr": np.nan})
        return pd.DataFrame(rows)

    def random_effects(self) -> dict[str, pd.DataFrame]:
        """Conditional modes of the random effects (``ranef``), one table per term."""
        s = _solve(self.problem, self.theta)
        b = self.problem.lambda_times(s.u, self.theta)
        out = {}
        for blk, off in zip(self.mm.blocks, self.problem.offsets):
            vals = b[off: off + blk.n_levels * blk.k].reshape(blk.n_levels, blk.k)
            out[blk.name] = pd.DataFrame(vals, index=pd.Index(blk.levels, name=blk.group), columns=blk.columns)
        return out

    # -- the deviance as a function of (θ, σ), for Satterthwaite and Kenward–Roger --------------
    def deviance_vp(self, varpar: np.ndarray) -> float:
        """lmerTest's ``devfun_vp``: the (REML) deviance at θ = varpar[:-1], σ = varpar[-1]."""
        theta, sigma = np.asarray(varpar[:-1], float), float(varpar[-1])
        s = _solve(self.problem, theta)
        n, p, s2 = self.problem.n, self.problem.p, sigma ** 2
        if self.reml:
            return s.logdet_M + s.prss / s2 + (n - p) * math.log(2 * math.pi * s2)
        return s.logdet_A + s.prss / s2 + n * math.log(2 * math.pi * s2)

    def deviance_vp_grad(self, varpar: np.ndarray) -> np.ndarray:
        """The exact gradient of :meth:`deviance_vp`."""
        theta, sigma = np.asarray(varpar[:-1], float), float(varpar[-1])
        s = _solve(self.problem, theta)
        dld, dprss = _gradient_parts(self.problem, theta, s, self.reml)
        n_eff = self.problem.n - (self.problem.p if self.reml else 0)
        return np.concatenate([dld + dprss / sigma ** 2, [-2 * s.prss / sigma ** 3 + 2 * n_eff / sigma]])

    def vcov_vp(self, varpar: np.ndarray) -> np.ndarray:
        """The covariance of β̂ at θ = varpar[:-1], σ = varpar[-1] (lmerTest's ``get_covbeta``)."""
        s = _solve(self.problem, np.asarray(varpar[:-1], float))
        return float(varpar[-1]) ** 2 * _schur_inverse(s.chol, self.problem.q)

    def vcov_vp_jacobian(self, varpar: np.ndarray) -> np.ndarray:
        """The exact Jacobian of :meth:`vcov_vp`, p × p × len(varpar) (lmerTest differentiates
        ``get_covbeta`` numerically; this is its closed form).

        ``Cov(β̂) = σ² S⁻¹`` with ``S = X'X − P'A⁻¹P``, ``P = Λ'Z'X``, ``A = Λ'Z'ZΛ + I``; with
        ``E_k = ∂Λ/∂θ_k``, ``B = A⁻¹P`` and ``R = Z'X − Z'ZΛB``:
        ``∂S/∂θ_k = −(R'E_kB + B'E_k'R)``, so ``∂Cov/∂θ_k = σ² S⁻¹ (R'E_kB + B'E_k'R) S⁻¹`` and
        ``∂Cov/∂σ = 2σ S⁻¹``.
        """
        prob = self.problem
        theta, sigma = np.asarray(varpar[:-1], float), float(varpar[-1])
        s = _solve(prob, theta)
        q = prob.q
        Sinv = _schur_inverse(s.chol, q)
        P = prob.times_lambda(prob.ZtX.T.copy(), theta).T  # Λ'Z'X
        B = linalg.cho_solve((np.ascontiguousarray(s.chol[:q, :q]), True), P, check_finite=False)
        R = prob.ZtX - prob.ZtZ @ prob.lambda_times_matrix(B, theta)
        out = np.empty(Sinv.shape + (len(varpar),))
        for k, (rows, cols) in enumerate(_lambda_pattern(prob)):
            REB = R[rows].T @ B[cols]
            out[..., k] = sigma ** 2 * Sinv @ (REB + REB.T) @ Sinv
        out[..., -1] = 2 * sigma * Sinv
        return out

    @property
    def varpar(self) -> np.ndarray:
        return np.concatenate([self.theta, [self.sigma]])


def _schur_inverse(chol: np.ndarray, q: int) -> np.ndarray:
    """(X'X − RZX'RZX)⁻¹ from the Cholesky factor of M: the inverse of its trailing block's factor."""
    RX = chol[q:, q:]
    inv = linalg.solve_triangular(RX, np.eye(len(RX)), lower=True, check_finite=False)
    return inv.T @ inv


def fit_lmm(formula: str | Formula | ModelMatrices, data: pd.DataFrame | None = None, *, reml: bool = True,
            factors=(), levels=None, source: str = "data", start: np.ndarray | None = None,
            tol: float = 1e-7, max_iter: int = 2000) -> LmmFit:
    """Fit a linear mixed model by (RE)ML, as ``lme4::lmer(formula, data, REML = reml)``.

    Parameters
    ----------
    formula : str, Formula or ModelMatrices
        An lme4 formula (``rating ~ shape * material + (1 + shape | participant) + (1 | stimulus)``),
        or matrices already built by :func:`analysis.stats.formula.model_matrices`.
    data : DataFrame
        The observations (not needed with ``ModelMatrices``).
    reml : bool
        REML (default, as lmer) or maximum likelihood (for likelihood-ratio tests).
    factors, levels, source
        Passed to :func:`~analysis.stats.formula.model_matrices`.
    start : ndarray, optional
        Starting θ (default: identity factors, as lme4).
    tol : float
        Projected-gradient tolerance of the optimiser.
    max_iter : int
        Most optimiser iterations.

    Returns
    -------
    LmmFit
        With ``converged``, ``singular`` and lme4-style ``warnings``.

    Raises
    ------
    FormulaError
        A formula the data cannot support (one-line message).
    """
    mm = formula if isinstance(formula, ModelMatrices) else model_matrices(formula, data, factors, levels, source)
    if not mm.blocks:
        raise FormulaError(f"{source}: '{mm.formula.text}' has no random term (write one as (1 | group))")
    n, p = mm.X.shape
    if np.linalg.matrix_rank(mm.X) < p:
        raise FormulaError(f"{source}: the fixed effects of '{mm.formula.text}' cannot be identified (the design "
                           f"matrix has rank {np.linalg.matrix_rank(mm.X)} < {p} columns: empty cells or a term that "
                           "repeats another)")
    if n <= p:
        raise FormulaError(f"{source}: {n} observations for {p} fixed effects: the model cannot be identified")
    for blk in mm.blocks:
        if blk.n_levels * blk.k >= n:
            raise FormulaError(f"{source}: {blk.name}: {blk.n_levels * blk.k} random effects for {n} observations: "
                               "the random effects and the residual cannot be told apart")
    prob = lmm_problem(mm)
    for blk in confounded_blocks(prob):
        raise FormulaError(f"{source}: the random effect {blk.name} cannot be identified: every {blk.group} lies "
                           "within one cell of the fixed effects, so its variance is theirs (leave the term out, or "
                           "model fewer fixed terms)")
    lower = prob.lower
    theta0 = np.where(lower == 0, 1.0, 0.0) if start is None else np.asarray(start, float)
    # no bounds: Λ enters only through ΛΛ', which a column's sign does not change, so the diagonal
    # is left free and made positive afterwards (bounded gradient steps stall where they hit 0)
    bounds = None
    f = _objective(prob, reml)
    with blas_threads(prob.q + prob.p):
        # a relative change of 1e-12, then the Newton polish: at 1e-15 the line search ended in rounding
        # ("ABNORMAL") after twice the evaluations, at the same optimum
        options = {"maxiter": max_iter, "ftol": 1e-12, "gtol": tol, "maxcor": 30}
        res = optimize.minimize(f, theta0, jac=True, method="L-BFGS-B", bounds=bounds, options=options)
        for _ in range(5):  # a diagonal θ at 0 is a stationary point: probe off the bound, restart if better
            better = _off_bound(f, res.x, res.fun, lower)
            if better is None:
                break
            nfev = res.nfev
            res = optimize.minimize(f, better, jac=True, method="L-BFGS-B", bounds=bounds, options=options)
            res.nfev += nfev
        theta = _positive_diagonal(prob, res.x)
        # polish: a few Newton steps on the free parameters (exact gradient, Hessian by differences)
        theta, grad = _polish(f, theta, lower)
        s = _solve(prob, theta)
    dev = _deviance(prob, s, reml)
    sigma = math.sqrt(s.prss / (n - p if reml else n))
    vcov = sigma ** 2 * _schur_inverse(s.chol, prob.q)
    free = ~((lower == 0) & (theta <= 1e-8))
    max_grad = float(np.max(np.abs(grad[free]))) if free.any() else 0.0
    singular = bool(np.any(theta[lower == 0] < 1e-4))
    msgs = []
    converged = bool(res.success or max_grad < 1e-3)
    if not converged:
        msgs.append(f"Model failed to converge: max|grad| = {max_grad:.3g} ({res.message})")
    if singular:
        msgs.append("boundary (singular) fit: see help('isSingular')")
    return LmmFit(prob, reml, theta, s.beta, sigma, dev, vcov, grad, int(res.nfev), converged,
                  str(res.message), singular, msgs)


def _positive_diagonal(prob: LmmProblem, theta: np.ndarray) -> np.ndarray:
    """The same ΛΛ' with every factor's diagonal ≥ 0 (columns with a negative diagonal negated)."""
    out = theta.copy()
    for blk, sl, T in zip(prob.mm.blocks, prob.theta_slices, prob.factors(theta)):
        T = T * np.where(np.diag(T) < 0, -1.0, 1.0)[None, :]
        out[sl] = T[_tril_colmajor(blk.k)]
    return out


def _off_bound(f, theta: np.ndarray, dev: float, lower: np.ndarray) -> np.ndarray | None:
    """θ with one bounded parameter moved off 0 when that lowers the deviance, else None.

    The deviance is even in a factor's diagonal element when the rest of its column is 0, so
    θ_ii = 0 has a zero gradient whatever the data: a gradient method that lands there stays.
    lme4's derivative-free BOBYQA does not see this; probing each bounded parameter does.
    """
    best, best_dev = None, dev - 1e-10 * max(1.0, abs(dev))
    for i in np.flatnonzero((lower == 0) & (np.abs(theta) <= 1e-8)):
        for value in (0.003, 0.03, 0.1, 0.5, 1.0):
            trial = theta.copy()
            trial[i] = value
            d = f(trial)[0]
            if d < best_dev:
                best, best_dev = trial, d
    return best


def _polish(f, theta: np.ndarray, lower: np.ndarray, steps: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Newton steps on the parameters off their bounds (tightens θ to ~1e-9 after L-BFGS-B)."""
    dev, grad = f(theta)
    for _ in range(steps):
        free = ~((lower == 0) & (theta <= 1e-8))
        if not free.any() or np.max(np.abs(grad[free])) < 1e-9:
            break
        idx = np.flatnonzero(free)
        h = 1e-5 * np.maximum(1.0, np.abs(theta[idx]))
        H = np.empty((len(idx), len(idx)))
        for a, (i, hi) in enumerate(zip(idx, h)):
            tp, tm = theta.copy(), theta.copy()
            tp[i] += hi
            tm[i] -= hi
            H[:, a] = (f(tp)[1][idx] - f(tm)[1][idx]) / (2 * hi)
        H = (H + H.T) / 2
        try:
            step = np.linalg.solve(H, grad[idx])
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(step)) or np.min(np.linalg.eigvalsh(H)) <= 0:
            break
        new = theta.copy()
        new[idx] -= step
        new = np.maximum(new, lower)
        ndev, ngrad = f(new)
        if not np.isfinite(ndev) or ndev > dev + 1e-10:
            break
        theta, dev, grad = new, ndev, ngrad
    return theta, grad
