"""What psignifit 4 gives on a set of 2AFC data sets: its MAP, its posterior's true mode, its 95 %
credible intervals on its default grid and on a 400-step grid (the reference for the intervals).

psignifit (PyPI, GPL-3) is a test dependency of Appeal Lab, never imported by the package. Run by
hand where it is installed and commit the output beside this script:

    python tests/py_reference/psignifit_agreement.py > tests/py_reference/psignifit_agreement.out

Per data set (the four of tests/test_psychometric.py's PSIGNIFIT_CASES that are 2AFC, eight fresh
simulated ones and the set on which the simplex once stalled, issue 52):

* ``map``: psignifit's printed MAP (``parameter_estimate_MAP``: its ``scipy.optimize.fmin`` from
  the best grid point, stopping at xtol = ftol = 1e-4);
* ``mode``: the maximum of psignifit's own log posterior (``psignifit._posterior.log_posterior``),
  found from ``map`` by bounded Nelder–Mead runs at xatol 1e-10, restarted until no restart
  improves it by 1e-12;
* ``ci``: psignifit's 95 % intervals of threshold and width on its default grid, and ``step``
  that grid's spacing; ``ci_fine``: the intervals with 400 grid points on the parameter itself
  (``grid_steps``), the nearest there is to the posterior's true quantiles.

tests/test_psychometric.py compares ``fit_bayes`` with these numbers on every run.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

#: The data set on which fit_bayes's simplex used to stall (issue 52): norm, 2AFC.
STALLED = [[0.05, 35, 60], [0.1, 34, 60], [0.15, 35, 60], [0.2, 37, 60], [0.3, 45, 60], [0.4, 52, 60],
           [0.55, 59, 60], [0.7, 60, 60], [0.85, 60, 60], [1.0, 60, 60]]


def data_sets() -> dict[str, tuple[str, list[list[float]]]]:
    """``{name: (family, rows)}``: level, correct, trials (2AFC)."""
    from test_psychometric import PSIGNIFIT_CASES, _psignifit_case

    from appeal.psychophysics.observers import SimulatedObserver, constant_stimuli

    out = {f"{f}-2": (f, _psignifit_case(f, n).tolist()) for f, n in PSIGNIFIT_CASES if n == 2 and f != "weibull"}
    rng = np.random.default_rng(52)
    for i in range(8):
        family = ("logistic", "norm")[i % 2]
        m, w, lam = rng.uniform(0.3, 0.7), rng.uniform(0.15, 0.6), rng.choice([0.0, 0.02, 0.05])
        obs = SimulatedObserver(m, w, lam, 0.5, family, seed=100 + i)
        out[f"fresh{i}-{family}"] = (family, constant_stimuli(obs, np.linspace(0.05, 1.0, 8), 40).tolist())
    out["stalled-norm"] = ("norm", STALLED)
    return out


def psignifit_numbers(family: str, rows: list[list[float]]) -> dict:
    import psignifit as ps
    from psignifit._posterior import log_posterior
    from scipy import optimize

    d = np.asarray(rows, float)
    res = ps.psignifit(d, sigmoid=family, experiment_type="2AFC", debug=True)
    names = ("threshold", "width", "lambda", "eta")
    est = dict(res.parameter_estimate_MAP)
    lo = {k: float(np.min(v)) for k, v in res.parameter_values.items()}
    hi = {k: float(np.max(v)) for k, v in res.parameter_values.items()}
    bounds = [(lo[k], hi[k]) for k in names]

    def neg(theta: np.ndarray) -> float:
        grid = {**{k: np.array([v]) for k, v in zip(names, theta)}, "gamma": np.array([0.5])}
        grid["eta"] = np.array([max(float(theta[3]), 1e-12)])
        v = float(np.asarray(log_posterior(d, res.configuration.make_sigmoid(), res.debug["priors"], grid)).squeeze())
        return -v if np.isfinite(v) else np.inf

    x = np.clip([float(est[k]) for k in names], [b[0] for b in bounds], [b[1] for b in bounds])
    f = neg(x)
    for _ in range(20):
        r = optimize.minimize(neg, x, method="Nelder-Mead", bounds=bounds,
                              options={"xatol": 1e-10, "fatol": 1e-13, "maxfev": 20000, "maxiter": 20000})
        if not f - r.fun > 1e-12:
            break
        x, f = r.x, r.fun
    out = {"family": family, "data": rows,
           "map": {k: float(est[k]) for k in ("threshold", "width")},
           "mode": {k: float(v) for k, v in zip(("threshold", "width"), x[:2])},
           "ci": {k: [float(v) for v in res.confidence_intervals[k]["0.95"]] for k in ("threshold", "width")},
           "step": {k: float(np.diff(res.parameter_values[k][:2])[0]) for k in ("threshold", "width")},
           "ci_fine": {}}
    for k in ("threshold", "width"):
        fine = ps.psignifit(d, sigmoid=family, experiment_type="2AFC", grid_steps={k: 400})
        out["ci_fine"][k] = [float(v) for v in fine.confidence_intervals[k]["0.95"]]
    return out


def main() -> None:
    from importlib.metadata import version

    out = {name: psignifit_numbers(family, rows) for name, (family, rows) in data_sets().items()}
    print(f"# psignifit {version('psignifit')}: MAP, posterior mode, 95 % intervals (default grid, 400 steps)")
    print(f"PSIGNIFIT_AGREEMENT = {out!r}")


if __name__ == "__main__":
    main()
