"""Simulated face-ERP recordings with planted, condition-dependent generators.

Dipoles in a volume source space of the sphere head fitted to the montage project through
MNE's forward model onto the scalp; :func:`mne.simulation.add_noise` adds spatially and
temporally correlated background EEG; slow drifts and blinks (seen by EOG channels and
leaking into frontal EEG) exercise the filters and the eye correction. The planted
effects follow thesis §7.4:

* N170 (bilateral occipito-temporal generators, 170 ms): u-shaped over stylisation (largest
  at the extremes), larger for angry > happy > neutral;
* EPN (same generators, 300 ms): angry > happy > neutral, no stylisation effect;
* LPP (parietal generator, 400-600 ms): rising linearly with stylisation.

Recordings are written as BioSemi BDF with a Status channel (or FIF).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from appeal.atomic import atomic_write_text

__all__ = ["SimulationDesign", "GENERATORS_MNI", "planted_generators", "simulate_subject", "simulate_study",
           "trigger_code"]

#: Planted generator positions (MNI mm): right/left occipito-temporal (N170, EPN), parietal (LPP).
GENERATORS_MNI = {"N170_right": (44.0, -76.0, -8.0), "N170_left": (-44.0, -76.0, -8.0), "LPP": (0.0, -60.0, 45.0)}

EMOTIONS = ("angry", "happy", "neutral")  # code order of protocols/erp_stylisation.yaml


def trigger_code(stylisation: int, emotion_index: int) -> int:
    """Trigger code of a cell: ``10 * (stylisation + 1) + emotion_index + 1`` (11 ... 63)."""
    return 10 * (int(stylisation) + 1) + int(emotion_index) + 1


@dataclass
class SimulationDesign:
    """What to simulate; defaults are small enough for tests.

    Amplitudes are dipole moments in nAm at the generators (before subject gain).
    """

    n_subjects: int = 8
    stylisation_levels: tuple[int, ...] = (0, 1, 2, 3, 4, 5)
    emotions: tuple[str, ...] = EMOTIONS
    trials_per_cell: int = 10
    sfreq: int = 256
    montage: str = "biosemi128"
    eog: tuple[str, ...] = ("EXG1", "EXG2", "EXG3", "EXG4")
    spacing_mm: float = 10.0
    noise_uV: float = 6.0
    n170_nAm: float = 60.0
    n170_u: float = 0.6
    emotion_gain: dict = field(default_factory=lambda: {"angry": 1.3, "happy": 1.15, "neutral": 1.0})
    epn_nAm: dict = field(default_factory=lambda: {"angry": 30.0, "happy": 18.0, "neutral": 6.0})
    lpp_nAm: tuple[float, float] = (30.0, 12.0)  # intercept, slope per stylisation level
    blink_rate_hz: float = 0.2
    n_bad_channels: int = 1
    subject_sd: float = 0.15
    seed: int = 0

    @property
    def events(self) -> dict[int, dict]:
        """code -> {stylisation, emotion}."""
        return {trigger_code(s, e): {"stylisation": s, "emotion": emo}
                for s in self.stylisation_levels for e, emo in enumerate(self.emotions)}


def planted_generators(head) -> dict[str, dict]:
    """Grid voxels nearest to :data:`GENERATORS_MNI` in ``head``: index, position, radial orientation."""
    mni = head.mni
    rr = head.positions
    centre = head.bem["r0"] if hasattr(head.bem, "__getitem__") and "r0" in head.bem else rr.mean(axis=0)
    out = {}
    for name, p in GENERATORS_MNI.items():
        i = int(np.argmin(np.linalg.norm(mni - np.asarray(p), axis=1)))
        ori = rr[i] - centre
        out[name] = {"index": i, "pos": rr[i], "mni": mni[i], "ori": ori / np.linalg.norm(ori)}
    return out


def _waveform(times: np.ndarray, mu: float, sd: float) -> np.ndarray:
    return np.exp(-0.5 * ((times - mu) / sd) ** 2)


def simulate_subject(design: SimulationDesign, subject_index: int, head=None, info=None, fwd=None,
                     duration_s: float | None = None):
    """One simulated subject as an MNE Raw (EEG, EOG, Status) in volts.

    Parameters
    ----------
    design : SimulationDesign
        The design.
    subject_index : int
        Which subject (seeds its noise, trial order and gain).
    head, info, fwd : optional
        A prepared head model, EEG info and fixed gain (from :func:`_setup`), to share work.
    duration_s : float | None
        If given, trials repeat until this recording length (for benchmarks).

    Returns
    -------
    raw : mne.io.RawArray
    events : ndarray (n, 3)
    """
    import mne

    if head is None:
        head, info, fwd = _setup(design)
    rng = np.random.default_rng([design.seed, subject_index])
    sf = float(design.sfreq)
    cells = [(s, e) for s in design.stylisation_levels for e in range(len(design.emotions))]
    order = np.repeat(np.arange(len(cells)), design.trials_per_cell)
    if duration_s is not None:
        n_needed = int(duration_s / 1.05) + 1
        order = np.resize(order, n_needed)
    rng.shuffle(order)
    soa = 0.6 + rng.uniform(0.4, 0.5, len(order))
    onsets = 2.0 + np.concatenate([[0.0], np.cumsum(soa[:-1])])
    total = float(duration_s) if duration_s is not None else onsets[-1] + 3.0
    onsets = onsets[onsets < total - 1.5]
    order = order[: len(onsets)]
    n_times = int(round(total * sf))
    samples = np.round(onsets * sf).astype(int)
    t = np.arange(int(0.8 * sf)) / sf
    gain = 1.0 + design.subject_sd * rng.standard_normal()
    gens = planted_generators(head)
    # source time courses (nAm) of the three generators
    src = np.zeros((3, n_times))
    w_n170 = -_waveform(t, 0.170, 0.016)
    w_epn = -_waveform(t, 0.300, 0.045)
    w_lpp = _waveform(t, 0.500, 0.080)
    w_p1 = _waveform(t, 0.105, 0.015)
    for k, samp in zip(order, samples):
        s, e = cells[k]
        emo = design.emotions[e]
        u = ((s - np.mean(design.stylisation_levels)) / np.ptp(design.stylisation_levels) * 2) ** 2
        n170 = design.n170_nAm * (1 + design.n170_u * u) * design.emotion_gain.get(emo, 1.0)
        temporal = n170 * w_n170 + design.epn_nAm.get(emo, 0.0) * w_epn + 25.0 * w_p1
        lpp = (design.lpp_nAm[0] + design.lpp_nAm[1] * s) * w_lpp
        seg = slice(samp, min(n_times, samp + len(t)))
        m = seg.stop - seg.start
        src[0, seg] += gain * temporal[:m]
        src[1, seg] += gain * temporal[:m]
        src[2, seg] += gain * lpp[:m]
    eeg = fwd @ (src * 1e-9)  # volts
    ch_eeg = info.ch_names
    n_eog = len(design.eog)
    all_info = mne.create_info(ch_eeg + list(design.eog) + ["Status"], sf, ["eeg"] * len(ch_eeg) + ["eog"] * n_eog + ["stim"])
    data = np.zeros((len(all_info.ch_names), n_times))
    data[: len(ch_eeg)] = eeg
    raw = mne.io.RawArray(data, all_info, verbose="error")
    raw.set_montage(mne.channels.make_standard_montage(design.montage) if design.montage != "none" else None,
                    on_missing="ignore", verbose="error")
    # background EEG: ad hoc diagonal covariance coloured by an AR filter
    cov = mne.make_ad_hoc_cov(raw.info, std=dict(eeg=design.noise_uV * 1e-6), verbose="error")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mne.simulation.add_noise(raw, cov, iir_filter=[1.0, -0.6, 0.1], rng=int(rng.integers(2**31)), verbose="error")
    d = raw._data
    # slow drifts (removed by the high-pass) and blinks (removed by the EOG correction)
    tt = np.arange(n_times) / sf
    d[: len(ch_eeg)] += 20e-6 * np.sin(2 * np.pi * 0.05 * tt + rng.uniform(0, 2 * np.pi, (len(ch_eeg), 1)))
    blinks = np.zeros(n_times)
    n_blinks = int(design.blink_rate_hz * total)
    bw = _waveform(np.arange(int(0.4 * sf)) / sf, 0.2, 0.05) * 150e-6
    for b in rng.integers(0, max(1, n_times - len(bw)), n_blinks):
        blinks[b:b + len(bw)] += bw
    pos = np.array([raw.info["chs"][i]["loc"][:3] for i in range(len(ch_eeg))])
    front = np.clip(pos[:, 1] / 0.09, 0, None) ** 2 * 0.5  # blink leakage grows towards the forehead
    d[: len(ch_eeg)] += front[:, None] * blinks
    # broken electrodes: very noisy channels (found and interpolated by the pipeline)
    bad_idx = rng.choice(len(ch_eeg), design.n_bad_channels, replace=False)
    d[bad_idx] += 80e-6 * rng.standard_normal((len(bad_idx), n_times))
    raw.info["description"] = "bad channels: " + " ".join(ch_eeg[i] for i in bad_idx)
    eog_w = np.array([1.0, 1.0, -0.3, -0.3])[:n_eog]
    d[len(ch_eeg): len(ch_eeg) + n_eog] += eog_w[:, None] * blinks + design.noise_uV * 1e-6 * rng.standard_normal((n_eog, n_times))
    codes = np.array([mne_code for mne_code in (trigger_code(cells[k][0], cells[k][1]) for k in order)])
    status = np.zeros(n_times, np.int64)
    width = max(1, int(0.008 * sf))
    for c, samp in zip(codes, samples):
        status[samp:samp + width] = c
    d[-1] = status
    events = np.c_[samples, np.zeros(len(samples), int), codes]
    return raw, events


def _setup(design: SimulationDesign):
    """Head model for the montage and the fixed-orientation gain of the planted generators (V per Am)."""
    import mne

    from analysis.erp.channels import make_montage
    from analysis.erp.source import template_head

    mont = make_montage(design.montage)
    info = mne.create_info(mont.ch_names, float(design.sfreq), "eeg")
    info.set_montage(mont, verbose="error")
    head = template_head(info, design.spacing_mm)
    fwd = mne.make_forward_solution(info, trans=None, src=head.src, bem=head.bem, eeg=True, meg=False, verbose="error")
    gens = planted_generators(head)
    g = fwd["sol"]["data"]
    cols = []
    for name in ("N170_right", "N170_left", "LPP"):
        i, ori = gens[name]["index"], gens[name]["ori"]
        cols.append(g[:, 3 * i:3 * i + 3] @ ori)
    return head, info, np.array(cols).T


def write_raw(raw, path: str | Path) -> Path:
    """Write a simulated Raw as BDF (``.bdf``, BioSemi Status channel) or FIF."""
    from analysis.erp.bdf import write_bdf

    path = Path(path)
    if path.suffix.lower() == ".bdf":
        data = raw.get_data()
        status = data[-1].astype(np.int64) | 0x100000  # BioSemi sets device bits above the 16 trigger bits
        return write_bdf(path, data[:-1] * 1e6, raw.ch_names[:-1], int(raw.info["sfreq"]), status)
    raw.save(path, overwrite=True, verbose="error")
    return path


def simulate_study(out_dir: str | Path, design: SimulationDesign | None = None, fmt: str = "bdf") -> dict:
    """Simulate a study into ``out_dir``: one recording per subject plus ``truth.yaml``.

    Returns
    -------
    dict
        ``files`` (list of paths), ``events`` (code -> levels), ``generators`` (name -> MNI mm
        of the grid voxel used), ``bad_channels`` (subject -> broken electrodes).
    """
    design = design or SimulationDesign()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    head, info, fwd = _setup(design)
    files, bads = [], {}
    for k in range(design.n_subjects):
        raw, _ = simulate_subject(design, k, head, info, fwd)
        files.append(write_raw(raw, out_dir / f"sub-{k + 1:02d}_task-faces_eeg.{fmt}"))
        bads[f"{k + 1:02d}"] = raw.info["description"].split(": ", 1)[1].split()
    gens = {n: [round(float(v), 1) for v in g["mni"]] for n, g in planted_generators(head).items()}
    truth = {"generators_mni_mm": gens, "bad_channels": bads, "events": {int(c): lv for c, lv in design.events.items()},
             "design": {"n_subjects": design.n_subjects, "trials_per_cell": design.trials_per_cell,
                        "sfreq": design.sfreq, "spacing_mm": design.spacing_mm}}
    atomic_write_text(out_dir / "truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return {"files": files, "events": design.events, "generators": gens, "bad_channels": bads}
