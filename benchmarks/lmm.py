"""Benchmark: a crossed linear mixed model (40 participants × 250 stimuli, by-participant random
slopes) fitted and tested (type-III table with Satterthwaite dfs), ours vs lme4 + lmerTest.

    python benchmarks/lmm.py [--repeats 5] [--mixedlm] [--command]

Two designs, both 10,000 rows, ``rating ~ shape + (1 + shape | participant) + (1 | stimulus)``
(shape: 3 levels, a property of each stimulus): *typical* (well-separated variance components)
and *near-singular* (the participant slopes almost collinear with the intercepts, a stimulus SD
near zero — what makes lme4 slow). Ours: :func:`analysis.stats.lmm.fit_lmm` +
:func:`analysis.stats.lmm_anova.lmm_anova` (Satterthwaite). R (when ``Rscript`` is on PATH):
``lmerTest::lmer`` (which also prepares the Satterthwaite derivatives) + ``anova(m, type = 3)``
on the same CSV, timed inside R with ``system.time``. Medians over the repeats and the ratio
ours / R are printed; the target is ≤ 0.5. ``--mixedlm`` also times the Rust-core ``mixedlm``
package (``lmer`` + ``anova(type=3)``), when installed. ``--command`` also times the whole
``appeal analyze lmm`` command as a fresh process (imports, reading the CSV, fit, tables) beside
``Rscript`` doing the same with lmerTest, interleaved, medians.
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

from analysis.stats.lmm import fit_lmm  # noqa: E402
from analysis.stats.lmm_anova import lmm_anova  # noqa: E402

FORMULA = "rating ~ shape + (1 + shape | participant) + (1 | stimulus)"
R_SCRIPT = r"""
suppressPackageStartupMessages({library(lmerTest)})
options(contrasts = c("contr.sum", "contr.poly"))
args <- commandArgs(trailingOnly = TRUE); d <- read.csv(args[1]); reps <- as.integer(args[2])
for (f in c("participant", "stimulus", "shape")) d[[f]] <- factor(d[[f]])
run <- function() { m <- lmerTest::lmer(rating ~ shape + (1 + shape | participant) + (1 | stimulus), data = d)
                    list(m = m, a = anova(m, type = 3)) }
times <- sapply(seq_len(reps), function(i) system.time(r <- run())[["elapsed"]])
r <- run()
cat(sprintf("time %.6f\nF %.10g\nddf %.10g\nsingular %d\nreml %.10f\n", median(times), r$a[["F value"]][1],
            r$a$DenDF[1], as.integer(isSingular(r$m)), REMLcrit(r$m)))
