"""End to end on simulated BDF recordings: planted effects recovered, source peaks near the
planted generators, equality with a plain MNE script, and a broken subject that does not
stop the others (through the ``appeal analyze erp`` command)."""

from __future__ import annotations

import importlib.util
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from analysis.erp.simulate import SimulationDesign, simulate_study
from appeal_cli import main

DESIGN = SimulationDesign(n_subjects=8, trials_per_cell=8, sfreq=128, spacing_mm=12.0, seed=3)


@pytest.fixture(scope="module", autouse=True)
def _one_blas_thread():
    """One BLAS thread in this process (the subject workers get cores // workers from joblib).

    The linear algebra here is small; on the shared 2-core machine two OpenBLAS threads
    waiting for each other made the module take ~2x longer. Results do not depend on it.
    """
    import scipy.linalg  # noqa: F401 - load SciPy's BLAS too, so the limit covers it
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        yield


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    d = tmp_path_factory.mktemp("erp_study")
    sim = simulate_study(d / "data", DESIGN)
    # a ninth, broken recording: the run must report it and go on
    broken = d / "data" / "sub-09_task-faces_eeg.bdf"
    broken.write_bytes(sim["files"][0].read_bytes()[:300_000])
    cfg = {"kind": "erp", "recordings": "data/sub-*_task-faces_eeg.bdf",
           "events": {int(c): lv for c, lv in DESIGN.events.items()},
           "levels": {"emotion": ["angry", "neutral", "happy"]}, "eog": list(DESIGN.eog),
           "source": {"spacing_mm": DESIGN.spacing_mm, "contrasts": [[5, 0]], "components": ["N170", "LPP"],
                      "n_permutations": 50},
           "mixed": {"enabled": True, "random": "(1 | subject)"}}
    config = d / "erp.yaml"
    config.write_text(yaml.safe_dump(cfg, sort_keys=False))
    out = d / "out"
    rc = main(["-q", "analyze", "erp", str(config), "--out", str(out), "--n-jobs", "2"])
    return {"dir": d, "out": out, "rc": rc, "sim": sim, "config": config}


def test_outputs_and_failed_subject(study):
    out = study["out"]
    assert study["rc"] == 0
    amps = pd.read_csv(out / "amplitudes.csv")
    assert list(amps.columns) == ["subject", "stylisation", "emotion", "component", "cluster", "mean_uV", "peak_uV",
                                  "peak_latency_ms", "frac_peak_latency_ms", "frac_area_latency_ms", "n_trials"]
    assert sorted(amps["subject"].unique()) == list(range(1, 9))
    assert len(amps) == 8 * 18 * 5  # N170 + EPN (2 clusters each) + LPP (1)
    fail = pd.read_csv(out / "failures.csv")
    assert fail["subject"].tolist() == [9] and "truncated" in fail["error"].iloc[0]
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["status"] == "ok" and prov["failed_subjects"][0].startswith("09: ")
    for f in ["report.md", "qc.csv", "stats/anova.csv", "stats/contrasts.csv", "source/clusters.csv",
              "source/level_peaks.csv", "figures/waveforms.png", "figures/bars_N170.svg", "figures/topomaps_emotion.png"]:
        assert (out / f).is_file(), f
    # peak latencies of the planted N170 (170 ms) and LPP (500 ms)
    lat = amps.groupby("component")["peak_latency_ms"].median()
    assert abs(lat["N170"] - 170) <= 16 and abs(lat["LPP"] - 500) <= 40
    # the planted N170 is a Gaussian around 170 ms: half its peak before it, half its area near it
    n170 = amps[amps.component == "N170"]
    assert (n170["frac_peak_latency_ms"] <= n170["peak_latency_ms"]).all()
    assert abs(n170["frac_area_latency_ms"].median() - 170) <= 16
    # data quality: one SME per subject x cell x component x cluster, from the kept single trials
    qc = pd.read_csv(out / "qc.csv")
    single = pd.read_csv(out / "single_trials.csv")
    assert len(single) == 5 * qc["n_epochs"].sum() and single["stimulus"].isna().all()
    sme = pd.read_csv(out / "sme.csv")
    assert len(sme) == len(amps) and (sme["n_trials"] >= 2).all() and not sme["flagged"].any()
    assert (out / "figures" / "sme.png").is_file() and "## Data quality (SME)" in (out / "report.md").read_text()


