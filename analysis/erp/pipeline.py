"""The ERP pipeline: one subject from file to measures, the whole study in parallel, and the
workflow that ``appeal analyze erp`` calls.

:func:`process_subject` runs in a worker process (one recording at a time, so memory stays
bounded by one subject); :func:`process_subjects` checks every recording first (untrusted input:
:func:`refused_recordings`), maps it over the others with :func:`appeal.parallel.parallel_map`,
reports failing subjects and carries on with the rest;
:func:`run_erp` runs them and writes every output (:mod:`analysis.erp.report`).
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError
from appeal.logs import logger
from appeal.parallel import ItemFailure, parallel_map

from analysis.erp.config import EventMap, event_map, find_recordings, subject_id
from analysis.erp.report import ErpOutputs, write_erp_outputs
from analysis.erp.results import ErpResult, SubjectResult
from analysis.erp_schema import ErpConfig

__all__ = ["SubjectResult", "ErpResult", "process_subject", "process_subjects", "preprocess", "run_erp",
           "resolve_components", "refused_recordings"]


def resolve_components(cfg: ErpConfig, ch_names: list[str], source: str = "config") -> dict:
    """Components with their clusters as channel indices into ``ch_names``."""
    from analysis.erp.channels import resolve_cluster

    montage = None if cfg.montage == "none" else cfg.montage
    out = {}
    for name, comp in cfg.components.items():
        clusters = {}
        for cname, chans in comp.clusters.items():
            labels = resolve_cluster(chans, ch_names, montage, where=f"{source}: components.{name}.clusters.{cname}")
            clusters[cname] = [ch_names.index(c) for c in labels]
        out[name] = {"window_s": tuple(comp.window_s), "polarity": comp.polarity, "clusters": clusters,
                     "peak_fraction": comp.peak_fraction, "area_fraction": comp.area_fraction}
    return out


def preprocess(path: str | Path, cfg: ErpConfig, emap: EventMap, seed: int = 0):
    """Read and preprocess one recording; returns ``(epochs, qc)``.

    Steps (each one MNE call): read, rename channels (``channels.rename``), channel types +
    montage, events from the Status channel
    (or annotations), filters, reference, EOG correction, bad channels (detected on the
    eye-corrected data, spherical-spline interpolation, then referenced again), optional
    resampling, epochs with baseline, rejection.
    """
    from analysis.erp import io, preprocessing as pp
    from analysis.erp.channels import rename_channels

    path = Path(path)
    raw = io.read_recording(path)
    rename_channels(raw, cfg.channels.rename, path)
    events = io.find_trigger_events(raw, path, cfg.stim_channel, cfg.trigger_mask)
    events = io.select_events(events, emap.codes, emap.ignore, emap.unknown, path)
    pp.setup_channels(raw, cfg.montage, cfg.eog, path)
    f = cfg.filter
    pp.filter_raw(raw, f.highpass_hz, f.lowpass_hz, highpass_causal=f.highpass_causal, method=f.method,
                  notch_hz=f.notch_hz)
    pp.set_reference(raw, cfg.reference)
    eog_info = pp.correct_eog(raw, cfg.eog_method, seed) if cfg.eog else {"eog_method": "none"}
    b = cfg.bad_channels
    bads = pp.fix_bad_channels(raw, detect=b.detect, z_threshold=b.z_threshold, flat_uV=b.flat_uV, mark=b.mark,
                               interpolate=b.interpolate, path=path)
    if bads:
        pp.set_reference(raw, cfg.reference)  # the interpolated channels join the reference
    if cfg.resample_hz:
        raw, events = raw.resample(cfg.resample_hz, events=events, verbose="error")
    event_id = {f"code{c}": int(c) for c in sorted(set(events[:, 2].tolist()))}
    ep = cfg.epochs
    epochs = pp.make_epochs(raw, events, event_id, ep.tmin_s, ep.tmax_s, ep.baseline_s,
                            cfg.reject.peak_to_peak_uV)
    del raw
    n_events = len(events)
    if cfg.reject.absolute_uV:
        pp.reject_absolute(epochs, cfg.reject.absolute_uV)
    n_eeg = len(epochs.ch_names)
    qc = {"file": str(path), "n_channels": n_eeg, "bad_channels": " ".join(bads),
          "pct_channels_interpolated": 100.0 * len(bads) / max(n_eeg, 1) if b.interpolate else 0.0,
          "n_events": n_events, "n_epochs": len(epochs),
          "pct_trials_rejected": 100.0 * (n_events - len(epochs)) / max(n_events, 1), **eog_info}
    if len(epochs) == 0:
        raise AppealInputError(f"{path}: reject: every epoch was rejected ({n_events} events); "
                               "check the threshold and the recording")
    return epochs, qc


def _cell_names(emap: EventMap, epochs) -> dict[tuple, list[str]]:
    out: dict[tuple, list[str]] = {}
    for name, code in epochs.event_id.items():
        out.setdefault(emap.cell_of(code), []).append(name)
    return out


def process_subject(path: str | Path, cfg: ErpConfig, emap: EventMap, head=None, subject: str | None = None,
                    seed: int = 0, beh: str | Path | None = None) -> SubjectResult:
    """One subject: preprocess, average per cell, measure, single-trial measures and their SME
    (with each trial's stimulus from ``beh``, the subject's ``*_beh.tsv``), and (with a head model)
    source maps."""
    from analysis.erp.measures import measure_cells
    from analysis.erp.quality import sme_table
    from analysis.erp.single_trials import match_stimuli, read_beh_trials, single_trial_table, trial_table

    import mne

    path = Path(path)
    subject = subject or subject_id(path, cfg.subject_pattern)
    mne.set_log_level("ERROR")
    epochs, qc = preprocess(path, cfg, emap, seed)
    comps = resolve_components(cfg, epochs.ch_names, source=str(path))
    cells = _cell_names(emap, epochs)
    evokeds, n_trials = {}, {}
    for cell in emap.cells:
        names = [n for n in cells.get(cell, []) if len(epochs[n])]
        n = sum(len(epochs[x]) for x in names)
        n_trials[cell] = n
        if n:
            evokeds[cell] = epochs[names].average().data
    qc["trials_per_cell_mean"] = float(np.mean(list(n_trials.values())))
    qc["trials_per_cell_min"] = int(min(n_trials.values()))
    amps = measure_cells(evokeds, n_trials, epochs.times, emap.factors, comps)
    codes = epochs.events[:, 2]
    stimuli = None if beh is None else match_stimuli(read_beh_trials(beh, list(emap.codes)), epochs.selection, codes,
                                                     qc["n_events"], beh, path)
    trials = trial_table(epochs.selection, epochs.events, {int(c): emap.cell_of(int(c)) for c in set(codes.tolist())},
                         emap.factors, stimuli)
    single = single_trial_table(epochs.get_data(copy=False), epochs.times, comps, trials)
    maps = {}
    if head is not None:
        from analysis.erp.source import BASELINE, subject_source_maps

        src = cfg.source
        factor = src.factor or emap.factors[0]
        fi = emap.factors.index(factor)
        groups: dict = {}
        for cell, names in cells.items():
            groups.setdefault(cell[fi], []).extend(names)
        comp_names = src.components or list(cfg.components)
        windows = {c: tuple(cfg.components[c].window_s) for c in comp_names}
        windows[BASELINE] = tuple(cfg.epochs.baseline_s or (cfg.epochs.tmin_s, 0.0))  # for the per-level maps
        maps = subject_source_maps(epochs, head, groups, windows, src.method, src.snr)
    return SubjectResult(subject=subject, path=str(path), qc=qc, amplitudes=amps,
                         evokeds={k: v.astype(np.float32) for k, v in evokeds.items()}, n_trials=n_trials,
                         info=epochs.info, times=epochs.times.copy(), source_maps=maps, single_trials=single,
                         sme=sme_table(single, emap.factors, emap.cells))


def _head_info(cfg: ErpConfig, first: Path):
    """EEG info with positions, for the shared head model."""
    import mne

    from analysis.erp.channels import make_montage, rename_channels
    from analysis.erp.io import read_recording
    from analysis.erp.preprocessing import setup_channels

    if cfg.montage != "none":
        mont = make_montage(cfg.montage)
        info = mne.create_info(mont.ch_names, 1000.0, "eeg")
        info.set_montage(mont, verbose="error")
        return info
    raw = read_recording(first)
    rename_channels(raw, cfg.channels.rename, first)
    setup_channels(raw, "none", cfg.eog, first)
    return raw.pick("eeg").info


def process_subjects(cfg: ErpConfig, *, source: str | Path = "config", n_jobs: int | None = None,
                     scheduler: str | None = None, seed: int = 0) -> ErpResult:
    """Run the scalp (and source) pipeline over every recording of ``cfg``.

    Parameters
    ----------
    cfg : ErpConfig
        The validated config.
    source : str | Path
        The config file (for messages).
    n_jobs : int | None
        Local worker processes (default ``cfg.n_jobs``, else all cores).
    scheduler : str | None
        Dask scheduler address.
    seed : int
        Seed of ICA and permutations.

    Returns
    -------
    ErpResult
        Successful subjects and the failures (each with a one-line reason).

    Raises
    ------
    AppealInputError
        When the config is inconsistent, or no subject succeeds.
    """
    from analysis.erp.source import add_forward, template_head

    emap = event_map(cfg, source)
    files = find_recordings(cfg, source)
    subjects = [subject_id(f, cfg.subject_pattern) for f in files]
    dup = sorted({s for s in subjects if subjects.count(s) > 1})
    if dup:
        raise AppealInputError(f"{source}: subject_pattern: several recordings give subject ids {dup} "
                               "(expected one recording per subject; adjust subject_pattern)")
    for comp in cfg.source.components or []:
        if comp not in cfg.components:
            raise AppealInputError(f"{source}: source.components: {comp!r} is not a component "
                                   f"(expected one of: {', '.join(cfg.components)})")
    if cfg.source.factor and cfg.source.factor not in emap.factors:
        raise AppealInputError(f"{source}: source.factor: {cfg.source.factor!r} is not a factor "
                               f"(expected one of: {', '.join(emap.factors)})")
    beh = {}
    if cfg.beh is not None:
        from analysis.erp.single_trials import find_beh_files

        beh = find_beh_files(cfg.beh, dict(zip(subjects, files)), cfg.subject_pattern, source)
    refused = refused_recordings(files, subjects)
    keep = [i for i in range(len(files)) if i not in refused]
    head = None
    if cfg.source.enabled:
        s = cfg.source
        info = _head_info(cfg, files[keep[0]])
        head = add_forward(template_head(info, s.spacing_mm, bem=s.bem, trans=s.trans, subjects_dir=s.subjects_dir,
                                         subject=s.subject), info)
    func = functools.partial(_process_item, cfg=cfg, emap=emap, head=head, seed=seed)
    items = [(files[i], subjects[i], beh.get(subjects[i])) for i in keep]
    res = parallel_map(func, items, n_jobs=n_jobs if n_jobs is not None else cfg.n_jobs, scheduler=scheduler,
                       desc="subjects", labels=[subjects[i] for i in keep])
    ok = [r for r in res.successful() if r is not None]
    logger.info("ERP pipeline: %s%s", res.summary(), f"; {len(refused)} recordings refused before" if refused else "")
    failures = sorted([dataclasses.replace(f, index=keep[f.index]) for f in res.failures] + list(refused.values()),
                      key=lambda f: f.index)
    if not ok:
        raise AppealInputError([f"{f.label}: {f.error}" for f in failures] or [f"{source}: no subject succeeded"])
    return ErpResult(subjects=ok, failures=failures, emap=emap, head=head)


def refused_recordings(files: list[Path], subjects: list[str]) -> dict[int, ItemFailure]:
    """The recordings that fail the checks made before reading (:func:`analysis.erp.io.check_recording`).

    They are reported like subjects that failed (index, subject, ``AppealInputError: ...``) without
    starting a worker. When every recording is refused this raises instead, with one line per
    recording (the run would have nothing to do; the lines are not logged twice).

    Returns
    -------
    dict
        Index into ``files`` -> :class:`appeal.parallel.ItemFailure`.

    Raises
    ------
    AppealInputError
        When no recording passes the checks.
    """
    from analysis.erp.io import check_recording

    refused = {}
    for i, (path, subject) in enumerate(zip(files, subjects)):
        try:
            check_recording(path)
        except AppealInputError as exc:
            refused[i] = ItemFailure(i, subject, f"{type(exc).__name__}: {exc}")
    if len(refused) == len(files):
        raise AppealInputError([f"{f.label}: {f.error}" for f in refused.values()])
    for f in refused.values():
        logger.warning("%s failed: %s", f.label, f.error)
    return refused


def run_erp(cfg: ErpConfig, out: Path, *, source: str | Path = "config", seed: int = 0,
            n_jobs: int | None = None, scheduler: str | None = None,
            n_permutations: int | None = None) -> tuple[ErpResult, ErpOutputs]:
    """The ERP workflow: run every subject (:func:`process_subjects`) and write all outputs into
    ``out`` (:func:`analysis.erp.report.write_erp_outputs`). ``appeal analyze erp`` calls this.

    Parameters
    ----------
    cfg : ErpConfig
        The validated config (:func:`analysis.erp.config.load_erp_config`, loaded once by the
        caller; the file is not read again).
    out : Path
        Output folder, existing (create it with :func:`appeal.outputs.output_run`).
    source : str | Path
        The config file: relative paths resolve against it and errors name it.
    seed : int
        Seed of ICA and permutations.
    n_jobs : int | None
        Local worker processes (default ``cfg.n_jobs``, else all cores).
    scheduler : str | None
        Dask scheduler address.
    n_permutations : int | None
        Override ``source.n_permutations`` (quick runs); ``cfg`` itself is not changed.

    Returns
    -------
    tuple of (ErpResult, ErpOutputs)
        The subjects' results and the paths written.
    """
    if n_permutations is not None:
        cfg = cfg.model_copy(update={"source": cfg.source.model_copy(update={"n_permutations": int(n_permutations)})})
    result = process_subjects(cfg, source=source, n_jobs=n_jobs, scheduler=scheduler, seed=seed)
    outputs = write_erp_outputs(result, cfg, Path(out), seed=seed, config_name=Path(source).name)
    return result, outputs


def _process_item(item, cfg, emap, head, seed):
    path, subject, beh = item
    return process_subject(path, cfg, emap, head=head, subject=subject, seed=seed, beh=beh)
