"""The numerics of :mod:`analysis.stats.clmm`: link functions and their derivatives, the
Laplace-approximated negative log-likelihood of a cumulative-link mixed model with random
intercepts, its exact gradient, the conditional modes (Newton on the q × q Hessian, factorised
through the largest random term) and the outer optimiser. The model and the parametrisation are
described in :mod:`analysis.stats.clmm`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import linalg, optimize, special

from analysis.stats.formula import FormulaError

__all__ = ["LaplaceProblem", "OptimResult", "ModeState", "optimise", "cdf", "pdf_derivs", "category_probabilities", "BOUNDARY"]

_BIG = 1e5
#: SDs below this are on the boundary: left out of the Hessian, as ``clmm`` (``paratBoundary2``).
BOUNDARY = 1e-3
_SQRT2PI = math.sqrt(2 * math.pi)


# ---------------------------------------------------------------------------------------- links
def cdf(x: np.ndarray, link: str) -> np.ndarray:
    return special.expit(x) if link == "logit" else special.ndtr(x)


def pdf_derivs(x: np.ndarray, link: str, order: int) -> tuple[np.ndarray, ...]:
    """The density f and its derivatives f', f'' (up to ``order``) at x."""
    if link == "logit":
        F, S = special.expit(x), special.expit(-x)
        f = F * S
        out = [f, f * (S - F)]
        if order >= 2:
            out.append(f * (1 - 6 * f))
    else:
        f = np.exp(-0.5 * x * x) / _SQRT2PI
        out = [f, -x * f]
        if order >= 2:
            out.append((x * x - 1) * f)
    return tuple(out[: order + 1])