def test_single_trial_mixed_models(study):
    """mixed: {enabled: true}: one LMM per component x cluster on single_trials.csv; the planted
    effects are found (LPP rises with stylisation; the N170 is scaled by emotion, not the LPP), and
    the fit equals a direct fit of the same table."""
    from analysis.stats.lmm import fit_lmm

    out = study["out"]
    report = (out / "report.md").read_text()
    assert "### Linear mixed models of the single-trial window means" in report and "#### LPP" in report
    lpp = pd.read_csv(out / "stats" / "lmm" / "LPP_parietal" / "lmm_anova.csv").set_index("effect")
    assert list(lpp.index) == ["stylisation", "emotion", "stylisation:emotion"]
    assert lpp.loc["stylisation", "p"] < 1e-6 and lpp.loc["emotion", "p"] > 0.01
    assert (lpp["method"] == "LMM type III, Satterthwaite").all()
    n170 = pd.read_csv(out / "stats" / "lmm" / "N170_right" / "lmm_anova.csv").set_index("effect")
    assert n170.loc["emotion", "p"] < 1e-6
    single = pd.read_csv(out / "single_trials.csv")
    part = single[(single.component == "LPP") & (single.cluster == "parietal")]
    direct = fit_lmm("mean_uV ~ stylisation * emotion + (1 | subject)", part,
                     factors=["stylisation", "emotion", "subject"], levels={"emotion": ["angry", "neutral", "happy"]})
    coefs = pd.read_csv(out / "stats" / "lmm" / "LPP_parietal" / "lmm_coefficients.csv")
    assert np.allclose(coefs["estimate"], direct.beta, rtol=1e-5, atol=1e-6)  # single_trials.csv is rounded


def test_strict_flag_fails_on_broken_subject(study, tmp_path, capsys):
    cfg = yaml.safe_load(study["config"].read_text())
    cfg.update(recordings=[str(study["dir"] / "data" / f"sub-{k}_task-faces_eeg.bdf") for k in ("01", "09")],
               source={"enabled": False})
    config = tmp_path / "two.yaml"
    config.write_text(yaml.safe_dump(cfg))
    rc = main(["analyze", "erp", str(config), "--out", str(tmp_path / "o"), "--strict", "--n-jobs", "1"])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("09: ") and "truncated" in err[-1]
    assert (tmp_path / "o" / "amplitudes.csv").is_file()


def test_bad_channels_found_and_interpolated(study):
    qc = pd.read_csv(study["out"] / "qc.csv", dtype={"subject": str})
    truth = study["sim"]["bad_channels"]
    for row in qc.itertuples():
        assert str(row.bad_channels).split() == truth[row.subject]
    assert np.allclose(qc["pct_channels_interpolated"], 100 / 128)


def _contrast(out, comp, factor, kind):
    c = pd.read_csv(out / "stats" / "contrasts.csv")
    return c[(c.component == comp) & (c.factor == factor) & (c.contrast == kind)].iloc[0]


def _effect(out, comp, effect):
    a = pd.read_csv(out / "stats" / "anova.csv")
    return a[(a.component == comp) & (a.effect == effect)].iloc[0]


def test_planted_effects_recovered(study):
    out = study["out"]
    # u-shaped N170: quadratic significant, linear not
    assert _contrast(out, "N170", "stylisation", "quadratic").p < 0.001
    assert _contrast(out, "N170", "stylisation", "linear").p > 0.05
    # linear LPP, explaining more than a u-shape
    lin, quad = _contrast(out, "LPP", "stylisation", "linear"), _contrast(out, "LPP", "stylisation", "quadratic")
    assert lin.p < 0.001 and lin.F > 10 * quad.F
    # emotion effects on N170 and EPN, none on the LPP
    assert _effect(out, "N170", "emotion").p_gg < 0.001
    assert _effect(out, "EPN", "emotion").p_gg < 0.001
    assert _effect(out, "LPP", "emotion").p > 0.01
    assert _effect(out, "N170", "stylisation").pes > 0.5


