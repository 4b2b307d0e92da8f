"""Sparse SPD solvers of the 3D correspondence: CHOLMOD (cvxopt) vs SciPy's SuperLU.

The matrices are the real ones of the synthetic 19k -> 10k pair (``synthetic_pair(16800,
15000)``): the first joint-fairing matrix (29k unknowns, source and target coupled by the
correspondences) and the first base-registration matrix (19k unknowns), captured from one
``correspond`` run. For each: SuperLU with MMD on AᵀA+A (SciPy's usual way), SuperLU with the
ordering the pipeline gives it, CHOLMOD's first factorisation (symbolic + numeric) and its
numeric-only refactorisation (what the pipeline does after the first), and the solve of
three right-hand sides (x/y/z). Then the whole correspondence with each backend.

Medians of ``--repeats``; CPU (process) seconds beside wall seconds because the development
machine is shared. Set OPENBLAS_NUM_THREADS=1 for single-threaded numbers.

Run: .venv/bin/python benchmarks/sparse_solvers.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import stimulus_engine.correspondence.solve as solve_mod  # noqa: E402
from stimulus_engine.correspondence import correspond  # noqa: E402
from stimulus_engine.correspondence.ordering import nested_dissection  # noqa: E402
from stimulus_engine.correspondence.solve import available_backends, factorize  # noqa: E402
from stimulus_engine.correspondence.synthetic import synthetic_pair  # noqa: E402


def timed(fn, repeats):
    """Median wall and CPU seconds of ``repeats`` calls, and the last result."""
    wall, cpu, out = [], [], None
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return statistics.median(wall), statistics.median(cpu), out


def capture_matrices(src, tgt, corr):
    """The first matrix each solver of one ``correspond`` run factorises."""
    seen = []
    original = solve_mod.factorize

    def recording(matrix, ordering=None, backend=None):
        seen.append(matrix)
        return original(matrix, ordering, backend)

    solve_mod.factorize = recording
    try:
        correspond(src, tgt, corr)
    finally:
        solve_mod.factorize = original
    return seen


def main() -> None:
    sys.stdout.reconfigure(line_buffering=True)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    if "cholmod" not in available_backends():
        print("cvxopt is not installed (pip install 'appeal-lab[fast]'): nothing to compare")
        return
    src, tgt, corr = synthetic_pair(16800, 15000)
    mats = capture_matrices(src, tgt, corr)
    fairing = next(m for m in mats if m.shape[0] > len(src.vertices))  # source + cropped target
    registration = next(m for m in mats if m.shape[0] == len(src.vertices))
    rng = np.random.default_rng(0)
    print(f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', '(unset)')}")
    print(f"{'matrix':32s} {'method':34s} {'wall s':>8s} {'CPU s':>8s} {'solve3 ms':>10s} {'residual':>9s}")
    for name, h, coords in (
        (f"fairing {fairing.shape[0]} (nnz {fairing.nnz})", fairing, None),
        (f"registration {registration.shape[0]} (nnz {registration.nnz})", registration, np.asarray(src.vertices)),
    ):
        b = rng.normal(size=(h.shape[0], 3))
        rows = {}
        methods = [("SuperLU, MMD(AᵀA+A)", lambda h=h: factorize(h, backend="superlu"))]
        if coords is not None:
            order = nested_dissection(h, coords)
            methods.append(("SuperLU, nested dissection", lambda h=h, o=order: factorize(h, o, backend="superlu")))
        methods.append(("CHOLMOD, symbolic + numeric", lambda h=h: factorize(h, backend="cholmod")))
        base = factorize(h, backend="cholmod")
        methods.append(("CHOLMOD, numeric refactorisation", lambda h=h, f=base: f.refactor(h)))
        for label, fn in methods:
            w, c, f = timed(fn, a.repeats)
            ws, _, x = timed(lambda f=f: f.solve(b), a.repeats)
            res = float(np.abs(h @ x - b).max() / np.abs(b).max())
            rows[label] = w
            print(f"{name:32s} {label:34s} {w:8.3f} {c:8.3f} {ws * 1000:10.1f} {res:9.1e}")
        ref = rows["SuperLU, MMD(AᵀA+A)"]
        print(f"{'':32s} ratio SuperLU(MMD) / CHOLMOD: first {ref / rows['CHOLMOD, symbolic + numeric']:.1f}x, "
              f"refactorisation {ref / rows['CHOLMOD, numeric refactorisation']:.1f}x")

    print(f"\nwhole correspondence {len(src.vertices)} -> {len(tgt.vertices)} (medians; 'total' excludes the metrics):")
    totals = {}
    for backend in ("superlu", "cholmod"):
        os.environ["APPEAL_SPARSE_SOLVER"] = backend
        wall, cpu, runs = [], [], []
        for _ in range(a.repeats):
            t, c0 = time.perf_counter(), time.process_time()
            runs.append(correspond(src, tgt, corr))
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c0)
        w, c, res = statistics.median(wall), statistics.median(cpu), runs[-1]
        totals[backend] = statistics.median(r.seconds["total"] for r in runs)
        stages = ", ".join(f"{k} {v:.2f}" for k, v in res.seconds.items() if k not in ("total",))
        print(f"  {backend:8s} call {w:.2f} s (CPU {c:.2f} s), pipeline total {totals[backend]:.2f} s; "
              f"Hausdorff {res.metrics['hausdorff_rel']:.4%}; {stages}")
    os.environ.pop("APPEAL_SPARSE_SOLVER", None)
    print(f"  ratio superlu / cholmod (pipeline total): {totals['superlu'] / totals['cholmod']:.2f}x")


if __name__ == "__main__":
    main()
