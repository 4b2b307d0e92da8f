"""The MAP polish of a Bayesian psychometric fit: a bounded, restarted simplex search with a budget.

:func:`analysis.psychometric.fit.fit_bayes` starts from the best point of its posterior grid and
refines it by a Nelder–Mead simplex (as psignifit 4 does with ``scipy.optimize.fmin``). Two things
make a plain simplex misbehave on these posteriors, and :func:`simplex_polish` answers both:

* **Optima on a bound.** Lapse and overdispersion often sit at 0, where the prior's support ends.
  An unbounded simplex sees ``-log 0 = inf`` beyond it and crawls along the boundary by ever
  smaller contractions: on one 2AFC set it used its 40,000-evaluation cap (17 s). Here the
  search is bounded (:func:`scipy.optimize.minimize` clips vertices onto the parameter box), so
  the simplex lies down on the bound instead.
* **A collapsed simplex.** A simplex that shrinks onto a bound (or along a ridge) can stop short of
  the optimum, or creep along it. The search restarts from its result with a fresh simplex one
  grid cell wide per parameter, until a restart improves the log posterior by no more than
  ``ftol``; a run is cut at a quarter of the budget (at least :data:`RUN_EVALS_MIN`), so a creeping
  simplex is restarted too.

Every evaluation counts against ``max_evals`` and the whole search against ``max_seconds``; when
either runs out the best point evaluated so far is the result (``SearchResult.stopped`` says why).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import optimize

__all__ = ["RUN_EVALS_MIN", "SearchResult", "initial_simplex", "simplex_polish"]

#: One simplex run's evaluations at least (a quarter of the budget where that is more).
RUN_EVALS_MIN = 200


@dataclass(frozen=True)
class SearchResult:
    """The best point found, its function value, evaluations used, simplex runs and why it stopped
    (``"converged"``, ``"evaluations"`` or ``"time"``)."""

    x: NDArray
    fun: float
    n_evals: int
    n_runs: int
    stopped: str


class _OutOfBudget(Exception):
    pass


def initial_simplex(x: ArrayLike, steps: ArrayLike, lower: ArrayLike, upper: ArrayLike) -> NDArray:
    """A simplex of ``n + 1`` vertices: ``x`` and ``x ± steps[i]`` along each axis ``i``, each
    vertex inside ``[lower, upper]`` (the step goes down where it would leave the box upwards and
    is shortened where the box is narrower than a step).

    Examples
    --------
    >>> initial_simplex([0.0, 1.0], [0.1, 0.5], [0.0, 0.0], [1.0, 1.2]).tolist()
    [[0.0, 1.0], [0.1, 1.0], [0.0, 0.5]]
    """
    x = np.asarray(x, float)
    lo, hi = np.asarray(lower, float), np.asarray(upper, float)
    out = np.repeat(x[None], len(x) + 1, axis=0)
    for i, step in enumerate(np.asarray(steps, float)):
        up, down = hi[i] - x[i], x[i] - lo[i]
        out[i + 1, i] += min(step, up) if up >= step or up >= down else -min(step, down)
    return out


def simplex_polish(fun: Callable[[NDArray], float], x0: ArrayLike, steps: ArrayLike,
                   bounds: Sequence[tuple[float, float]], *, max_evals: int = 4000, max_seconds: float = 2.0,
                   xtol: float = 1e-9, ftol: float = 1e-10, max_runs: int = 8) -> SearchResult:
    """Minimise ``fun`` from ``x0`` by bounded Nelder–Mead runs, restarted until they stop improving.

    Parameters
    ----------
    fun : callable
        The objective (here the negative log posterior; ``inf`` outside the prior's support).
    x0 : array_like
        The start (the best grid point).
    steps : array_like
        The first simplex's edge per parameter, and every restart's (the grid's cell size).
    bounds : sequence of (float, float)
        The box the search stays in.
    max_evals : int
        Evaluations of ``fun`` over all runs.
    max_seconds : float
        Wall-clock time over all runs.
    xtol, ftol : float
        One run's convergence (:func:`scipy.optimize.minimize` Nelder–Mead ``xatol``, ``fatol``);
        ``ftol`` is also the smallest improvement for which a restart counts.
    max_runs : int
        Simplex runs at most (the first and its restarts).

    Returns
    -------
    SearchResult
    """
    lower = np.array([b[0] for b in bounds], float)
    upper = np.array([b[1] for b in bounds], float)
    x0 = np.clip(np.asarray(x0, float), lower, upper)
    deadline = time.perf_counter() + max_seconds
    state = {"n": 0, "x": x0, "f": float(fun(x0)), "why": "converged"}
    state["n"] = 1

    def counted(theta: NDArray) -> float:
        if state["n"] >= max_evals:
            state["why"] = "evaluations"
            raise _OutOfBudget
        if time.perf_counter() > deadline:
            state["why"] = "time"
            raise _OutOfBudget
        state["n"] += 1
        value = float(fun(theta))
        if value < state["f"]:
            state["x"], state["f"] = np.array(theta, float), value
        return value

    runs = 0
    # a run that crawls (a simplex creeping along a bound or a ridge) is cut at a quarter of the budget:
    # the restart's fresh simplex moves on where it stalled (one yes/no set used all 4,000 evaluations
    # in one run and stopped short; cut, it converged in 4 runs and 2,921)
    run_evals = max(RUN_EVALS_MIN, max_evals // 4)
    while runs < max_runs:
        runs += 1
        before = state["f"]
        try:
            res = optimize.minimize(counted, state["x"], method="Nelder-Mead", bounds=list(zip(lower, upper)),
                                    options={"initial_simplex": initial_simplex(state["x"], steps, lower, upper),
                                             "xatol": xtol, "fatol": ftol, "maxfev": run_evals, "maxiter": run_evals})
        except _OutOfBudget:
            break
        cut = res.status in (1, 2)  # the run's own cap, not its convergence
        if cut and runs == max_runs:
            state["why"] = "evaluations"
        if not cut and not before - state["f"] > ftol:
            break
    return SearchResult(state["x"], state["f"], state["n"], runs, state["why"])
