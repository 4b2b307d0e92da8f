"""BioSemi's own sample file (Newtest17-256.bdf) end to end from the shipped short config."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from appeal.assets import protocols_dir
from appeal_cli import main

CONFIG = protocols_dir() / "analysis" / "erp_biosemi_sample.yaml"


def _config(shared_data: Path, tmp_path: Path) -> Path:
    """The shipped config; a copy reading the data from ``$APPEAL_DATA`` when it lives elsewhere."""
    doc = yaml.safe_load(CONFIG.read_text())
    real = shared_data / "eeg/biosemi/Newtest17-256.bdf"
    if (CONFIG.parent / doc["recordings"]).resolve() == real.resolve():
        return CONFIG
    doc["recordings"] = str(real)
    copy = tmp_path / CONFIG.name
    copy.write_text(yaml.safe_dump(doc, sort_keys=False))
    return copy


def test_biosemi_sample_end_to_end(shared_data, tmp_path, capsys):
    config = _config(shared_data, tmp_path)
    assert main(["validate", str(config)]) == 0
    out = tmp_path / "out"
    assert main(["analyze", "erp", str(config), "--out", str(out), "--n-jobs", "1"]) == 0, capsys.readouterr().err
    amps = pd.read_csv(out / "amplitudes.csv")
    assert list(amps.columns) == ["subject", "condition", "component", "cluster", "mean_uV", "peak_uV",
                                  "peak_latency_ms", "frac_peak_latency_ms", "frac_area_latency_ms", "n_trials"]
    assert amps[["component", "cluster"]].values.tolist() == [["P1", "occipital"], ["N1", "occipital"],
                                                            ["P3", "parietal"]]
    assert (amps["condition"] == "trigger").all() and amps[["mean_uV", "peak_uV"]].notna().all().all()
    # 40 triggers of code 255 (the return to the resting value 254 is not an event); the last
    # one is 0.22 s before the end, too close for a -0.2 ... 0.8 s epoch
    qc = pd.read_csv(out / "qc.csv").iloc[0]
    assert qc["n_events"] == 40 and qc["n_epochs"] == 39 and (amps["n_trials"] == 39).all()
    assert qc["n_channels"] == 16  # A1..A16 renamed to the biosemi16 cap and all placed
    # single trials: the 39 kept epochs are the first 39 triggers; their means average to the cell's
    single = pd.read_csv(out / "single_trials.csv")
    assert len(single) == 39 * 3 and sorted(single["trial"].unique()) == list(range(1, 40))
    assert (single["code"] == 255).all() and single["stimulus"].isna().all()
    means = single.groupby("component", sort=False)["mean_uV"].mean()
    assert np.allclose(means[amps["component"]].to_numpy(), amps["mean_uV"], atol=1e-4)  # CSVs keep 6 digits
    sme = pd.read_csv(out / "sme.csv").set_index("component")["sme_uV"]
    sd = single.groupby("component")["mean_uV"].std(ddof=0) / np.sqrt(39)
    assert np.allclose(sme[sd.index], sd, rtol=1e-4)
    for f in ["report.md", "figures/waveforms.png", "figures/bars_P1.png", "figures/bars_N1.png",
              "figures/bars_P3.png", "provenance.json", "log.txt"]:
        assert (out / f).is_file(), f
    report = (out / "report.md").read_text()
    assert "1 subjects analysed" in report and "Statistics need at least two subjects" in report
    assert "Oz" in (out / "figures/waveforms.svg").read_text()
