"""Benchmark: one 128-channel, 2048 Hz, 10-minute BioSemi recording through the scalp pipeline.

Runs ``analysis.erp.process_subject`` (ours, source summaries off) and the same steps written
directly in MNE (:func:`plain_mne`) on the same simulated BDF file, each in a fresh process
so peak memory is measured per run; prints the median times, the ratio and peak memory, and
checks that both give the same window means.

Peak memory is the worker's ``VmHWM`` (Linux ``/proc/self/status``): ``ru_maxrss`` of a child
started with ``subprocess`` starts from the parent's high-water mark (Linux carries it across
fork + exec), so it reported the ~6 GB this script needs to *simulate* the recording for both
pipelines alike.

    .venv/bin/python benchmarks/erp.py [--minutes 10] [--repeats 3] [--sfreq 2048]

Targets (issue 8): ours <= 90 s, <= 6 GB peak, overhead <= 20 % over plain MNE.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

EOG = ["EXG1", "EXG2", "EXG3", "EXG4"]


def plain_mne(path, events_map: dict, components: dict, bads=(), *, highpass=0.16, lowpass=30.0, reject_uV=120.0,
              tmin=-0.1, tmax=0.6) -> dict:
    """The thesis's scalp steps written directly in MNE (what an analyst would script).

    Returns
    -------
    dict
        (cell, component, cluster) -> mean amplitude in µV.
    """
    import mne

    raw = mne.io.read_raw_bdf(path, preload=True, verbose="error")
    events = mne.find_events(raw, stim_channel="Status", shortest_event=1, mask=0xFFFF, mask_type="and",
                             verbose="error")
    raw.set_channel_types({c: "eog" for c in EOG}, verbose="error")
    raw.set_montage("biosemi128", verbose="error")
    raw.filter(highpass, None, picks=["eeg", "eog"], phase="minimum", verbose="error")
    raw.filter(None, lowpass, picks=["eeg", "eog"], verbose="error")
    raw.set_eeg_reference("average", verbose="error")
    mne.preprocessing.EOGRegression(picks="eeg", picks_artifact="eog").fit(raw).apply(raw, copy=False)
    if bads:
        raw.info["bads"] = list(bads)
        raw.interpolate_bads(reset_bads=True, verbose="error")
        raw.set_eeg_reference("average", verbose="error")
    event_id = {f"code{c}": int(c) for c in sorted(set(events[:, 2]) & set(events_map))}
    events = events[np.isin(events[:, 2], list(event_id.values()))]
    epochs = mne.Epochs(raw, events, event_id, tmin, tmax, baseline=(tmin, 0.0), picks="eeg", preload=True,
                        verbose="error")
    del raw
    data = epochs.get_data(copy=False)
    epochs.drop(np.flatnonzero(np.abs(data).max(axis=(1, 2)) > reject_uV * 1e-6), verbose="error")
    out = {}
    cells = sorted({tuple(v.values()) for v in events_map.values()}, key=str)
    for cell in cells:
        names = [f"code{c}" for c, lv in events_map.items() if tuple(lv.values()) == cell and f"code{c}" in event_id]
        if not names or not len(epochs[names]):
            continue
        evoked = epochs[names].average()
        for comp, (window, clusters) in components.items():
            for cname, chans in clusters.items():
                win = evoked.copy().crop(window[0], window[1])  # both ends included
                out[(cell, comp, cname)] = float(win.get_data(picks=chans).mean() * 1e6)
    return out


def _config(path: Path):
    from analysis.erp.simulate import SimulationDesign
    from analysis.erp_schema import ErpConfig

    events = {int(c): lv for c, lv in SimulationDesign().events.items()}
    return ErpConfig(kind="erp", recordings=path, events=events, eog=EOG, source={"enabled": False},
                     bad_channels={"detect": False})


def _components(cfg, ch_names):
    from analysis.erp.pipeline import resolve_components

    comps = resolve_components(cfg, ch_names)
    return {k: (v["window_s"], {c: [ch_names[i] for i in idx] for c, idx in v["clusters"].items()}) for k, v in comps.items()}


def peak_memory_gb() -> float:
    """Peak resident memory of this process in GB (GiB): ``VmHWM``, else ``ru_maxrss``."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024 ** 2  # kB
    except OSError:
        pass
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # kB on Linux, bytes on macOS
    return rss / (1024 ** 3 if sys.platform == "darwin" else 1024 ** 2)


