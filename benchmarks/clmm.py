"""Benchmark: a cumulative-link mixed model of 7-point ratings, ours vs R's ordinal::clmm.

    python benchmarks/clmm.py [--participants 40] [--stimuli 50] [--repeats 3]

The design: 40 participants × 50 stimuli × shape (2) × material (2) = 8,000 ratings (logit link),
``rating ~ shape * material + (1 | participant) + (1 | stimulus)`` (crossed random intercepts).
Ours: :func:`analysis.stats.clmm.fit_clmm` from the table to the fitted model with its Hessian
(standard errors, cond.H), as ``clmm(..., Hess = TRUE)`` (its default) returns. R (when
``Rscript`` is on PATH): ``ordinal::clmm`` with its default settings on the same CSV, timed inside
R with ``system.time`` over the same number of repeats. Medians are printed with the ratio, and
how far apart the two fits are (R's defaults stop at max|grad| ~ 1e-3, so ~1e-4 is expected).
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis.stats.clmm import fit_clmm  # noqa: E402

FORMULA = "rating ~ shape * material + (1 | participant) + (1 | stimulus)"
R_SCRIPT = r"""
suppressPackageStartupMessages(library(ordinal))
options(contrasts = c("contr.sum", "contr.poly"))
args <- commandArgs(trailingOnly = TRUE); d <- read.csv(args[1]); reps <- as.integer(args[2])
for (f in c("participant", "stimulus", "shape", "material"))
  d[[f]] <- factor(as.character(d[[f]]), levels = sort(unique(as.character(d[[f]])), method = "radix"))
d$rating <- factor(d$rating, ordered = TRUE)
fit <- NULL
t <- sapply(seq_len(reps), function(i) system.time(
  fit <<- clmm(rating ~ shape * material + (1 | participant) + (1 | stimulus), data = d))[["elapsed"]])
cat(sprintf("time %.6f\nloglik %.10f\nmaxgrad %.3g\n", median(t), fit$logLik, max(abs(fit$gradient))))
sd <- sapply(VarCorr(fit), function(v) attr(v, "stddev")[[1]])
cat(sprintf("coef %s\n", paste(sprintf("%.10f", c(coef(fit), sd[c("participant", "stimulus")])), collapse = ",")))
"""


def simulate(n_participants: int, n_stimuli: int, seed: int = 0) -> pd.DataFrame:
    """Logistic latent ratings cut into 7 categories; participant and stimulus intercepts."""
    rng = np.random.default_rng(seed)
    p, s, sh, ma = np.meshgrid(np.arange(n_participants), np.arange(n_stimuli), [0, 1], [0, 1], indexing="ij")
    p, s, sh, ma = p.ravel(), s.ravel(), sh.ravel(), ma.ravel()
    eta = 0.5 * sh + 0.3 * ma - 0.2 * sh * ma + rng.normal(0, 0.8, n_participants)[p] + rng.normal(0, 0.4, n_stimuli)[s]
    cuts = np.array([-2.0, -1.1, -0.3, 0.5, 1.3, 2.2])
    rating = 1 + np.searchsorted(cuts, eta + rng.logistic(size=len(eta)))
    return pd.DataFrame({"participant": [f"p{i:02d}" for i in p], "stimulus": [f"f{i:03d}" for i in s],
                         "shape": np.where(sh == 1, "stylised", "realistic"),
                         "material": np.where(ma == 1, "glossy", "matte"),
                         "rating": rating})


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=40)
    ap.add_argument("--stimuli", type=int, default=50)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    data = simulate(args.participants, args.stimuli)
    print(f"design: {args.participants} participants x {args.stimuli} stimuli x 2 x 2 = {len(data)} ratings; {FORMULA}")
    fit_clmm(FORMULA, simulate(6, 5, seed=1))  # warm-up (imports)
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        fit = fit_clmm(FORMULA, data)
        times.append(time.perf_counter() - t0)
    ours = statistics.median(times)
    print(f"ours (analysis.stats.clmm.fit_clmm, median of {args.repeats}): {ours:.3f} s  "
          f"(logLik {fit.loglik:.6f}, max|grad| {fit.max_grad:.1e}, {fit.n_evals} evaluations)")

    if not shutil.which("Rscript"):
        print("R: skipped (Rscript not found)")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "d.csv"
        data.to_csv(csv, index=False)
        script = Path(tmp) / "bench.R"
        script.write_text(R_SCRIPT)
        res = subprocess.run(["Rscript", str(script), str(csv), str(args.repeats)], capture_output=True, text=True,
                             check=False)
    if res.returncode != 0:
        print("R failed:", res.stderr.strip().splitlines()[-1:])
        return 1
    r = dict(line.split(" ", 1) for line in res.stdout.strip().splitlines())
    t = float(r["time"])
    print(f"R ordinal::clmm (default settings, median of {args.repeats}): {t:.3f} s  (logLik {float(r['loglik']):.6f}, "
          f"max|grad| {float(r['maxgrad']):.1e})  -> Python/R = {ours / t:.3f} (ours {t / ours:.0f}x faster)")
    ref = np.array([float(v) for v in r["coef"].split(",")])
    mine = np.concatenate([fit.theta, fit.beta, fit.tau])
    print(f"agreement: |logLik difference| {abs(fit.loglik - float(r['loglik'])):.2e}, "
          f"max |parameter difference| {np.max(np.abs(mine - ref)):.2e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
