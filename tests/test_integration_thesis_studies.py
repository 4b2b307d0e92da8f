"""Exp. 1a, 1b, 1c, 2 (with the photographs rated at the end) and 3 end to end from their shipped files: simulated participants in the real runner
(the shipped protocol with drawn faces as stimuli), then the shipped analysis file (its data glob
pointed at them) writes the ANOVA tables, post-hocs, reliabilities and figures the thesis reports."""

from __future__ import annotations

import json
import subprocess
import sys

import pandas as pd
import pytest
import yaml

from appeal.assets import protocols_dir
from appeal_cli import main

STUDIES = {
    "exp1a": ("exp1a_shape_material.yaml", ["exp1a_ratings.yaml"],
              {"shape": [1.0, 0.5, 0.0], "material": ["flat", "bilateral", "original"],
               "expression": ["neutral", "anger", "happiness", "sadness", "surprise"]},
              {"shape": 2, "material": 2, "expression": 4, "shape:material": 4}),
    "exp1b": ("exp1b_shading_lighting.yaml", ["exp1b_ratings.yaml"],
              {"shape": [0.0, 0.5, 1.0], "material": ["original"], "shading": ["pbr", "phong"],
               "lighting": ["direct_hard", "direct_soft", "gi_soft"],
               "expression": ["neutral", "anger", "happiness", "sadness", "surprise"]},
              {"shading": 1, "lighting": 2, "expression": 4, "shading:lighting": 2}),
    "exp1c": ("exp1c_texture.yaml", ["exp1c_ratings.yaml"],
              {"shape": [0.0, 0.5, 1.0], "material": ["flat", "bilateral", "blur50", "blur25", "original"],
               "expression": ["neutral"]},
              {"shape": 2, "material": 4, "shape:material": 8}),
    "exp2": ("exp2_stylisation.yaml", ["exp2_ratings.yaml"],
             {"character": ["c1", "c2"], "shape": [1.0, 0.5, 0.0], "material": ["flat", "blur50", "original"],
              "expression": ["neutral", "happiness"]},
             {"character": 1, "shape": 2, "material": 2, "expression": 1, "shape:material": 4}),
    "exp3": ("exp3_expressions.yaml", ["exp3_ratings.yaml", "exp3_recognition.yaml"],
             {"character": ["c1", "c2"], "shape": [0.0, 0.5, 1.0], "material": ["flat", "original"],
              "expression": ["neutral", "anger", "happiness", "sadness", "surprise"]},
             {"character": 1, "shape": 2, "material": 1, "expression": 4, "shape:expression": 8}),
}


@pytest.mark.slow
@pytest.mark.parametrize("study", sorted(STUDIES))
def test_shipped_study_runs_and_is_analysed(study, tmp_path, capsys):
    from experiments.drawn_faces import draw_face_grid

    proto_name, analysis_names, levels, dfs = STUDIES[study]
    manifest = draw_face_grid(tmp_path / "faces", levels, size=(160, 120))
    if study == "exp2":  # photographs of the actors, rated at the end of the session
        photos = draw_face_grid(tmp_path / "photos", {"character": ["c1", "c2"], "shape": ["photograph"],
                                                      "material": ["photograph"], "expression": ["neutral"]},
                                size=(160, 120))
        both = pd.concat([pd.read_csv(m).assign(file=lambda t, m=m: [str(m.parent / f) for f in t.file])
                          for m in (manifest, photos)])
        manifest = tmp_path / "manifest.csv"
        both.to_csv(manifest, index=False)
    proto = yaml.safe_load((protocols_dir() / proto_name).read_text())
    proto["stimuli"].pop("grid", None)
    if "levels" in proto["stimuli"]:  # the drawn faces' levels (anchors pair shape and material by position)
        proto["stimuli"]["levels"] = {f: levels[f] for f in proto["stimuli"]["levels"]}
    proto["stimuli"]["manifest"] = str(manifest)
    assert proto["timing"]["stimulus_visible_during_response"] is False  # the thesis's exposure
    pfile = tmp_path / proto_name
    pfile.write_text(yaml.safe_dump(proto, allow_unicode=True))
    n_subjects = 5
    for i in range(n_subjects):
        cmd = [sys.executable, "-m", "appeal_cli", "-q", "run", str(pfile), "--participant", f"{i + 1:02d}",
               "--out", str(tmp_path / "data" / f"sub-{i + 1:02d}"), "--simulate", "default",
               "--seed", str(10 + i), "--no-window"]
        res = subprocess.run(cmd, capture_output=True, text=True, check=False, timeout=600)
        assert res.returncode == 0, res.stderr
    for analysis_name in analysis_names:
        _analyse(tmp_path, analysis_name, dfs, n_subjects, capsys, levels)
    raw = pd.concat(pd.read_csv(f, sep="\t") for f in (tmp_path / "data").rglob("*_beh.tsv"))
    if study == "exp1c":  # three passes: every cell rated three times, averaged for the ANOVA
        main_rows = raw[raw["phase"] == "main"]
        assert (main_rows.groupby(["participant_id", "shape", "material"]).size() == 3).all()
    if study == "exp2":  # the photographs' ratings beside the three matched levels, per scale
        for scale in ("realism", "appeal"):
            ref = pd.read_csv(tmp_path / "exp2_ratings" / scale / "reference_photograph.csv")
            assert ref["condition"].tolist()[0] == "photograph" and len(ref) == 4
            assert ref.loc[0, "n"] == n_subjects and ref.loc[1:, "p_holm"].notna().all()
    if study == "exp3":  # recognition is a proportion, with errors to analyse
        assert 0.3 < raw.loc[raw["phase"] == "main", "correct_expression"].mean() < 1.0


def _analyse(tmp_path, analysis_name, dfs, n_subjects, capsys, levels):
    """Run a shipped analysis file on the simulated sessions and check what it wrote."""
    analysis = yaml.safe_load((protocols_dir() / "analysis" / analysis_name).read_text())
    analysis["data"] = str(tmp_path / "data" / "**" / "*_beh.tsv")
    for f in analysis.get("levels", {}):  # the drawn faces' levels, in the file's order (most stylised first)
        analysis["levels"][f] = levels[f]
    afile = tmp_path / analysis_name
    afile.write_text(yaml.safe_dump(analysis))
    out = tmp_path / analysis_name.removesuffix(".yaml")
    assert main(["analyze", "ratings", str(afile), "--out", str(out)]) == 0, capsys.readouterr().err
    res = json.loads((out / "results.json").read_text())
    assert set(res["scales"]) == set(analysis["scales"])
    for scale in analysis["scales"]:
        anova = {e["effect"]: e for e in res["scales"][scale]["anova"]}
        for effect, df in dfs.items():
            assert anova[effect]["num_df"] == df and anova[effect]["den_df"] == df * (n_subjects - 1), (scale, effect)
        assert list((out / scale).glob("*.png"))
        for e in res["scales"][scale]["anova"]:  # Tukey HSD for every significant main effect
            if ":" not in e["effect"] and max(e["p"], e.get("p_gg") or 0) < 0.05:  # significant either way
                assert (out / scale / f"posthoc_{e['effect']}.csv").is_file(), (scale, e["effect"])
    groups = analysis.get("reliability") or ([analysis["scales"]] if len(analysis["scales"]) >= 2 else [])
    assert {r["scales"] for r in res.get("reliability", [])} == {" + ".join(g) for g in groups}
    assert all(0 < r["alpha"] <= 1 for r in res.get("reliability", []) if r["scales"] != "appeal + realism")