def _worker(kind: str, path: str) -> None:
    """Run one pipeline in this process; print JSON with seconds, peak RSS and the means."""
    import mne

    from analysis.erp.config import event_map
    from analysis.erp.pipeline import process_subject

    mne.set_log_level("ERROR")
    cfg = _config(Path(path))
    t0 = time.perf_counter()
    if kind == "ours":
        res = process_subject(path, cfg, event_map(cfg))
        means = {f"{(r.stylisation, r.emotion)}|{r.component}|{r.cluster}": r.mean_uV for r in res.amplitudes.itertuples()}
    else:
        from analysis.erp.channels import make_montage

        comps = _components(cfg, make_montage("biosemi128").ch_names)
        out = plain_mne(path, {int(c): lv for c, lv in cfg.events.items()}, comps)
        means = {f"{k[0]}|{k[1]}|{k[2]}": v for k, v in out.items()}
    secs = time.perf_counter() - t0
    peak_gb = peak_memory_gb()
    print(json.dumps({"seconds": secs, "peak_gb": peak_gb, "means": means}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--minutes", type=float, default=10.0, help="length of the recording (default 10)")
    ap.add_argument("--sfreq", type=int, default=2048, help="sampling rate in Hz (default 2048)")
    ap.add_argument("--repeats", type=int, default=3, help="runs of each pipeline; medians reported (default 3)")
    ap.add_argument("--worker", nargs=2, metavar=("KIND", "PATH"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        _worker(*args.worker)
        return
    from analysis.erp.simulate import SimulationDesign, _setup, simulate_subject, write_raw

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "sub-01_task-faces_eeg.bdf"
        t0 = time.perf_counter()
        design = SimulationDesign(sfreq=args.sfreq, n_bad_channels=0)
        head, info, fwd = _setup(design)
        raw, _ = simulate_subject(design, 0, head, info, fwd, duration_s=args.minutes * 60)
        write_raw(raw, path)
        del raw
        print(f"simulated {args.minutes:g} min, 128 EEG + 4 EOG + Status at {args.sfreq} Hz: "
              f"{path.stat().st_size / 1e6:.0f} MB BDF in {time.perf_counter() - t0:.1f} s")
        runs: dict[str, list] = {"ours": [], "mne": []}
        for _ in range(args.repeats):
            for kind in ("mne", "ours"):
                out = subprocess.run([sys.executable, __file__, "--worker", kind, str(path)], capture_output=True,
                                     text=True, check=True)
                runs[kind].append(json.loads(out.stdout.strip().splitlines()[-1]))
    t_ours = statistics.median(r["seconds"] for r in runs["ours"])
    t_mne = statistics.median(r["seconds"] for r in runs["mne"])
    m_ours = max(r["peak_gb"] for r in runs["ours"])
    m_mne = max(r["peak_gb"] for r in runs["mne"])
    a, b = runs["ours"][0]["means"], runs["mne"][0]["means"]
    diff = max(abs(a[k] - b[k]) for k in b)
    for label, kind, t, m in (("plain MNE ", "mne", t_mne, m_mne), ("appeal erp", "ours", t_ours, m_ours)):
        each = ", ".join(f"{r['seconds']:.1f}" for r in runs[kind])
        print(f"{label}: median {t:6.1f} s  peak {m:.2f} GB   (runs: {each})")
    print(f"ratio ours/MNE: {t_ours / t_mne:.3f}   (target <= 1.20; ours <= 90 s, <= 6 GB)")
    print(f"largest difference of the {len(a)} window means: {diff:.2e} µV")


if __name__ == "__main__":
    main()
