"""Kenward–Roger inference for linear mixed models, as R's pbkrtest (0.5.2) computes it.

Kenward & Roger (1997, *Biometrics* 53(3)); Halekoh & Højsgaard (2014, *J. Stat. Softw.*
59(9)). The variance parameters γ are every element of every random term's covariance matrix
(its lower triangle with the diagonal, column by column) and the residual variance; with
``G_i = Z_r E_i Z_r'`` (``E_i`` the symmetric indicator of that element on each level of term
r) and ``G = I`` for the residual, ``V = Σ γ_i G_i``. pbkrtest's ``vcovAdj`` forms

    P_i  = −X'V⁻¹G_iV⁻¹X,    Q_ij = X'V⁻¹G_iV⁻¹G_jV⁻¹X,
    IE2_ij = tr(V⁻¹G_iV⁻¹G_j) − 2 tr(Φ Q_ij) + tr(Φ P_i Φ P_j),    W = 2 IE2⁻¹,
    Φ_A  = Φ + 2 Φ [Σ_ij W_ij (Q_ij − P_i Φ P_j)] Φ,

with Φ = (X'V⁻¹X)⁻¹, from n × n matrices. Here nothing n × n is formed: with
``V = σ²(I + ZΛΛ'Z')`` Woodbury gives ``V⁻¹ = σ⁻²(I − Z H Z')``, ``H = Λ(Λ'Z'ZΛ + I)⁻¹Λ'``, so
``V⁻¹[Z X] = [Z X] K`` with the (q+p)-square ``K = σ⁻²(I − [I; 0] H [Z'Z Z'X])``. Every
quantity above is then a product of ``N_m = [Z X]'V⁻ᵐ[Z X] = S Kᵐ`` (S the Gram matrix of
[Z X], from :class:`~analysis.stats.lmm.LmmProblem`'s cross products) and the per-level E_i,
summed over levels with reshapes; ``tr(V⁻²)`` is ``σ⁻⁴(n − 2 tr(HZ'Z) + tr((HZ'Z)²))``. The cost
is O((q+p)³) whatever the number of rows.

:meth:`KenwardRoger.test` is pbkrtest's ``.KR_adjust`` (what ``lmerTest::anova(m, ddf =
"Kenward-Roger")`` reports) and :meth:`KenwardRoger.ddf` its ``Lb_ddf`` (lmerTest's
``summary(m, ddf = "Kenward-Roger")`` and emmeans' ``lmer.df = "kenward-roger"``, whose
standard errors come from :attr:`KenwardRoger.vcov` = Φ_A).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, stats

from analysis.stats.lmm import LmmFit, LmmProblem, fit_lmm

__all__ = ["KenwardRoger", "kenward_roger", "kr_statistics", "variance_components", "VarianceComponent"]

#: pbkrtest inverts IE2 when its smallest |eigenvalue| exceeds this, else takes MASS::ginv.
_IE2_TOL = 1e-10


@dataclass(frozen=True)
class VarianceComponent:
    """One variance parameter γ: element (row, col) of random term ``block``'s covariance
    (``block`` is None for the residual variance)."""

    block: int | None
    row: int
    col: int
    name: str

    def indicator(self, k: int) -> np.ndarray:
        """The symmetric k × k indicator E of this element."""
        E = np.zeros((k, k))
        E[self.row, self.col] = E[self.col, self.row] = 1.0
        return E


@dataclass
class KenwardRoger:
    """pbkrtest's ``vcovAdj`` of one REML fit, and the tests built on it.

    Attributes
    ----------
    beta : ndarray
        The fixed effects β̂ (p).
    vcov_unadjusted : ndarray
        Φ = (X'V⁻¹X)⁻¹ at the REML estimates (lme4's ``vcov``).
    vcov : ndarray
        Φ_A, the Kenward–Roger adjusted covariance of β̂.
    P : ndarray
        g × p × p: ``P_i = −X'V⁻¹G_iV⁻¹X``.
    Q : ndarray
        g × g × p × p: ``Q_ij = X'V⁻¹G_iV⁻¹G_jV⁻¹X`` (``Q[j, i] = Q[i, j]'``).
    W : ndarray
        g × g: twice the inverse (or pseudo-inverse) of the information ``IE2``.
    information : ndarray
        IE2 (g × g).
    condition : float
        The smallest |eigenvalue| of IE2 (pbkrtest's ``condi``); below 1e-10 W is a pseudo-inverse.
    components : list of VarianceComponent
        The g variance parameters, in the order of P, Q and W (the residual last).
    gamma : ndarray
        Their values (covariance elements and σ²).
    """

    beta: np.ndarray
    vcov_unadjusted: np.ndarray
    vcov: np.ndarray
    P: np.ndarray
    Q: np.ndarray
    W: np.ndarray
    information: np.ndarray
    condition: float
    components: list[VarianceComponent]
    gamma: np.ndarray

    def test(self, L: np.ndarray, rhs: np.ndarray | None = None) -> dict[str, float]:
        """The Kenward–Roger F test of ``Lβ = rhs`` (pbkrtest's ``.KR_adjust``).

        Parameters
        ----------
        L : ndarray
            Contrast matrix, one hypothesis per row (a vector is one row).
        rhs : ndarray, optional
            The hypothesised values of ``Lβ`` (default 0); as lmerTest, β_H = ginv(L) rhs.

        Returns
        -------
        dict
            ``F`` (scaled, as lmerTest's ``F value``), ``num_df`` (rank of L), ``den_df``,
            ``p``, ``F_unscaled`` (Wald/q with Φ_A), ``p_unscaled``, ``F_scaling`` and the
            auxiliary ``A1``, ``A2``, ``rho``.
        """
        L = np.atleast_2d(np.asarray(L, float))
        beta_h = np.zeros_like(self.beta) if rhs is None else np.linalg.pinv(L) @ np.atleast_1d(np.asarray(rhs, float))
        q = int(np.linalg.matrix_rank(L))
        A1, A2 = _a1_a2(L, self.vcov_unadjusted, self.P, self.W)
        ddf, scaling, rho = kr_statistics(A1, A2, q)
        d = L @ (self.beta - beta_h)
        F_u = float(d @ np.linalg.solve(L @ self.vcov @ L.T, d)) / q
        F = scaling * F_u
        return {"F": F, "num_df": q, "den_df": ddf, "p": float(stats.f.sf(F, q, ddf)), "F_unscaled": F_u,
                "p_unscaled": float(stats.f.sf(F_u, q, ddf)), "F_scaling": scaling, "A1": A1, "A2": A2, "rho": rho}

    def ddf(self, l: np.ndarray) -> float:
        """Kenward–Roger df of ``l'β`` (pbkrtest's ``Lb_ddf``; q = number of rows of l)."""
        L = np.atleast_2d(np.asarray(l, float))
        A1, A2 = _a1_a2(L, self.vcov_unadjusted, self.P, self.W)
        return kr_statistics(A1, A2, L.shape[0])[0]

    def contrast(self, l: np.ndarray) -> dict[str, float]:
        """The t test of ``l'β = 0``: estimate, SE from Φ_A, KR df, t and two-sided p
        (lmerTest's ``contest1D`` under Kenward–Roger)."""
        l = np.asarray(l, float)
        est = float(l @ self.beta)
        se = float(np.sqrt(l @ self.vcov @ l))
        df = self.ddf(l)
        t = est / se
        return {"estimate": est, "se": se, "df": df, "t": t, "p": float(2 * stats.t.sf(abs(t), df))}


def kenward_roger(fit: LmmFit) -> KenwardRoger:
    """pbkrtest's ``vcovAdj`` of a fitted LMM, with q- and p-sized matrices only.

    Parameters
    ----------
    fit : LmmFit
        A fit from :func:`~analysis.stats.lmm.fit_lmm`. An ML fit is refitted by REML first,
        as ``pbkrtest::vcovAdj`` does.

    Returns
    -------
    KenwardRoger
        Φ, Φ_A, P_i, Q_ij, W, IE2 and the variance parameters, with :meth:`~KenwardRoger.test`
        and :meth:`~KenwardRoger.ddf`.
    """
    if not fit.reml:
        fit = fit_lmm(fit.mm, reml=True)
    prob, sigma2 = fit.problem, fit.sigma ** 2
    comps = variance_components(prob)
    H = _woodbury_h(prob, fit.theta)
    S = _gram(prob)
    N1, N2, XV3X = _v_powers(S, H, prob.q, sigma2)
    P, Q = _p_q_matrices(prob, comps, N1, N2, XV3X)
    K = _trace_matrix(prob, comps, N1, N2, H, sigma2)
    Phi = fit.vcov
    IE2 = _information(K, P, Q, Phi)
    W, condi = _w_matrix(IE2)
    PhiA = _adjusted_vcov(Phi, P, Q, W)
    gamma = _gamma(fit, comps)
    return KenwardRoger(fit.beta.copy(), Phi, PhiA, P, Q, W, IE2, condi, comps, gamma)


# ---------------------------------------------------------------------------- the parameters
def variance_components(prob: LmmProblem) -> list[VarianceComponent]:
    """The variance parameters in pbkrtest's order within a term (lower triangle by column),
    terms in the order of the model's random blocks, the residual last."""
    out = []
    for r, blk in enumerate(prob.mm.blocks):
        for j in range(blk.k):
            for i in range(j, blk.k):
                what = blk.columns[i] if i == j else f"{blk.columns[i]},{blk.columns[j]}"
                out.append(VarianceComponent(r, i, j, f"{blk.group}: {what}"))
    out.append(VarianceComponent(None, 0, 0, "Residual"))
    return out


def _gamma(fit: LmmFit, comps: list[VarianceComponent]) -> np.ndarray:
    covs = fit.random_covariances()
    return np.array([fit.sigma ** 2 if c.block is None else covs[c.block][c.row, c.col] for c in comps])


# ---------------------------------------------------------------------------- V⁻¹ by Woodbury
def _woodbury_h(prob: LmmProblem, theta: np.ndarray) -> np.ndarray:
    """H = Λ(Λ'Z'ZΛ + I)⁻¹Λ' (q × q), so that V⁻¹ = σ⁻²(I − ZHZ')."""
    Lam = prob.times_lambda(np.eye(prob.q), theta)  # I Λ = Λ (dense q × q, block diagonal)
    C = Lam.T @ prob.ZtZ @ Lam
    C[np.diag_indices_from(C)] += 1.0
    Lc = linalg.cholesky(C, lower=True, check_finite=False)
    R = linalg.solve_triangular(Lc, Lam.T, lower=True, check_finite=False)
    return R.T @ R


def _gram(prob: LmmProblem) -> np.ndarray:
    """S = [Z X]'[Z X] ((q+p) square, Z's columns first)."""
    q = prob.q
    S = np.empty((q + prob.p, q + prob.p))
    S[:q, :q] = prob.ZtZ
    S[:q, q:] = prob.ZtX
    S[q:, :q] = prob.ZtX.T
    S[q:, q:] = prob.XtX
    return S


def _times_k(N: np.ndarray, S: np.ndarray, H: np.ndarray, q: int, sigma2: float) -> np.ndarray:
    """N K for K = σ⁻²(I − [I; 0] H S[:q]) (V⁻¹[Z X] = [Z X] K)."""
    return (N - N[:, :q] @ (H @ S[:q])) / sigma2


def _v_powers(S: np.ndarray, H: np.ndarray, q: int, sigma2: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """[Z X]'V⁻¹[Z X], [Z X]'V⁻²[Z X] and X'V⁻³X."""
    N1 = _times_k(S, S, H, q, sigma2)
    N1 = (N1 + N1.T) / 2
    N2 = _times_k(N1, S, H, q, sigma2)
    N2 = (N2 + N2.T) / 2
    XV3X = _times_k(N2[q:], S, H, q, sigma2)[:, q:]
    return N1, N2, (XV3X + XV3X.T) / 2


# ---------------------------------------------------------------------------- P, Q, traces
def _block_slice(prob: LmmProblem, r: int) -> slice:
    blk = prob.mm.blocks[r]
    return slice(prob.offsets[r], prob.offsets[r] + blk.n_levels * blk.k)


def _times_e(M: np.ndarray, E: np.ndarray, k: int) -> np.ndarray:
    """M (I_L ⊗ E) for M with L·k columns (level-major)."""
    m = M.shape[0]
    return (M.reshape(m, -1, k) @ E).reshape(m, -1)


def _xv_ze(prob: LmmProblem, comp: VarianceComponent, N1: np.ndarray) -> np.ndarray | None:
    """Y_i = X'V⁻¹Z_r(I ⊗ E_i) (p × q_r), so that X'V⁻¹G_i = Y_i Z_r' (None for the residual)."""
    if comp.block is None:
        return None
    k = prob.mm.blocks[comp.block].k
    return _times_e(N1[prob.q:, _block_slice(prob, comp.block)], comp.indicator(k), k)


def _p_q_matrices(prob: LmmProblem, comps: list[VarianceComponent], N1: np.ndarray, N2: np.ndarray,
                  XV3X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """P (g × p × p) and Q (g × g × p × p) from the blocks of N1 = [Z X]'V⁻¹[Z X] and N2."""
    q, p, g = prob.q, prob.p, len(comps)
    P = np.empty((g, p, p))
    Q = np.empty((g, g, p, p))
    Y = [_xv_ze(prob, c, N1) for c in comps]
    for i, ci in enumerate(comps):
        if ci.block is None:
            P[i] = -N2[q:, q:]
            Q[i, i] = XV3X
            continue
        ri = _block_slice(prob, ci.block)
        P[i] = -Y[i] @ N1[ri, q:]
        YN = Y[i] @ N1[ri, :q]  # X'V⁻¹G_iV⁻¹Z (p × q)
        for j in range(i, g):
            cj = comps[j]
            Q[i, j] = Y[i] @ N2[ri, q:] if cj.block is None else YN[:, _block_slice(prob, cj.block)] @ Y[j].T
            Q[j, i] = Q[i, j].T
    return P, Q


def _pair_tensor(N: np.ndarray, kr: int, ks: int) -> np.ndarray:
    """T[a, c, b, d] = Σ_{l,m} N[(l,a),(m,c)] N[(l,b),(m,d)] for an (L_r k_r) × (L_s k_s) block."""
    Lr, Ls = N.shape[0] // kr, N.shape[1] // ks
    F = N.reshape(Lr, kr, Ls, ks).transpose(1, 3, 0, 2).reshape(kr * ks, Lr * Ls)
    return (F @ F.T).reshape(kr, ks, kr, ks)


def _trace_matrix(prob: LmmProblem, comps: list[VarianceComponent], N1: np.ndarray, N2: np.ndarray,
                  H: np.ndarray, sigma2: float) -> np.ndarray:
    """tr(V⁻¹G_iV⁻¹G_j) for all pairs (pbkrtest's ``Ktrace``)."""
    g, blocks = len(comps), prob.mm.blocks
    K = np.empty((g, g))
    tensors: dict[tuple[int, int], np.ndarray] = {}
    diag_sums: dict[int, np.ndarray] = {}
    for i, ci in enumerate(comps):
        for j in range(i, g):
            cj = comps[j]
            if ci.block is None:  # residual with itself: tr(V⁻²)
                HZ = H @ prob.ZtZ
                val = (prob.n - 2 * np.trace(HZ) + np.sum(HZ * HZ.T)) / sigma2 ** 2
            elif cj.block is None:  # tr(G_i V⁻²) = tr(E_i Z_r'V⁻²Z_r)
                r, k = ci.block, blocks[ci.block].k
                if r not in diag_sums:
                    sl = _block_slice(prob, r)
                    D = N2[sl, sl].reshape(-1, k, blocks[r].n_levels, k)
                    diag_sums[r] = np.einsum("lalb->ab", D)
                val = float(np.sum(ci.indicator(k) * diag_sums[r]))
            else:
                r, s = ci.block, cj.block
                kr, ks = blocks[r].k, blocks[s].k
                if (r, s) not in tensors:
                    tensors[(r, s)] = _pair_tensor(N1[_block_slice(prob, r), _block_slice(prob, s)], kr, ks)
                val = float(np.einsum("ab,cd,acbd->", ci.indicator(kr), cj.indicator(ks), tensors[(r, s)]))
            K[i, j] = K[j, i] = val
    return K


# ---------------------------------------------------------------------------- W and Φ_A
def _information(K: np.ndarray, P: np.ndarray, Q: np.ndarray, Phi: np.ndarray) -> np.ndarray:
    """IE2_ij = tr(V⁻¹G_iV⁻¹G_j) − 2 tr(Φ Q_ij) + tr(Φ P_i Φ P_j)."""
    PhiP = np.einsum("ab,ibc->iac", Phi, P)
    return K - 2 * np.einsum("ab,ijba->ij", Phi, Q) + np.einsum("iab,jba->ij", PhiP, PhiP)


def _w_matrix(IE2: np.ndarray) -> tuple[np.ndarray, float]:
    """W = 2 IE2⁻¹ (MASS::ginv when IE2 is near singular) and pbkrtest's ``condi``."""
    condi = float(np.min(np.abs(np.linalg.eigvals(IE2))))
    if condi > _IE2_TOL:
        W = 2 * np.linalg.inv(IE2)
    else:
        W = 2 * np.linalg.pinv(IE2, rcond=np.sqrt(np.finfo(float).eps))
    return (W + W.T) / 2, condi


def _adjusted_vcov(Phi: np.ndarray, P: np.ndarray, Q: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Φ_A = Φ + 2 Φ U Φ, U = Σ_ij W_ij (Q_ij − P_i Φ P_j)."""
    PPhiP = np.einsum("iab,bc,jcd->ijad", P, Phi, P)
    U = np.einsum("ij,ijab->ab", W, Q - PPhiP)
    return Phi + 2 * Phi @ U @ Phi


# ---------------------------------------------------------------------------- the tests
def _a1_a2(L: np.ndarray, Phi: np.ndarray, P: np.ndarray, W: np.ndarray) -> tuple[float, float]:
    """A1 = Σ W_ij tr(Θ Φ P_i Φ) tr(Θ Φ P_j Φ), A2 = Σ W_ij tr(Θ Φ P_i Φ Θ Φ P_j Φ),
    Θ = L'(LΦL')⁻¹L."""
    Theta = L.T @ np.linalg.solve(L @ Phi @ L.T, L)
    u = np.einsum("ab,ibc,cd->iad", Theta @ Phi, P, Phi)
    tr = np.trace(u, axis1=1, axis2=2)
    return float(tr @ W @ tr), float(np.einsum("ij,iab,jba->", W, u, u))


def _div_zero(x: float, y: float, tol: float = 1e-14) -> float:
    """pbkrtest's ``.divZero``: 1 when both are (near) zero."""
    return 1.0 if abs(x) < tol and abs(y) < tol else x / y


def kr_statistics(A1: float, A2: float, q: int) -> tuple[float, float, float]:
    """Kenward–Roger's denominator df, F scaling and ρ from A1, A2 and the number of
    hypotheses q (the closing lines of pbkrtest's ``.KR_adjust`` and ``Lb_ddf``)."""
    B = (A1 + 6 * A2) / (2 * q)
    g = ((q + 1) * A1 - (q + 4) * A2) / ((q + 2) * A2)
    den = 3 * q + 2 * (1 - g)
    c1, c2, c3 = g / den, (q - g) / den, (q + 2 - g) / den
    V0 = 1 + c1 * B
    V0 = 0.0 if abs(V0) < 1e-10 else V0
    V1, V2 = 1 - c2 * B, 1 - c3 * B
    rho = _div_zero(1 - A2 / q, V1) ** 2 * V0 / V2 / q
    df2 = 4 + (q + 2) / (q * rho - 1)
    scaling = 1.0 if abs(df2 - 2) < 0.01 else df2 * (1 - A2 / q) / (df2 - 2)
    return float(df2), float(scaling), float(rho)
