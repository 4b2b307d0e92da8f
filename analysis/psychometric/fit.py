"""Fitting psychometric functions: maximum likelihood and psignifit-style Bayesian grid posteriors.

Data are rows ``(level, n_correct, n_trials)``. :func:`fit_ml` maximises the binomial likelihood;
:func:`fit_bayes` follows psignifit 4 (Schütt et al. 2016): psignifit's default priors
(:mod:`analysis.psychometric.priors`), a beta-binomial likelihood with overdispersion ``eta``, the
posterior on a grid whose bounds are first narrowed to where the posterior has mass, marginal
posteriors with 95 % percentile credible intervals, and the MAP estimate found by a bounded,
restarted simplex search from the best grid point (:mod:`analysis.psychometric.map_search`; what
agrees with psignifit and why: docs/psychophysics.md). :func:`fit_table` turns fits into a tidy one-row-per-fit table.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy import optimize, special

from appeal.psychophysics.functions import check_family, psi, psi_inverse
from appeal.psychophysics.intervals import credible_interval
from analysis.psychometric.map_search import SearchResult, simplex_polish
from analysis.psychometric.priors import default_bounds, default_priors
from appeal.errors import AppealInputError

__all__ = ["MIN_TRIALS", "MIN_LEVELS", "as_data", "log_likelihood", "FitResult", "fit_ml", "fit_bayes",
           "credible_interval", "fit_table"]

#: A fit needs at least this many trials in all …
MIN_TRIALS = 20
#: … over at least this many distinct levels.
MIN_LEVELS = 3
PARAMS = ("threshold", "width", "lambda", "gamma", "eta")
#: The MAP polish's budget (:func:`analysis.psychometric.map_search.simplex_polish`): posterior
#: evaluations over all its simplex runs (41 measured data sets used 389-953; 4,000 take ~1.8 s
#: here), which keeps a result the same on any machine, and seconds, a safety net for slow ones.
MAP_MAX_EVALS = 4000
MAP_MAX_SECONDS = 10.0


def as_data(data: ArrayLike | pd.DataFrame) -> NDArray:
    """Check and return data as an ``(n, 3)`` float array of ``level, n_correct, n_trials``.

    Parameters
    ----------
    data : array_like or pandas.DataFrame
        Rows ``(level, n_correct, n_trials)``; a DataFrame needs the columns ``level``,
        ``n_correct`` and ``n_trials``.

    Raises
    ------
    AppealInputError
        One line: bad shape, counts out of range, or fewer than :data:`MIN_TRIALS` trials over
        :data:`MIN_LEVELS` levels.
    """
    if isinstance(data, pd.DataFrame):
        missing = [c for c in ("level", "n_correct", "n_trials") if c not in data.columns]
        if missing:
            raise AppealInputError(f"psychometric data lack the column(s) {', '.join(missing)}")
        data = data[["level", "n_correct", "n_trials"]].to_numpy(float)
    arr = np.asarray(data, float)
    if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0:
        raise AppealInputError("psychometric data must be rows of (level, n_correct, n_trials)")
    if not np.all(np.isfinite(arr)):
        raise AppealInputError("psychometric data contain missing or infinite values")
    k, n = arr[:, 1], arr[:, 2]
    if np.any(n < 1) or np.any(k < 0) or np.any(k > n) or np.any(k != np.round(k)) or np.any(n != np.round(n)):
        raise AppealInputError("psychometric data need whole counts with 0 <= n_correct <= n_trials and n_trials >= 1")
    total, levels = int(n.sum()), len(np.unique(arr[:, 0]))
    if total < MIN_TRIALS or levels < MIN_LEVELS:
        raise AppealInputError(f"a psychometric fit needs at least {MIN_TRIALS} trials over {MIN_LEVELS} levels "
                               f"(got {total} trials over {levels} level{'s' if levels != 1 else ''})")
    return arr


def log_likelihood(p: NDArray, k: NDArray, n: NDArray, eta: NDArray | float = 0.0) -> NDArray:
    """Log likelihood of ``k`` successes in ``n`` trials at success probability ``p``, summed over the
    last axis (without the binomial coefficient, as psignifit).

    ``eta`` is psignifit's overdispersion: the standard deviation of the beta distribution of the
    true rate around ``p``. ``eta`` broadcasts against ``p``'s
    leading axes; ``eta**2 <= 1e-9`` is treated as the binomial.
    """
    p = np.asarray(p, float)
    eta = np.asarray(eta, float)[..., None]
    with np.errstate(divide="ignore", invalid="ignore"):
        binom = special.xlogy(k, p) + special.xlog1py(n - k, -p)
        v = np.maximum(eta ** 2, 1e-9)  # variance; at or below 1e-9 the binomial (as psignifit)
        nu = 1.0 / v - 1.0
        a, b = p * nu, (1 - p) * nu
        bb = (special.gammaln(k + a) + special.gammaln(n - k + b) - special.gammaln(n + nu)
              - special.gammaln(a) - special.gammaln(b) + special.gammaln(nu))
        out = np.where(eta ** 2 <= 1e-9, binom, bb)
    return np.nan_to_num(out, nan=-np.inf).sum(axis=-1)


@dataclass
class FitResult:
    """One fitted psychometric function.

    Attributes
    ----------
    family : str
    method : str
        ``"ml"`` or ``"bayes"``.
    estimate : dict
        Point estimates of ``threshold``, ``width``, ``lambda``, ``gamma`` and ``eta`` (MAP for a
        Bayesian fit; ``eta`` is 0 for an ML fit).
    ci : dict
        95 % credible interval ``(lo, hi)`` per free parameter (Bayesian fits only).
    marginals : dict
        ``{parameter: (grid values, posterior mass)}`` (Bayesian fits only).
    n_trials : int
    nafc : int or None
        Number of alternatives (``gamma = 1/nafc``); ``None`` for yes/no with a free guess rate.
    log_likelihood : float
        Binomial log likelihood at the estimate (no binomial coefficient).
    map_search : SearchResult or None
        How the MAP polish went (evaluations, simplex runs, why it stopped); None without one.
    """

    family: str
    method: str
    estimate: dict[str, float]
    n_trials: int
    nafc: int | None
    log_likelihood: float
    ci: dict[str, tuple[float, float]] = field(default_factory=dict)
    marginals: dict[str, tuple[NDArray, NDArray]] = field(default_factory=dict)
    pc: float = 0.5
    alpha: float = 0.05
    map_search: SearchResult | None = None

    def predict(self, x: ArrayLike) -> NDArray:
        """The fitted psychometric function at ``x``."""
        e = self.estimate
        return psi(x, e["threshold"], e["width"], e["gamma"], e["lambda"], self.family, self.pc, self.alpha)

    def level_at(self, p: float) -> float:
        """The stimulus at which the fitted function reaches ``p`` (e.g. 0.75 in 2AFC)."""
        e = self.estimate
        return float(psi_inverse(p, e["threshold"], e["width"], e["gamma"], e["lambda"], self.family,
                                 self.pc, self.alpha))


def _check_nafc(nafc: int | None) -> float | None:
    if nafc is None:
        return None
    if int(nafc) != nafc or nafc < 2:
        raise AppealInputError(f"nafc must be a whole number >= 2 or None for yes/no (got {nafc})")
    return 1.0 / nafc


def fit_ml(data: ArrayLike | pd.DataFrame, family: str = "logistic", nafc: int | None = 2, pc: float = 0.5,
           alpha: float = 0.05, max_lapse: float = 0.5) -> FitResult:
    """Maximum-likelihood fit (binomial) of threshold, width, lapse and, for yes/no, the guess rate.

    Parameters
    ----------
    data : array_like or pandas.DataFrame
        See :func:`as_data`.
    family : str
        ``"logistic"``, ``"norm"`` or ``"weibull"``.
    nafc : int or None
        Alternatives of a forced-choice task (guess rate ``1/nafc``), or ``None`` for yes/no.
    pc, alpha : float
        Threshold and width definitions (see :mod:`appeal.psychophysics.functions`).
    max_lapse : float
        Upper bound of the lapse (and guess) rate.

    Returns
    -------
    FitResult
    """
    check_family(family)
    d = as_data(data)
    guess = _check_nafc(nafc)
    x, k, n = d.T
    u = np.log(x) if family == "weibull" and np.all(x > 0) else x
    lo, hi = float(u.min()), float(u.max())
    spread = max(hi - lo, 1e-12)

    def unpack(theta: NDArray) -> tuple[float, float, float, float]:
        g = guess if guess is not None else theta[3]
        return theta[0], float(np.exp(theta[1])), theta[2], g

    def nll(theta: NDArray) -> float:
        m, w, lam, g = unpack(theta)
        p = np.clip(psi(x, m, w, g, lam, family, pc, alpha), 1e-12, 1 - 1e-12)
        return -float(log_likelihood(p, k, n))

    bounds = [(lo - spread, hi + spread), (np.log(spread / 1000), np.log(spread * 10)), (0.0, max_lapse)]
    if guess is None:
        bounds.append((0.0, max_lapse))
    best = None
    for m0 in np.linspace(lo, hi, 5):
        for w0 in (spread / 4, spread / 2, spread):
            start = [m0, np.log(w0), 0.02] + ([0.02] if guess is None else [])
            r = optimize.minimize(nll, start, method="L-BFGS-B", bounds=bounds)
            if best is None or r.fun < best.fun:
                best = r
    m, w, lam, g = unpack(best.x)
    est = {"threshold": float(m), "width": w, "lambda": float(lam), "gamma": float(g), "eta": 0.0}
    return FitResult(family, "ml", est, int(n.sum()), nafc, -float(best.fun), pc=pc, alpha=alpha)


def _grid(bounds: Mapping[str, tuple[float, float]], steps: Mapping[str, int]) -> dict[str, NDArray]:
    return {p: (np.array([bounds[p][0]]) if np.isclose(*bounds[p]) else np.linspace(*bounds[p], steps[p]))
            for p in PARAMS}


def _log_posterior_grid(grid: Mapping[str, NDArray], x: NDArray, k: NDArray, n: NDArray, family: str, pc: float,
                        alpha: float, priors: Mapping[str, Any]) -> NDArray:
    """Log posterior (unnormalised) on the grid, axes in :data:`PARAMS` order."""
    m = grid["threshold"][:, None, None, None, None]
    w = grid["width"][None, :, None, None, None]
    lam = grid["lambda"][None, None, :, None, None]
    g = grid["gamma"][None, None, None, :, None]
    p = psi(x, m[..., None], w[..., None], g[..., None], lam[..., None], family, pc, alpha)  # T W L G 1 X
    p = np.clip(p, 1e-300, 1 - 1e-16)
    eta = grid["eta"][None, None, None, None, :]
    ll = log_likelihood(p, k, n, eta)
    with np.errstate(divide="ignore"):
        lp = ll.copy()
        for i, name in enumerate(PARAMS):
            shape = [1] * 5
            shape[i] = -1
            prior = np.asarray(priors[name](grid[name]), float) if len(grid[name]) > 1 else np.ones(1)
            lp = lp + np.log(prior).reshape(shape)
    return lp


def _weights(grid: Mapping[str, NDArray]) -> NDArray:
    w = np.ones((1,) * 5)
    for i, name in enumerate(PARAMS):
        v = grid[name]
        d = np.ones(1)
        if len(v) > 1:  # composite trapezoid weights
            d = np.empty_like(v)
            d[1:] = np.diff(v)
            d[0] = d[1] / 2
            d[-1] = d[-1] / 2
        shape = [1] * 5
        shape[i] = -1
        w = w * d.reshape(shape)
    return w


def fit_bayes(data: ArrayLike | pd.DataFrame, family: str = "logistic", nafc: int | None = 2, pc: float = 0.5,
              alpha: float = 0.05, stimulus_range: tuple[float, float] | None = None,
              width_min: float | None = None, beta: float = 10.0, grid_steps: Mapping[str, int] | None = None,
              coarse_steps: Mapping[str, int] | None = None, priors: Mapping[str, Any] | None = None,
              ci_level: float = 0.95, refine_map: bool = True) -> FitResult:
    """psignifit-4-style Bayesian fit: grid posterior, marginals, MAP and credible intervals.

    Parameters
    ----------
    data : array_like or pandas.DataFrame
        See :func:`as_data`.
    family : str
        ``"logistic"``, ``"norm"`` or ``"weibull"`` (threshold and width then in log units).
    nafc : int or None
        Alternatives of a forced-choice task (guess rate fixed at ``1/nafc``), ``None`` for yes/no
        (the guess rate gets a Beta(1, 10) prior).
    pc, alpha : float
        Threshold and width definitions.
    stimulus_range : (float, float), optional
        Range for the priors; default the data's (log, for Weibull) level range.
    width_min : float, optional
        Smallest width in the prior; default the smallest spacing between levels, or 1/100 of a
        given ``stimulus_range`` (as psignifit).
    beta : float
        The overdispersion prior is Beta(1, ``beta``).
    grid_steps, coarse_steps : mapping, optional
        Grid points per parameter for the final grid (default threshold 40, width 40, lapse 20,
        guess 20 (yes/no), eta 20) and for the first, bound-finding grid.
    priors : mapping, optional
        Replacement prior densities per parameter.
    ci_level : float
        Credible level of the intervals.
    refine_map : bool
        Refine the MAP estimate by a bounded, restarted simplex search from the best grid point
        (:func:`~analysis.psychometric.map_search.simplex_polish`, at most :data:`MAP_MAX_EVALS`
        posterior evaluations and :data:`MAP_MAX_SECONDS`). False: the best grid point is the estimate (the
        marginals and intervals are the same; planning runs use it).

    Returns
    -------
    FitResult
        With ``estimate`` the MAP, ``ci`` the percentile intervals and ``marginals``.
    """
    check_family(family)
    d = as_data(data)
    guess = _check_nafc(nafc)
    x, k, n = d.T
    u = np.log(x) if family == "weibull" else x
    if family == "weibull" and np.any(x <= 0):
        raise AppealInputError("the Weibull family needs positive stimulus levels")
    user_range = stimulus_range is not None
    srange = (float(u.min()), float(u.max())) if stimulus_range is None else tuple(map(float, stimulus_range))
    if not srange[1] > srange[0]:
        raise AppealInputError(f"the stimulus range {srange} is empty")
    if width_min is None:
        width_min = (srange[1] - srange[0]) / 100 if user_range else float(np.diff(np.unique(u)).min())
    pri = dict(default_priors(srange, width_min, alpha, beta))
    if priors:
        pri.update(priors)
    bounds = default_bounds(srange, width_min, alpha, guess)
    fine = {"threshold": 40, "width": 40, "lambda": 20, "gamma": 20, "eta": 20, **(grid_steps or {})}
    coarse = ({"threshold": 30, "width": 40, "lambda": 10, "gamma": 1, "eta": 20} if guess is not None else
              {"threshold": 25, "width": 30, "lambda": 10, "gamma": 10, "eta": 15})
    coarse.update(coarse_steps or {})
    # Weibull: the sigmoid is evaluated on the original levels, parameters in log units.
    xs = x

    # 1) coarse grid over the full bounds, 2) narrow each bound to where the posterior has mass
    g0 = _grid(bounds, coarse)
    lp0 = _log_posterior_grid(g0, xs, k, n, family, pc, alpha, pri)
    keep = np.exp(lp0 - lp0.max()) > np.exp(-10)
    idx = np.nonzero(keep)
    nb = {}
    for ax, name in enumerate(PARAMS):
        v = g0[name]
        lo_i, hi_i = max(int(idx[ax].min()) - 1, 0), min(int(idx[ax].max()) + 1, len(v) - 1)
        nb[name] = (float(v[lo_i]), float(v[hi_i]))
    g = _grid(nb, fine)
    lp = _log_posterior_grid(g, xs, k, n, family, pc, alpha, pri)
    mass = np.exp(lp - lp.max()) * _weights(g)
    mass /= mass.sum()
    marginals, ci = {}, {}
    for ax, name in enumerate(PARAMS):
        other = tuple(i for i in range(5) if i != ax)
        mg = mass.sum(axis=other)
        marginals[name] = (g[name], mg)
        if len(g[name]) > 1:
            ci[name] = credible_interval(g[name], mg, ci_level)

    # MAP: simplex from the best grid point over the free parameters
    free = [name for name in PARAMS if len(g[name]) > 1]
    fixed = {name: float(g[name][0]) for name in PARAMS if len(g[name]) == 1}
    best = np.unravel_index(np.argmax(lp), lp.shape)
    start = [float(g[name][best[PARAMS.index(name)]]) for name in free]

    def neg_lp(theta: NDArray) -> float:
        par = {**fixed, **dict(zip(free, theta))}
        pr = 0.0
        for name in free:
            v = float(np.asarray(pri[name](np.array([par[name]])), float)[0])
            if not v > 0:
                return np.inf
            pr += np.log(v)
        p = np.clip(psi(xs, par["threshold"], par["width"], par["gamma"], par["lambda"], family, pc, alpha),
                    1e-300, 1 - 1e-16)
        return -(float(log_likelihood(p, k, n, par["eta"])) + pr)

    theta = np.asarray(start)
    search = None
    if refine_map:
        cells = [float(g[name][1] - g[name][0]) for name in free]
        search = simplex_polish(neg_lp, start, cells, [bounds[name] for name in free], max_evals=MAP_MAX_EVALS,
                                max_seconds=MAP_MAX_SECONDS)
        theta = search.x
    est = {**fixed, **{nm: float(v) for nm, v in zip(free, theta)}}
    est = {name: float(est[name]) for name in PARAMS}
    p_hat = np.clip(psi(xs, est["threshold"], est["width"], est["gamma"], est["lambda"], family, pc, alpha),
                    1e-300, 1 - 1e-16)
    return FitResult(family, "bayes", est, int(n.sum()), nafc, float(log_likelihood(p_hat, k, n)), ci, marginals,
                     pc=pc, alpha=alpha, map_search=search)


def fit_table(fits: Sequence[FitResult] | Mapping[Any, FitResult], label: str = "fit") -> pd.DataFrame:
    """A tidy table, one row per fit: estimates, credible intervals, family, method, trials.

    Parameters
    ----------
    fits : sequence or mapping of FitResult
        A mapping's keys become the ``label`` column (tuples spread over several columns are not
        split; pass strings or numbers).
    label : str
        Name of the label column.

    Returns
    -------
    pandas.DataFrame
        Columns ``label, family, method, nafc, n_trials, threshold, threshold_lo, threshold_hi,
        width, width_lo, width_hi, lambda, ..., eta_hi, log_likelihood``.
    """
    items = list(fits.items()) if isinstance(fits, Mapping) else list(enumerate(fits))
    rows = []
    for key, f in items:
        row: dict[str, Any] = {label: key, "family": f.family, "method": f.method, "nafc": f.nafc,
                               "n_trials": f.n_trials}
        for name in PARAMS:
            row[name] = f.estimate[name]
            lo, hi = f.ci.get(name, (np.nan, np.nan))
            row[f"{name}_lo"], row[f"{name}_hi"] = lo, hi
        row["log_likelihood"] = f.log_likelihood
        rows.append(row)
    return pd.DataFrame(rows)
