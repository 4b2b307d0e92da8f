"""Runner output → rating analysis: simulated participants in the real runner, analysed as a study.

The runner writes anchors, practice and end-of-session rows next to the main trials; the
analysis must keep only the main trials and recover the simulated model's shape effect on
realism (the ``default`` participant model: realism rises linearly with shape level).
"""

from __future__ import annotations

import json
import subprocess
import sys

import pandas as pd
import yaml

from appeal.assets import protocols_dir
from appeal_cli import main


def _session(protocol, out, stimuli, participant, seed):
    cmd = [sys.executable, "-m", "appeal_cli", "-q", "run", str(protocol), "--participant", participant,
           "--out", str(out), "--simulate", "default", "--stimuli", str(stimuli), "--seed", str(seed), "--no-window"]
    res = subprocess.run(cmd, capture_output=True, text=True, check=False, timeout=600)
    assert res.returncode == 0, res.stderr


def test_simulated_sessions_analysed_as_a_rating_study(tmp_path, capsys):
    from experiments.drawn_faces import draw_face_grid

    levels = {"character": ["c1", "c2"], "shape": [0, 1, 2, 3, 4], "material": [0, 2, 4], "expression": ["neutral", "happiness"]}
    manifest = draw_face_grid(tmp_path / "faces", levels, size=(160, 120))
    proto = yaml.safe_load((protocols_dir() / "exp2_stylisation.yaml").read_text())
    proto["stimuli"].pop("levels")
    proto["stimuli"].pop("grid")
    proto["stimuli"]["manifest"] = str(manifest)
    proto["anchors"]["if_missing"] = "skip"
    pfile = tmp_path / "exp2.yaml"
    pfile.write_text(yaml.safe_dump(proto, allow_unicode=True))
    data = tmp_path / "data"
    for i in range(6):
        _session(pfile, data / f"sub-{i + 1:02d}", manifest, f"{i + 1:02d}", seed=100 + i)
    files = sorted(data.rglob("*_beh.tsv"))
    assert len(files) == 6
    raw = pd.concat([pd.read_csv(f, sep="\t") for f in files])
    n_main = int((raw["phase"] == "main").sum())
    assert n_main == 6 * 60 and len(raw) >= n_main

    study = tmp_path / "ratings.yaml"
    study.write_text(yaml.safe_dump({
        "kind": "ratings", "title": "integration", "data": "data/**/*_beh.tsv",
        "within": ["character", "shape", "material", "expression"], "scales": ["realism", "appeal"],
        "contrasts": [{"factor": "shape"}],
    }))
    assert main(["analyze", "ratings", str(study), "--out", str(tmp_path / "res")]) == 0, capsys.readouterr().err
    res = json.loads((tmp_path / "res" / "results.json").read_text())
    realism = res["scales"]["realism"]
    shape = next(e for e in realism["anova"] if e["effect"] == "shape")
    assert shape["p"] < 1e-4 and shape["num_df"] == 4
    contrasts = pd.read_csv(tmp_path / "res" / "realism" / "contrasts_shape.csv")
    linear = contrasts.set_index("contrast").loc["linear"]
    assert linear["p"] < 1e-4
