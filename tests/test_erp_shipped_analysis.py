"""The shipped ERP analysis file (fsaverage template head, 5 mm grid, clusters >= 200 mm3, atlas
labels) end to end on simulated BioSemi recordings coded as the shipped runner protocol codes them."""

from __future__ import annotations

import pandas as pd
import pytest
import yaml

from analysis.erp.atlas import atlas_available
from analysis.erp.simulate import SimulationDesign, simulate_study
from appeal.assets import protocols_dir
from appeal_cli import main

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not atlas_available(), reason="needs the atlases: pip install 'appeal-lab[atlas]'")]


def test_the_shipped_erp_analysis_runs_as_written(tmp_path):
    sim = simulate_study(tmp_path / "data", SimulationDesign(n_subjects=5, trials_per_cell=6, sfreq=128, seed=5))
    cfg = yaml.safe_load((protocols_dir() / "analysis" / "erp_stylisation.yaml").read_text())
    assert cfg["source"]["bem"] == "fsaverage" and cfg["source"]["spacing_mm"] <= 5
    cfg["recordings"] = [str(f) for f in sim["files"]]
    cfg["events"] = {"protocol": str(protocols_dir() / "erp_stylisation.yaml")}  # the runner's own codes
    cfg["source"].update(contrasts=[[5, 0]], components=["N170"], n_permutations=32)
    config = tmp_path / "erp.yaml"
    config.write_text(yaml.safe_dump(cfg, sort_keys=False))
    out = tmp_path / "out"
    assert main(["-q", "analyze", "erp", str(config), "--out", str(out), "--n-jobs", "2"]) == 0
    report = (out / "report.md").read_text()
    assert "fsaverage BEM head model, volume grid 5 mm" in report and "clusters ≥ 200 mm³" in report
    levels = pd.read_csv(out / "source" / "level_fwe.csv")
    assert set(levels["component"]) == {"N170"} and (levels["area"].notna()).all()
    assert "| Cluster voxels (mm³) | Peak t |" in report or "No cluster reached the size threshold." in report
    amps = pd.read_csv(out / "amplitudes.csv")
    assert sorted(amps["subject"].unique()) == [1, 2, 3, 4, 5]