def _link_terms(x: np.ndarray, link: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """F(x), 1 − F(x) (accurate in the upper tail), the density f and its derivative f'."""
    if link == "logit":
        e = np.exp(-np.abs(x))
        r = 1.0 / (1.0 + e)
        er = e * r
        pos = x >= 0
        F = np.where(pos, r, er)
        S = np.where(pos, er, r)
        f = er * r
        return F, S, f, f * (S - F)
    f = np.exp(-0.5 * x * x) / _SQRT2PI
    return special.ndtr(x), special.ndtr(-x), f, -x * f


def _second(x: np.ndarray, f: np.ndarray, link: str) -> np.ndarray:
    """f''(x) from f(x)."""
    return f * (1 - 6 * f) if link == "logit" else (x * x - 1) * f


def category_probabilities(eta1: np.ndarray, eta2: np.ndarray, link: str) -> np.ndarray:
    """F(η1) − F(η2), from the upper tails where both are positive (``ordinal``'s get_fitted)."""
    upper = eta2 > 0
    p = cdf(eta1, link) - cdf(eta2, link)
    if upper.any():
        p[upper] = cdf(-eta2[upper], link) - cdf(-eta1[upper], link)
    return p


# -------------------------------------------------------------------------------------- problem
@dataclass
class _Rows:
    """Each row's probability and the link's terms at η1 and η2."""

    eta1: np.ndarray
    eta2: np.ndarray
    p: np.ndarray
    f1: np.ndarray
    f2: np.ndarray
    g1: np.ndarray
    g2: np.ndarray


@dataclass
class _Hessian:
    """H = I + ΛZ'WZΛ in blocks, the levels of the largest random term (D) first:

        H = [diag(d)  B]      factorised through the Schur complement S = M − B'D⁻¹B
            [B'       M]      (m × m, m = the levels of the other terms).
    """

    d: np.ndarray
    B: np.ndarray
    E: np.ndarray          # D⁻¹B
    chol: np.ndarray       # Cholesky factor of S (lower)
    logdet: float

    def solve(self, g: np.ndarray) -> np.ndarray:
        L = len(self.d)
        gD, gR = g[:L], g[L:]
        if not len(gR):
            return gD / self.d
        xR = linalg.cho_solve((self.chol, True), gR - self.E.T @ gD, check_finite=False)
        return np.concatenate([gD / self.d - self.E @ xR, xR])

    def inverse(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """diag(C_DD), C_DR and C_RR of C = H⁻¹ (C_DD is not formed)."""
        m = self.chol.shape[0]
        if not m:
            return 1.0 / self.d, np.zeros((len(self.d), 0)), np.zeros((0, 0))
        Sinv = linalg.cho_solve((self.chol, True), np.eye(m), check_finite=False)
        CDR = -self.E @ Sinv
        return 1.0 / self.d - np.sum(self.E * CDR, axis=1), CDR, Sinv

    def diagonal_of_inverse(self) -> np.ndarray:
        dD, _, Sinv = self.inverse()
        return np.concatenate([dD, np.diag(Sinv)])


@dataclass
class ModeState:
    """What the inner Newton iterations leave at one φ (conditional modes and their Hessian)."""

    phi: np.ndarray
    u: np.ndarray          # internal order (the largest term's levels first)
    nll: float
    rows: _Rows
    d1: np.ndarray
    w: np.ndarray
    A: tuple[np.ndarray, np.ndarray, np.ndarray]
    H: _Hessian
    iterations: int
    converged: bool


class LaplaceProblem:
    """The data of one cumulative-link mixed model and the Laplace objective over φ = (θ, β, τ).

    τ in φ follows the formula's random terms; internally the random effects u are ordered with
    the term of most levels first (its block of H is diagonal: the Schur complement is over the
    others' levels only).
    """

    def __init__(self, y: np.ndarray, X: np.ndarray, codes: Sequence[np.ndarray], n_levels: Sequence[int],
                 link: str, n_cat: int):
        self.y = np.asarray(y, np.int64)
        self.X = np.ascontiguousarray(X, float)
        K = len(n_levels)
        self.order = [int(np.argmax(n_levels))]
        self.order += [k for k in range(K) if k != self.order[0]]
        self.codes = [np.asarray(codes[k], np.int64) for k in self.order]
        self.L = [int(n_levels[k]) for k in self.order]
        self.K = K
        self.offsets = np.concatenate([[0], np.cumsum(self.L)[:-1]]).astype(int)
        self.q = int(sum(self.L))
        self.L0 = self.L[0]
        self.m = self.q - self.L0
        self.roff = [0] + [int(o - self.L0) for o in self.offsets[1:]]   # offsets within R
        self.link = link
        self.J = n_cat
        self.nt = n_cat - 1
        self.p = self.X.shape[1]
        self.n = len(self.y)
        self.n_par = self.nt + self.p + self.K
        self.ucodes = [c + o for c, o in zip(self.codes, self.offsets)]
        self.pairs = [(k, l, self.codes[k] * self.L[l] + self.codes[l]) for k in range(K) for l in range(k + 1, K)]
        self._u = np.zeros(self.q)
        self.n_evals = 0
        self.inner_iterations = 0

    # -- pieces ------------------------------------------------------------------------------
    def split(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """θ, β and τ (internal order)."""
        return phi[: self.nt], phi[self.nt: self.nt + self.p], phi[self.nt + self.p:][self.order]

    def user_terms(self, v: np.ndarray) -> list[np.ndarray]:
        """A q-vector in internal order cut into one piece per random term, in the formula's order."""
        pieces = [v[o: o + L] for o, L in zip(self.offsets, self.L)]
        out = [None] * self.K
        for j, k in enumerate(self.order):
            out[k] = pieces[j]
        return out

    def lam(self, tau: np.ndarray) -> np.ndarray:
        return np.repeat(tau, self.L)

    def zl(self, u: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """b_i = Σ_k τ_k u_k[level of row i]."""
        b = tau[0] * u[self.ucodes[0]]
        for k in range(1, self.K):
            b = b + tau[k] * u[self.ucodes[k]]
        return b

    def zt(self, v: np.ndarray) -> np.ndarray:
        """Z'v (sum of v over the rows of each level), length q."""
        return np.concatenate([np.bincount(c, v, minlength=L) for c, L in zip(self.codes, self.L)])

    def ztwz(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Z'WZ in blocks: the diagonal of the D block, the D × R block and the R × R block."""
        aD = np.bincount(self.codes[0], w, minlength=self.L0)
        ADR = np.zeros((self.L0, self.m))
        ARR = np.zeros((self.m, self.m))
        for k in range(1, self.K):
            r = self.roff[k]
            idx = np.arange(r, r + self.L[k])
            ARR[idx, idx] = np.bincount(self.codes[k], w, minlength=self.L[k])
        for k, l, idx in self.pairs:
            blk = np.bincount(idx, w, minlength=self.L[k] * self.L[l]).reshape(self.L[k], self.L[l])
            rl = self.roff[l]
            if k == 0:
                ADR[:, rl: rl + self.L[l]] = blk
            else:
                rk = self.roff[k]
                ARR[rk: rk + self.L[k], rl: rl + self.L[l]] = blk
                ARR[rl: rl + self.L[l], rk: rk + self.L[k]] = blk.T
        return aD, ADR, ARR

    def hessian_u(self, A: tuple[np.ndarray, np.ndarray, np.ndarray], lam: np.ndarray) -> _Hessian | None:
        aD, ADR, ARR = A
        lD, lR = lam[: self.L0], lam[self.L0:]
        d = 1.0 + lD * lD * aD
        if not self.m:
            return _Hessian(d, ADR, ADR, np.zeros((0, 0)), float(np.sum(np.log(d))))
        B = ADR * lD[:, None] * lR[None, :]
        E = B / d[:, None]
        S = ARR * lR[:, None] * lR[None, :] - B.T @ E
        S[np.arange(self.m), np.arange(self.m)] += 1.0
        try:
            chol = linalg.cholesky(S, lower=True, check_finite=False)
        except linalg.LinAlgError:
            return None
        return _Hessian(d, B, E, chol, float(np.sum(np.log(d)) + 2.0 * np.sum(np.log(np.diag(chol)))))

    def fixed_eta(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta, beta, _ = self.split(phi)
        th = np.concatenate([[-_BIG], theta, [_BIG]])
        xb = self.X @ beta if self.p else np.zeros(self.n)
        return th[self.y + 1] - xb, th[self.y] - xb

    def rows(self, e1: np.ndarray, e2: np.ndarray, b: np.ndarray) -> _Rows:
        eta1, eta2 = e1 - b, e2 - b
        F1, S1, f1, g1 = _link_terms(eta1, self.link)
        F2, S2, f2, g2 = _link_terms(eta2, self.link)
        p = np.where(eta2 > 0, S2 - S1, F1 - F2)
        return _Rows(eta1, eta2, p, f1, f2, g1, g2)

    # -- the conditional modes ---------------------------------------------------------------
    def mode(self, phi: np.ndarray, max_iter: int = 100) -> ModeState | None:
        """Newton iterations for û(φ) to machine precision (from the last û); None where L = 0."""
        _, _, tau = self.split(phi)
        lam = self.lam(tau)
        e1, e2 = self.fixed_eta(phi)
        u = self._u.copy()
        nll = np.inf
        for _ in range(2):
            r = self.rows(e1, e2, self.zl(u, tau))
            if np.all(r.p > 0):
                nll = -np.sum(np.log(r.p)) + 0.5 * u @ u
                if np.isfinite(nll):
                    break
            u = np.zeros(self.q)
        if not np.isfinite(nll):
            return None
        converged, it = False, 0
        for it in range(1, max_iter + 1):
            d1 = (r.f1 - r.f2) / r.p
            w = d1 * d1 - (r.g1 - r.g2) / r.p
            grad = lam * self.zt(d1) + u
            A = self.ztwz(w)
            H = self.hessian_u(A, lam)
            if H is None:
                return None
            step = H.solve(grad)
            size = float(np.max(np.abs(step)))
            if size < 1e-11 or it == max_iter:
                converged = size < 1e-8
                break
            t = 1.0
            for _ in range(40):
                u_new = u - t * step
                r_new = self.rows(e1, e2, self.zl(u_new, tau))
                nll_new = -np.sum(np.log(r_new.p)) + 0.5 * u_new @ u_new if np.all(r_new.p > 0) else np.inf
                # in the quadratic region a Newton step is taken even if rounding hides its decrease
                if nll_new <= nll or (t * size < 1e-7 and np.isfinite(nll_new)):
                    break
                t /= 2
            else:
                converged = size < 1e-6
                break
            u, r, nll = u_new, r_new, nll_new
        self.inner_iterations += it
        self._u = u
        return ModeState(phi.copy(), u, float(nll), r, d1, w, A, H, it, converged)

    # -- the Laplace objective and its gradient --------------------------------------------------
    def objective(self, phi: np.ndarray) -> tuple[float, ModeState | None]:
        self.n_evals += 1
        s = self.mode(phi)
        if s is None:
            return np.inf, None
        return s.nll + 0.5 * s.H.logdet, s

    def gradient(self, s: ModeState) -> np.ndarray:
        """The exact gradient of h(û) + ½ log det H over φ = (θ, β, τ)."""
        _, _, tau = self.split(s.phi)
        lam = self.lam(tau)
        r, d1, w = s.rows, s.d1, s.w
        p = r.p
        h1, h2 = _second(r.eta1, r.f1, self.link), _second(r.eta2, r.f2, self.link)
        a1, a2 = r.f1 / p, -r.f2 / p
        gp = (r.g1 - r.g2) / p
        wp = -((h1 - h2) / p - 3 * d1 * gp + 2 * d1 ** 3)               # dw/ds
        we1 = -(h1 / p - gp * a1 - 2 * d1 * (r.g1 / p - d1 * a1))        # dw/dη1
        we2 = -(-h2 / p - gp * a2 - 2 * d1 * (-r.g2 / p - d1 * a2))      # dw/dη2
        e1 = r.g1 / p - d1 * a1                                          # dd1/dη1
        e2 = -r.g2 / p - d1 * a2                                         # dd1/dη2
        cD, CDR, CRR = s.H.inverse()
        cdiag = np.concatenate([cD, np.diag(CRR)])
        # v_i = z_i'ΛCΛz_i
        v = tau[0] ** 2 * cdiag[self.ucodes[0]]
        for k in range(1, self.K):
            v = v + tau[k] ** 2 * cdiag[self.ucodes[k]]
        for k, l, _ in self.pairs:
            ck, cl = self.codes[k], self.roff[l] + self.codes[l]
            c = CDR[ck, cl] if k == 0 else CRR[self.roff[k] + ck, cl]
            v = v + 2 * tau[k] * tau[l] * c
        rr = -0.5 * lam * self.zt(v * wp)                                # ½ tr(C ∂H/∂u_m)
        t = s.H.solve(rr)
        T = self.zl(t, tau)                                              # (ZΛ C r)_i
        # per-row weights of the shift s_i = −x_i'β − b_i, and of η1, η2 separately
        rho = d1 - 0.5 * v * wp - T * w
        c1 = -a1 + 0.5 * v * we1 - T * e1
        c2 = -a2 + 0.5 * v * we2 - T * e2
        g_theta = (np.bincount(self.y, c1, minlength=self.J)[: self.nt]
                   + np.bincount(self.y, c2, minlength=self.J)[1:])
        g_beta = self.X.T @ rho if self.p else np.zeros(0)
        ztd1 = self.zt(d1)
        # diag(Z'WZ Λ C), block by block
        aD, ADR, ARR = s.A
        lD, lR = lam[: self.L0], lam[self.L0:]
        dg_D = aD * lD * cD + np.sum(ADR * CDR * lR[None, :], axis=1)
        dg_R = np.sum(ARR * CRR * lR[None, :], axis=1) + np.sum(ADR * CDR * lD[:, None], axis=0)
        diag_alc = np.concatenate([dg_D, dg_R])
        g_tau = np.empty(self.K)
        for k in range(self.K):
            sl = slice(self.offsets[k], self.offsets[k] + self.L[k])
            g_tau[k] = rho @ s.u[self.ucodes[k]] + diag_alc[sl].sum() - t[sl] @ ztd1[sl]
        g_user = np.empty(self.K)
        g_user[self.order] = g_tau
        return np.concatenate([g_theta, g_beta, g_user])

    def value_and_gradient(self, phi: np.ndarray) -> tuple[float, np.ndarray]:
        f, s = self.objective(phi)
        if s is None:
            return np.inf, np.full(self.n_par, np.nan)
        return f, self.gradient(s)

    def hessian(self, phi: np.ndarray, free: np.ndarray, step: float = 1e-4) -> np.ndarray:
        """Central differences of the exact gradient over the ``free`` parameters (symmetrised)."""
        idx = np.flatnonzero(free)
        H = np.empty((len(idx), len(idx)))
        for a, i in enumerate(idx):
            h = step * max(1.0, abs(phi[i]))
            pp, pm = phi.copy(), phi.copy()
            pp[i] += h
            pm[i] -= h
            H[:, a] = (self.value_and_gradient(pp)[1][idx] - self.value_and_gradient(pm)[1][idx]) / (2 * h)
        return (H + H.T) / 2


# ------------------------------------------------------------------------------------ optimiser
def _to_psi(phi: np.ndarray, nt: int) -> np.ndarray:
    psi = phi.copy()
    if nt > 1:
        psi[1:nt] = np.log(np.diff(phi[:nt]))
    return psi


def _from_psi(psi: np.ndarray, nt: int) -> np.ndarray:
    phi = psi.copy()
    if nt > 1:
        phi[:nt] = psi[0] + np.concatenate([[0.0], np.cumsum(np.exp(psi[1:nt]))])
    return phi


def _start(prob: LaplaceProblem) -> np.ndarray:
    """Thresholds at the link quantiles of the cumulative proportions, β = 0, τ = 1 (as clmm's ST)."""
    counts = np.bincount(prob.y, minlength=prob.J)
    cum = np.cumsum(counts)[:-1] / prob.n
    cum = np.clip(cum, 1e-4, 1 - 1e-4)
    theta = special.logit(cum) if prob.link == "logit" else special.ndtri(cum)
    theta = np.maximum.accumulate(theta + 1e-6 * np.arange(prob.nt))
    return np.concatenate([theta, np.zeros(prob.p), np.ones(prob.K)])


@dataclass
class OptimResult:
    phi: np.ndarray
    nll: float
    grad: np.ndarray
    hessian: np.ndarray
    free: np.ndarray
    state: ModeState
    converged: bool
    message: str
    n_evals: int
    n_iter: int


def optimise(prob: LaplaceProblem, start: np.ndarray | None, gtol: float, max_iter: int, polish: bool = True) -> OptimResult:
    """L-BFGS-B, then (``polish``) Newton steps and the Hessian; without, only the likelihood counts."""
    nt, K = prob.nt, prob.K
    phi0 = _start(prob) if start is None else np.asarray(start, float).copy()
    psi0 = _to_psi(phi0, nt)

    def f_psi(psi):
        phi = _from_psi(psi, nt)
        val, g = prob.value_and_gradient(phi)
        if not np.isfinite(val):
            return 1e300, np.zeros_like(psi)
        gp = g.copy()
        if nt > 1:
            gaps = np.exp(psi[1:nt])
            tail = np.cumsum(g[:nt][::-1])[::-1]          # Σ_{j ≥ i} ∂/∂θ_j
            gp[0] = tail[0]
            gp[1:nt] = gaps * tail[1:]
        return val, gp

    bounds = [(None, None)] * (prob.n_par - K) + [(0.0, None)] * K
    res = optimize.minimize(f_psi, psi0, jac=True, method="L-BFGS-B", bounds=bounds,
                            options={"maxiter": max_iter, "ftol": 1e-14, "gtol": 1e-7, "maxcor": 20})
    phi = _from_psi(res.x, nt)
    phi[prob.n_par - K:] = np.maximum(phi[prob.n_par - K:], 0.0)
    val, s = prob.objective(phi)
    if s is None:
        raise FormulaError("the cumulative-link mixed model could not be fitted (zero likelihood at the estimates)")
    grad = prob.gradient(s)
    if not polish and np.max(np.abs(grad)) < 1e-4:   # the log-likelihood is then within ~1e-9
        gmax = float(np.max(np.abs(grad)))
        return OptimResult(phi, val, grad, np.zeros((0, 0)), np.ones(prob.n_par, bool), s, True,
                       f"{res.message}; max|grad| = {gmax:.2e}", prob.n_evals, int(res.nit))
    # Newton steps on the parameters off the boundary; the last Hessian is the one reported
    n_newton, converged = 0, False
    while True:
        free = np.ones(prob.n_par, bool)
        free[prob.n_par - K:] = phi[prob.n_par - K:] >= BOUNDARY
        H = prob.hessian(phi, free)
        gmax = float(np.max(np.abs(grad[free]))) if free.any() else 0.0
        if gmax < gtol or n_newton >= 8:
            converged = gmax < max(gtol, 1e-6)
            break
        try:
            step = linalg.solve(H, grad[free], assume_a="sym")
        except (linalg.LinAlgError, ValueError):
            break
        if not np.all(np.isfinite(step)) or np.min(np.linalg.eigvalsh(H)) <= 0:
            break
        t, accepted = 1.0, False
        for _ in range(20):
            new = phi.copy()
            new[free] -= t * step
            new[prob.n_par - K:] = np.maximum(new[prob.n_par - K:], 0.0)
            nval, ns = prob.objective(new)
            if ns is not None and nval <= val + 1e-12 * max(1.0, abs(val)):
                accepted = True
                break
            t /= 2
        if not accepted:
            break
        ngrad = prob.gradient(ns)
        if np.max(np.abs(ngrad[free])) > gmax and nval >= val:
            break
        phi, val, s, grad = new, nval, ns, ngrad
        n_newton += 1
    msg = str(res.message) + f"; {n_newton} Newton step(s), max|grad| = {gmax:.2e}"
    return OptimResult(phi, val, grad, H, free, s, converged, msg, prob.n_evals, int(res.nit) + n_newton)


# ------------------------------------------------------------------------------------------ fit
