"""Planning with simulated observers: how many trials a procedure needs for a given precision.

Before a study, run the procedure many times against a simulated observer with the
psychometric function one expects (:class:`~appeal.psychophysics.SimulatedObserver`) and read
off the trials it takes until the threshold's 95 % credible interval is as narrow as wanted —
for the psi method from its own posterior (it stops there by ``max_ci_width``), for the method
of constant stimuli from a Bayesian fit (:func:`~analysis.psychometric.fit.fit_bayes`) after each
pass over the levels — and how often that interval holds the observer's true threshold.

Example
-------
>>> from appeal.psychophysics import SimulatedObserver
>>> obs = SimulatedObserver(threshold=0.3, width=0.4, lapse=0.02)
>>> levels = [round(0.05 * k, 2) for k in range(1, 21)]
>>> table = trials_for_precision("psi", obs, levels, target_width=0.15, n_sessions=5, seed=1)
>>> list(table.columns)
['method', 'session', 'n_trials', 'ci_width', 'reached', 'covered']
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from analysis.psychometric.fit import fit_bayes
from analysis.stats.anova import single_thread_blas
from appeal.errors import AppealInputError
from appeal.psychophysics import ConstantStimuli, PsiProcedure, SimulatedObserver, run_procedure

__all__ = ["trials_for_precision", "precision_summary", "PLANNING_GRID"]

#: The Bayesian fit's grid for planning (psignifit's 40 x 40 x 20 x 20 is slower; the intervals on this
#: one differed from the full grid's by 0.1-5 % of their width on simulated 2AFC data). Planning fits
#: skip the MAP search (``refine_map=False``): only the threshold's interval is used.
PLANNING_GRID = {"threshold": 30, "width": 20, "lambda": 10, "eta": 10}


def _psi_session(observer: SimulatedObserver, levels: Sequence[float], target_width: float, max_trials: int,
                 min_trials: int) -> tuple[int, float, bool]:
    proc = PsiProcedure(levels, guess=observer.guess, family=observer.family, max_trials=max_trials,
                        max_ci_width=target_width, min_trials=min_trials)
    run_procedure(proc, observer)
    e = proc.estimate()
    return proc.n_trials, e["threshold_hi"] - e["threshold_lo"], e["threshold_lo"] <= observer.threshold <= e["threshold_hi"]


def _constant_session(observer: SimulatedObserver, levels: Sequence[float], target_width: float, max_trials: int,
                      seed: int, grid_steps: Mapping[str, int] | None) -> tuple[int, float, bool]:
    """Passes of constant stimuli (every level once a pass), fitted after passes 3, 4, 6, 8, 11 …
    (about 1.4 times more each time), until the threshold's interval is narrow enough."""
    per_pass = len(levels)
    passes = max(1, max_trials // per_pass)
    checks = {int(round(3 * 1.4 ** k)) for k in range(40)} | {passes}
    proc = ConstantStimuli(levels, passes, seed=seed)
    k = 0
    width, covered = float("inf"), False
    while not proc.finished:
        for _ in range(per_pass):
            x = proc.next_level()
            proc.update(x, observer.respond(x))
        k += 1
        if k not in checks:
            continue
        hist = np.array(proc.history, float)
        xs = np.unique(hist[:, 0])
        data = np.array([[x, hist[hist[:, 0] == x, 1].sum(), (hist[:, 0] == x).sum()] for x in xs])
        fit = fit_bayes(data, family=observer.family, nafc=round(1 / observer.guess) if observer.guess else None,
                        grid_steps=grid_steps, refine_map=False)
        lo, hi = fit.ci["threshold"]
        width, covered = hi - lo, lo <= observer.threshold <= hi
        if width <= target_width:
            break
    return proc.n_trials, width, covered


def trials_for_precision(method: str, observer: SimulatedObserver, levels: Sequence[float], *,
                         target_width: float, n_sessions: int = 50, max_trials: int = 600, min_trials: int = 10,
                         seed: int = 0, grid_steps: Mapping[str, int] | None = None) -> pd.DataFrame:
    """Simulated sessions of ``method`` until the threshold's 95 % interval is ``target_width`` wide.

    Parameters
    ----------
    method : {"psi", "constant"}
        The psi method, or the method of constant stimuli (every level once per pass).
    observer : SimulatedObserver
        The expected observer (its ``rng`` is reseeded per session from ``seed``).
    levels : sequence of float
        The increasing levels the procedure may show (e.g. the differences of a continuum).
    target_width : float
        The interval width wanted, in units of the levels.
    n_sessions : int
        Simulated sessions.
    max_trials : int
        A session stops here if the width is not reached (``reached`` is then False).
    min_trials : int
        psi: trials before the width may stop a session.
    seed : int
        Seed of the sessions.
    grid_steps : mapping, optional
        constant: the Bayesian fit's grid (default :data:`PLANNING_GRID`).

    Returns
    -------
    pandas.DataFrame
        One row per session: ``method``, ``session``, ``n_trials``, ``ci_width``, ``reached``
        (the width was reached) and ``covered`` (the final interval holds the true threshold).
    """
    if method not in ("psi", "constant"):
        raise AppealInputError(f"method: expected 'psi' or 'constant' (got '{method}')")
    if not target_width > 0:
        raise AppealInputError(f"target_width: expected a positive width (got {target_width})")
    with single_thread_blas():
        rows = [_session(method, observer, levels, target_width, max_trials, min_trials, seed, s,
                         grid_steps or PLANNING_GRID) for s in range(n_sessions)]
    return pd.DataFrame(rows)


def _session(method: str, observer: SimulatedObserver, levels: Sequence[float], target_width: float, max_trials: int,
             min_trials: int, seed: int, s: int, grid_steps: Mapping[str, int]) -> dict[str, object]:
    """One simulated session (number ``s``) as a row of :func:`trials_for_precision`'s table."""
    observer.rng = np.random.default_rng([seed, s])
    if method == "psi":
        n, width, covered = _psi_session(observer, levels, target_width, max_trials, min_trials)
    else:
        n, width, covered = _constant_session(observer, levels, target_width, max_trials, seed + s, grid_steps)
    return {"method": method, "session": s + 1, "n_trials": n, "ci_width": width,
            "reached": bool(width <= target_width), "covered": bool(covered)}


def precision_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per method: median and 90th-percentile trials, the share of sessions reaching the width,
    and the interval's coverage of the true threshold."""
    g = table.groupby("method")
    return pd.DataFrame({"sessions": g.size(), "median_trials": g["n_trials"].median(),
                         "p90_trials": g["n_trials"].quantile(0.9), "reached": g["reached"].mean(),
                         "coverage": g["covered"].mean()}).reset_index()