def test_source_peaks_near_planted_generators(study):
    out = study["out"]
    gens = {k: np.array(v) for k, v in study["sim"]["generators"].items()}
    peaks = pd.read_csv(out / "source" / "level_peaks.csv")
    n170 = peaks[(peaks.component == "N170") & (peaks.level == 0)][["x_mm", "y_mm", "z_mm"]].to_numpy()
    for name in ("N170_left", "N170_right"):
        assert np.linalg.norm(n170[:2] - gens[name], axis=1).min() <= 15, name
    lpp = peaks[(peaks.component == "LPP") & (peaks.level == 5)].iloc[0][["x_mm", "y_mm", "z_mm"]].to_numpy(float)
    assert np.linalg.norm(lpp - gens["LPP"]) <= 15
    clusters = pd.read_csv(out / "source" / "clusters.csv")
    top = clusters[(clusters.component == "LPP") & (clusters.contrast == "stylisation 5 > 0")].iloc[0]
    assert top.n_voxels >= 25 and top.p_fwe < 0.05 and top.peak_p_uncorrected < 0.005
    assert np.linalg.norm(top[["x_mm", "y_mm", "z_mm"]].to_numpy(float) - gens["LPP"]) <= 15
    # the labels name the planted generators' regions (AAL): the LPP's in the precuneus, the N170's
    # in the lateral occipito-temporal cortex of each hemisphere
    assert top.region.startswith("Precuneus") and top.brodmann == 7
    # per-level FWE maps (thesis Fig. 7.8, upper panel): the N170 activation of the most stylised
    # level peaks at a planted N170 generator
    lv = pd.read_csv(out / "source" / "level_fwe.csv")
    n170 = lv[(lv.component == "N170") & (lv.level == 0)].iloc[0]
    assert n170.n_significant > 0 and n170.peak_p_fwe < 0.05
    at = n170[["x_mm", "y_mm", "z_mm"]].to_numpy(float)
    assert min(np.linalg.norm(at - gens[g]) for g in ("N170_left", "N170_right")) <= 15
    assert (out / "figures" / "level_N170_0.png").is_file()
    near = peaks[(peaks.component == "N170") & (peaks.level == 0)].iloc[:2]
    for r in near.itertuples():
        assert r.region.rsplit("_", 1)[0] in ("Occipital_Inf", "Occipital_Mid", "Fusiform", "Temporal_Inf"), r.region
        assert r.region.endswith("_L" if r.x_mm < 0 else "_R")


def test_amplitudes_equal_plain_mne_script(study):
    """Our window means == benchmarks/erp.py's plain_mne (the same steps written directly in MNE)."""
    from analysis.erp.channels import make_montage
    from analysis.erp.config import load_erp_config

    spec = importlib.util.spec_from_file_location("bench_erp", Path(__file__).parent.parent / "benchmarks" / "erp.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    cfg = load_erp_config(study["config"])
    comps = bench._components(cfg, make_montage("biosemi128").ch_names)
    path = study["sim"]["files"][1]
    ref = bench.plain_mne(path, {int(c): lv for c, lv in cfg.events.items()}, comps, bads=study["sim"]["bad_channels"]["02"])
    amps = pd.read_csv(study["out"] / "amplitudes.csv")
    amps = amps[amps.subject == 2]
    ours = {((r.stylisation, r.emotion), r.component, r.cluster): r.mean_uV for r in amps.itertuples()}
    assert set(ref) == set(ours)
    assert max(abs(ref[k] - ours[k]) for k in ref) < 1e-4  # CSV keeps 6 significant digits


def test_shared_forward_equals_per_subject_forward(study):
    """process_subjects computes the montage's forward once; a subject's pick of it equals its own forward."""
    import mne

    from analysis.erp.config import load_erp_config
    from analysis.erp.io import read_recording
    from analysis.erp.pipeline import _head_info
    from analysis.erp.preprocessing import setup_channels
    from analysis.erp.source import _forward, add_forward, template_head

    cfg = load_erp_config(study["config"])
    path = study["sim"]["files"][2]
    head = template_head(_head_info(cfg, path), DESIGN.spacing_mm)
    raw = read_recording(path)
    setup_channels(raw, cfg.montage, cfg.eog, path)
    info = raw.pick("eeg").set_eeg_reference("average", projection=True, verbose="error").info
    own = _forward(head, info)  # head.forward is None: computed for this subject
    add_forward(head, _head_info(cfg, path))
    shared = _forward(head, info)
    assert shared is not head.forward and shared["sol"]["data"].shape == own["sol"]["data"].shape
    assert shared["info"]["ch_names"] == own["info"]["ch_names"] == info["ch_names"]
    assert np.array_equal(shared["sol"]["data"], own["sol"]["data"])
    # electrodes elsewhere (another montage): the subject gets its own forward again
    moved = info.copy()
    with moved._unlock():
        moved["chs"][0]["loc"][:3] += 0.01
    assert not np.array_equal(_forward(head, moved)["sol"]["data"], shared["sol"]["data"])
    assert mne.pick_types(moved, eeg=True).size == 128
