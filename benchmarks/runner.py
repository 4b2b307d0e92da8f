"""Benchmark: the cost of writing one trial durably, ours vs the usual alternatives.

    python benchmarks/runner.py [--trials 540] [--repeats 5]

A 540-trial ERP session (the row of ``protocols/erp_stylisation.yaml``, 22 columns) is
written trial by trial, each trial made crash-safe before the next one starts:

* ours (as the runner uses it): ``experiments.TsvWriter(fsync="background")`` - append one
  line and flush before returning (safe against a crash/SIGKILL of the process at once),
  ``os.fsync`` by a helper thread right after (the trial loop does not wait for the disk);
* ours, synchronous: the same with ``os.fsync`` before returning (bound by the disk's fsync
  latency: ~4 ms on this virtual disk);
* pandas: keep a DataFrame, rewrite the whole CSV after every trial (``to_csv``) + fsync;
* PsychoPy: ``data.ExperimentHandler`` - ``addData`` ... ``nextEntry`` then
  ``saveAsWideText`` after every trial (PsychoPy only saves at the end by default; saving
  every trial is what users do to not lose data) + fsync.

Prints the median cost per trial (over all trials and repeats), the worst trial, and the
ratio competitor / ours. Target: < 2 ms per trial for ours.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pandas as pd  # noqa: E402

from experiments import TsvWriter  # noqa: E402

COLUMNS = ["participant_id", "session", "trial", "phase", "block", "repetition", "stimulus", "character",
           "stylisation", "emotion", "fixation_frames", "fixation_onset_s", "onset_frame", "onset_s", "offset_s",
           "duration_frames", "shown_frames", "shown_s", "dropped_frames", "trigger", "trigger_s", "trigger_flip_ms"]


def _row(i: int) -> dict:
    return {"participant_id": "01", "session": 1, "trial": i + 1, "phase": "main", "block": "1", "repetition": 1 + i // 36,
            "stimulus": f"character-c1_stylisation-{i % 6}_emotion-angry.png", "character": "c1",
            "stylisation": i % 6, "emotion": "angry", "fixation_frames": 24 + i % 7, "fixation_onset_s": i * 1.05 + 0.6,
            "onset_frame": i * 63, "onset_s": i * 1.05, "offset_s": i * 1.05 + 0.6, "duration_frames": 36,
            "shown_frames": 36, "shown_s": 0.6, "dropped_frames": 0, "trigger": 11 + i % 6, "trigger_s": i * 1.05,
            "trigger_flip_ms": 0.05}


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def ours(folder: Path, n: int, fsync: str = "background") -> list[float]:
    times = []
    with TsvWriter(folder / "ours.tsv", COLUMNS, fsync=fsync) as w:
        for i in range(n):
            row = _row(i)
            t = time.perf_counter()
            w.write(row)
            times.append(time.perf_counter() - t)
    return times


def pandas_rewrite(folder: Path, n: int) -> list[float]:
    times, rows = [], []
    path = folder / "pandas.csv"
    for i in range(n):
        row = _row(i)
        t = time.perf_counter()
        rows.append(row)
        pd.DataFrame(rows, columns=COLUMNS).to_csv(path, index=False)
        _fsync(path)
        times.append(time.perf_counter() - t)
    return times


def psychopy_handler(folder: Path, n: int) -> list[float]:
    from psychopy import data, logging

    logging.console.setLevel(logging.CRITICAL)
    exp = data.ExperimentHandler(name="bench", savePickle=False, saveWideText=False,
                                 dataFileName=str(folder / "psychopy"))
    times = []
    for i in range(n):
        row = _row(i)
        t = time.perf_counter()
        for k, v in row.items():
            exp.addData(k, v)
        exp.nextEntry()
        exp.saveAsWideText(str(folder / "psychopy.tsv"), delim="\t", appendFile=False, fileCollisionMethod="overwrite")
        _fsync(folder / "psychopy.tsv")
        times.append(time.perf_counter() - t)
    exp.abort()
    return times


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=540)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    results: dict[str, list[float]] = {"ours (append+flush, background fsync)": [],
                                       "ours (append+flush+fsync, synchronous)": [], "pandas rewrite-per-trial": [],
                                       "PsychoPy ExperimentHandler save-per-trial": []}
    funcs = [ours, lambda f, n: ours(f, n, "sync"), pandas_rewrite, psychopy_handler]
    for _ in range(args.repeats):
        for (name, acc), fn in zip(results.items(), funcs):
            with tempfile.TemporaryDirectory() as d:
                acc.extend(fn(Path(d), args.trials))
    base = statistics.median(results["ours (append+flush, background fsync)"])
    print(f"writing one trial of a {args.trials}-trial session ({len(COLUMNS)} columns), {args.repeats} repeats")
    print(f"{'method':45s} {'median ms':>10s} {'p99 ms':>9s} {'max ms':>9s} {'ratio':>8s}")
    for name, ts in results.items():
        ts_sorted = sorted(ts)
        med = statistics.median(ts)
        p99 = ts_sorted[int(0.99 * (len(ts) - 1))]
        print(f"{name:45s} {med * 1e3:10.3f} {p99 * 1e3:9.3f} {max(ts) * 1e3:9.3f} {med / base:8.1f}x")
    print(f"target < 2 ms per trial (ours, median): {'met' if base < 0.002 else 'NOT met'}")


if __name__ == "__main__":
    main()
