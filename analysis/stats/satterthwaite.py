"""Satterthwaite's degrees of freedom for linear mixed models, as lmerTest computes them.

Kuznetsova, Brockhoff & Christensen (2017, *J. Stat. Softw.* 82(13)): the variance parameters
are (θ, σ); their asymptotic covariance is ``A = 2 H⁻¹`` with ``H`` the Hessian of the
(RE)ML deviance at the estimates (:meth:`~analysis.stats.lmm.LmmFit.deviance_vp`, σ not
profiled out), and ``J_k = ∂ Cov(β̂)/∂ varpar_k``. For a contrast ``l``,
``ν = 2 (l'Cl)² / (g'Ag)`` with ``g_k = l'J_k l``; an F test of a matrix ``L`` of rank q uses
the eigen-decomposition of ``L C L'`` (one ν per direction) and combines them as lmerTest's
``get_Fstat_ddf``. The Hessian is the central difference of the exact gradient,
Richardson-extrapolated (errors ~1e-10 relative); ``J`` is exact
(:meth:`~analysis.stats.lmm.LmmFit.vcov_vp_jacobian`; lmerTest differences it numerically, and so
did this module: the two agree to ~1e-9, ``tests/test_stats_lmm.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special

from analysis.stats.lmm import LmmFit, blas_threads

__all__ = ["Satterthwaite", "satterthwaite", "richardson_jacobian", "contrast_test", "f_test_ddf"]


def richardson_jacobian(fun, x: np.ndarray, rel_step: float = 1e-3, levels: int = 2) -> np.ndarray:
    """∂fun/∂x by central differences with Richardson extrapolation (as ``numDeriv``).

    ``fun`` returns an array of any shape; the result has that shape plus ``len(x)``.
    """
    x = np.asarray(x, float)
    f0 = np.asarray(fun(x), float)
    out = np.empty(f0.shape + (len(x),))
    for i in range(len(x)):
        h0 = rel_step * max(abs(x[i]), 0.1)
        table = []
        for m in range(levels):
            h = h0 / 2 ** m
            xp, xm = x.copy(), x.copy()
            xp[i] += h
            xm[i] -= h
            table.append((np.asarray(fun(xp), float) - np.asarray(fun(xm), float)) / (2 * h))
        for k in range(1, levels):  # eliminate h^2, h^4, ...
            table = [(4 ** k * table[j + 1] - table[j]) / (4 ** k - 1) for j in range(len(table) - 1)]
        out[..., i] = table[0]
    return out


@dataclass
class Satterthwaite:
    """Everything needed to attach Satterthwaite dfs to contrasts of one fit."""

    fit: LmmFit
    vcov_varpar: np.ndarray
    jacobian: np.ndarray  # p × p × n_varpar
    hessian: np.ndarray

    @property
    def vcov(self) -> np.ndarray:
        """The covariance of β̂ the tests use (the fit's own)."""
        return self.fit.vcov

    def ddf(self, l: np.ndarray) -> float:
        """Satterthwaite's df of the contrast ``l'β`` (lmerTest's ``contest1D``)."""
        l = np.asarray(l, float)
        v = float(l @ self.fit.vcov @ l)
        g = np.einsum("i,ijk,j->k", l, self.jacobian, l)
        denom = float(g @ self.vcov_varpar @ g)
        return 2 * v ** 2 / denom if denom > 0 else np.inf

    def test(self, L: np.ndarray, rhs: np.ndarray | None = None, eps: float = np.sqrt(np.finfo(float).eps)) -> dict:
        """The F test of ``Lβ = rhs`` with its Satterthwaite df (lmerTest's ``contestMD``)."""
        L = np.atleast_2d(np.asarray(L, float))
        est = L @ self.fit.beta - (0 if rhs is None else np.asarray(rhs, float))
        VL = L @ self.fit.vcov @ L.T
        d, P = np.linalg.eigh(VL)
        d, P = d[::-1], P[:, ::-1]
        keep = d > max(eps * d[0], 0)
        q = int(keep.sum())
        PtL = (P.T @ L)[:q]
        if q == 1:
            ddf = self.ddf(L[0])
            t = est[0] / np.sqrt(VL[0, 0])
            F = t ** 2
        else:
            t2 = (P.T @ est)[:q] ** 2 / d[:q]
            F = t2.sum() / q
            grads = np.einsum("mi,ijk,mj->mk", PtL, self.jacobian, PtL)  # one gradient per direction
            nus = 2 * d[:q] ** 2 / np.einsum("mk,kl,ml->m", grads, self.vcov_varpar, grads)
            ddf = f_test_ddf(nus)
        return {"F": float(F), "num_df": q, "den_df": float(ddf), "p": float(special.fdtrc(q, ddf, F))}


def f_test_ddf(nu: np.ndarray, tol: float = 1e-8) -> float:
    """The denominator df of an F test from the dfs of its q orthogonal directions (lmerTest)."""
    nu = np.asarray(nu, float)
    if len(nu) == 1:
        return float(nu[0])
    if np.all(np.abs(np.diff(nu)) < tol):
        return float(nu.mean())
    if np.any(nu <= 2):
        return 2.0
    E = np.sum(nu / (nu - 2))
    return float(2 * E / (E - len(nu)))


def satterthwaite(fit: LmmFit) -> Satterthwaite:
    """Prepare Satterthwaite dfs for a fit (the Hessian and the Jacobian of Cov(β̂) at the estimates)."""
    vp = fit.varpar
    with blas_threads(fit.problem.q + fit.problem.p):
        H = richardson_jacobian(fit.deviance_vp_grad, vp)
        J = fit.vcov_vp_jacobian(vp)
    H = (H + H.T) / 2
    try:
        A = 2 * np.linalg.inv(H)
    except np.linalg.LinAlgError:
        A = 2 * np.linalg.pinv(H)
    return Satterthwaite(fit, A, J, H)


def contrast_test(sat: Satterthwaite, l: np.ndarray) -> dict:
    """Estimate, SE, df, t and two-sided p of one contrast ``l'β``."""
    l = np.asarray(l, float)
    est = float(l @ sat.fit.beta)
    se = float(np.sqrt(l @ sat.fit.vcov @ l))
    df = sat.ddf(l)
    t = est / se
    return {"estimate": est, "se": se, "df": df, "t": t, "p": float(2 * special.stdtr(df, -abs(t)))}