"""


def simulate(kind: str, seed: int = 0, n_participants: int = 40, n_stimuli: int = 250) -> pd.DataFrame:
    """One crossed design: every participant rates every stimulus once."""
    rng = np.random.default_rng(seed)
    d = pd.DataFrame([(f"p{p:02d}", f"s{s:03d}") for p in range(n_participants) for s in range(n_stimuli)],
                     columns=["participant", "stimulus"])
    p_idx = np.repeat(np.arange(n_participants), n_stimuli)
    s_idx = np.tile(np.arange(n_stimuli), n_participants)
    shape = s_idx % 3
    d["shape"] = shape
    u = rng.normal(0, 0.8, n_participants)
    if kind == "typical":
        slopes = rng.normal(0, 0.4, (n_participants, 3))
        w = rng.normal(0, 0.5, n_stimuli)
    else:  # slopes nearly a multiple of the intercepts, almost no stimulus variance
        slopes = 0.6 * u[:, None] * np.array([-1, 0, 1]) + rng.normal(0, 0.02, (n_participants, 3))
        w = rng.normal(0, 0.02, n_stimuli)
    d["rating"] = 4 + 0.4 * (shape - 1) + u[p_idx] + slopes[p_idx, shape] + w[s_idx] + rng.normal(0, 1, len(d))
    return d


def ours(d: pd.DataFrame) -> tuple[float, dict]:
    t = time.perf_counter()
    m = fit_lmm(FORMULA, d, factors=["participant", "stimulus", "shape"])
    a = lmm_anova(m)
    return time.perf_counter() - t, {"F": a.F[0], "ddf": a.den_df[0], "singular": m.singular, "reml": m.deviance}


def with_mixedlm(d: pd.DataFrame) -> float:
    import mixedlm

    d = d.assign(shape=d["shape"].astype(str))
    t = time.perf_counter()
    m = mixedlm.lmer(FORMULA, d)
    mixedlm.anova_type3(m, ddf_method="Satterthwaite")
    return time.perf_counter() - t


def whole_command(csv: Path, repeats: int, rscript: str | None) -> None:
    """Time ``appeal analyze lmm`` as a user runs it (a fresh process: imports, reading, fit, tables), and
    ``Rscript`` doing the same with lmerTest when R is there; medians of ``repeats`` runs, interleaved."""
    appeal = str(Path(sys.executable).with_name("appeal"))
    ours_cmd = [appeal, "analyze", "lmm", str(csv), "--formula", FORMULA, "--factors", "shape"]
    r_cmd = [rscript, "-e", "suppressPackageStartupMessages(library(lmerTest)); options(contrasts = c('contr.sum', "
             f"'contr.poly')); d <- read.csv('{csv}'); for (f in c('participant', 'stimulus', 'shape')) "
             f"d[[f]] <- factor(d[[f]]); m <- lmer({FORMULA}, data = d); print(anova(m, type = 3)); "
             "print(summary(m))"] if rscript else None
    times: dict[str, list[float]] = {"appeal analyze lmm": [], "Rscript lmerTest": []}
    for _ in range(repeats):
        for name, cmd in (("appeal analyze lmm", ours_cmd), ("Rscript lmerTest", r_cmd)):
            if cmd is None:
                continue
            t = time.perf_counter()
            subprocess.run(cmd, capture_output=True, check=True)
            times[name].append(time.perf_counter() - t)
    med = {k: statistics.median(v) for k, v in times.items() if v}
    print("  whole command, median of %d: %s (runs %s)" % (
        repeats, ", ".join(f"{k} {v:.2f} s" for k, v in med.items()),
        "; ".join(f"{k}: " + " ".join(f"{x:.2f}" for x in v) for k, v in times.items() if v)))
    if len(med) == 2:
        print(f"  ratio ours / R = {med['appeal analyze lmm'] / med['Rscript lmerTest']:.2f}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--mixedlm", action="store_true", help="also time the mixedlm package")
    ap.add_argument("--command", action="store_true",
                    help="also time the whole `appeal analyze lmm` command as a process (issue 52: <= 1.5 s)")
    args = ap.parse_args()
    rscript = shutil.which("Rscript")
    ok = True
    for kind in ("typical", "near-singular"):
        d = simulate(kind)
        if args.command:
            with tempfile.TemporaryDirectory() as tmp:
                d.to_csv(Path(tmp) / "d.csv", index=False)
                whole_command(Path(tmp) / "d.csv", args.repeats, rscript)
        runs = [ours(d) for _ in range(args.repeats)]
        t_ours = statistics.median(r[0] for r in runs)
        res = runs[-1][1]
        print(f"{kind}: {len(d)} rows; ours {t_ours:.3f} s (F = {res['F']:.6g}, ddf = {res['ddf']:.6g}, "
              f"singular = {res['singular']}, REML criterion {res['reml']:.6f})")
        if args.mixedlm:
            try:
                t_m = statistics.median(with_mixedlm(d) for _ in range(args.repeats))
                print(f"  mixedlm {t_m:.3f} s")
            except Exception as exc:  # noqa: BLE001 - a competitor's failure is reported, not fatal
                print(f"  mixedlm failed: {type(exc).__name__}: {str(exc).splitlines()[0][:120]}")
        if not rscript:
            print("  Rscript not found: install with `make r-deps` to compare")
            continue
        with tempfile.TemporaryDirectory() as tmp:
            csv, script = Path(tmp) / "d.csv", Path(tmp) / "bench.R"
            d.to_csv(csv, index=False)
            script.write_text(R_SCRIPT)
            out = subprocess.run([rscript, str(script), str(csv), str(args.repeats)], capture_output=True, text=True,
                                 check=True).stdout
        r = dict(line.split(" ", 1) for line in out.strip().splitlines())
        t_r = float(r["time"])
        ratio = t_ours / t_r
        ok &= ratio <= 0.5
        print(f"  lme4 + lmerTest {t_r:.3f} s (F = {float(r['F']):.6g}, ddf = {float(r['ddf']):.6g}, "
              f"singular = {bool(int(r['singular']))}, REML criterion {float(r['reml']):.6f}); ratio ours / R = {ratio:.2f} (target <= 0.5)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
