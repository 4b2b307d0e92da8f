"""Benchmark: the full 4-way rm-ANOVA table (21 subjects × 2×5×5×5 = 5,250 rows), ours vs R.

    python benchmarks/anova.py [--repeats 7] [--statsmodels]

Ours: ``analysis.rm_anova`` on the long table (data checks + every effect with Mauchly,
GG/HF, pes, ges). R (when ``Rscript`` is on PATH): the same CSV, timed inside R with
``system.time`` over the same number of repeats, (a) the car pipeline a script would run:
``car::Anova(lm(wide ~ 1), idata, idesign, type = 3)`` + ``summary(multivariate = FALSE)``
on the wide matrix (reshaping included), (b) ``afex::aov_ez`` (what most analysts call).
Medians are printed with the ratio. statsmodels' AnovaRM (no sphericity statistics) takes
~100 s per fit for this design, so it only runs with ``--statsmodels`` (one repeat).
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis import rm_anova  # noqa: E402
from analysis.stats.simulate import exp2_design, simulate_ratings  # noqa: E402

R_SCRIPT = r"""
suppressPackageStartupMessages({library(car); library(afex)})
args <- commandArgs(trailingOnly = TRUE); d <- read.csv(args[1]); reps <- as.integer(args[2])
w <- c("character", "shape", "material", "expression")
for (f in c("participant_id", w)) d[[f]] <- factor(d[[f]])
car_pipeline <- function() {
  d <- d[order(d$participant_id, d$character, d$shape, d$material, d$expression), ]
  Y <- matrix(d$response_appeal, nrow = nlevels(d$participant_id), byrow = TRUE)
  idata <- expand.grid(expression = levels(d$expression), material = levels(d$material),
                       shape = levels(d$shape), character = levels(d$character))[, 4:1]
  fit <- lm(Y ~ 1)
  a <- car::Anova(fit, idata = idata, idesign = ~character * shape * material * expression, type = 3)
  summary(a, multivariate = FALSE)
}
afex_pipeline <- function() suppressMessages(aov_ez("participant_id", "response_appeal", d, within = w, type = 3,
                                                    anova_table = list(es = c("pes", "ges"))))
t_car <- sapply(seq_len(reps), function(i) system.time(car_pipeline())[["elapsed"]])
t_afex <- sapply(seq_len(reps), function(i) system.time(afex_pipeline())[["elapsed"]])
cat(sprintf("car %.6f\nafex %.6f\n", median(t_car), median(t_afex)))
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--statsmodels", action="store_true", help="also time statsmodels AnovaRM once (~100 s)")
    args = ap.parse_args()
    factors, scales = exp2_design()
    data = simulate_ratings(factors, scales, n_subjects=21, seed=0)
    within = list(factors)
    print(f"design: 21 subjects x {' x '.join(str(len(v)) for v in factors.values())} = {len(data)} rows")
    rm_anova(data, "response_appeal", "participant_id", within)  # warm-up (imports)
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        table = rm_anova(data, "response_appeal", "participant_id", within)
        times.append(time.perf_counter() - t0)
    ours = statistics.median(times)
    print(f"ours (analysis.rm_anova, {len(table)} effects, median of {args.repeats}): {ours * 1e3:.1f} ms")

    if shutil.which("Rscript"):
        with tempfile.TemporaryDirectory() as tmp:
            csv = Path(tmp) / "d.csv"
            data.to_csv(csv, index=False)
            script = Path(tmp) / "bench.R"
            script.write_text(R_SCRIPT)
            res = subprocess.run(["Rscript", str(script), str(csv), str(args.repeats)], capture_output=True,
                                 text=True, check=False)
            if res.returncode != 0:
                print("R failed:", res.stderr.strip().splitlines()[-1:])
            else:
                r = dict(line.split() for line in res.stdout.strip().splitlines())
                for name, label in (("car", "R car::Anova + summary (wide matrix)"), ("afex", "R afex::aov_ez")):
                    t = float(r[name])
                    print(f"{label}, median of {args.repeats}: {t * 1e3:.1f} ms  -> ours is {t / ours:.1f}x faster")
    else:
        print("R: skipped (Rscript not found)")

    if args.statsmodels:
        from statsmodels.stats.anova import AnovaRM

        t0 = time.perf_counter()
        AnovaRM(data, "response_appeal", "participant_id", within=within).fit()
        t = time.perf_counter() - t0
        print(f"statsmodels AnovaRM (1 run, no sphericity statistics): {t:.1f} s -> ours is {t / ours:.0f}x faster")
    else:
        print("statsmodels AnovaRM: skipped (about 100 s per fit for this design, and it has no Mauchly/GG/HF; "
              "run with --statsmodels to time it)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
