"""appeal analyze anova/posthoc/contrasts/ratings, the ratings study file, reporting and the simulator."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis import rm_anova
from analysis.ratings_schema import RatingsAnalysis
from analysis.stats.reporting import anova_text, format_effect, markdown_table
from analysis.stats.simulate import ScaleModel, exp2_design, simulate_ratings, write_bids
from appeal_cli import main
from appeal.errors import StudyFileError
from appeal.studyfile import validate_data
from r_reference_numbers import r_reference

DATA = Path(__file__).parent / "data"
W2 = str(DATA / "stats_within2_likert.csv")
OBK = str(DATA / "stats_obk_long.csv")


def test_anova_json_keys_and_values(tmp_path, capsys):
    out = tmp_path / "a.json"
    assert main(["analyze", "anova", OBK, "--dv", "value", "--subject", "id", "--within", "phase", "hour",
                 "--between", "treatment", "gender", "--json", str(out)]) == 0
    effects = json.loads(out.read_text())["effects"]
    assert [e["effect"] for e in effects][:4] == ["treatment", "gender", "treatment:gender", "phase"]
    assert list(effects[0]) == ["effect", "SS", "error_SS", "num_df", "den_df", "F", "p", "mauchly_W", "mauchly_p",
                                "gg_eps", "hf_eps", "p_gg", "p_hf", "pes", "ges", "note"]
    assert effects[0]["mauchly_W"] is None and effects[0]["gg_eps"] is None  # between effect: undefined
    hour = next(e for e in effects if e["effect"] == "hour")
    assert hour["F"] == pytest.approx(r_reference("anova_reference")["R_OBK"]["hour"]["F"], rel=1e-9)
    assert "F*(" in capsys.readouterr().out  # hour violates sphericity -> GG in the text


def test_posthoc_and_contrasts_json(tmp_path):
    p = tmp_path / "p.json"
    assert main(["analyze", "posthoc", W2, "--dv", "rating", "--subject", "id", "--within", "A", "B",
                 "--effect", "A", "--json", str(p)]) == 0
    comps = json.loads(p.read_text())["comparisons"]
    assert [(c["a"], c["b"]) for c in comps] == [("a1", "a2"), ("a1", "a3"), ("a2", "a3")]
    assert set(comps[0]) == {"effect", "a", "b", "diff", "se", "df", "q", "p"}
    # emmeans' Tukey p values (tests/r_reference/anova_reference.out, R_PAIRS_W2_A)
    r_pairs = r_reference("anova_reference")["R_PAIRS_W2_A"]
    assert [c["p"] for c in comps] == pytest.approx([row[-1] for row in r_pairs], rel=1e-6)
    c = tmp_path / "c.json"
    assert main(["analyze", "contrasts", W2, "--dv", "rating", "--subject", "id", "--within", "A", "B",
                 "--factor", "B", "--json", str(c)]) == 0
    rows = json.loads(c.read_text())["contrasts"]
    assert [r["contrast"] for r in rows] == ["linear", "quadratic", "cubic"]
    assert rows[0]["F"] == pytest.approx(r_reference("anova_reference")["R_POLY_W2_B"][1][0], rel=1e-9)


def test_cli_bad_input_is_one_line(tmp_path, capsys):
    assert main(["analyze", "anova", W2, "--dv", "ratng", "--subject", "id", "--within", "A", "B"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"{W2}: dv: column 'ratng' not found (did you mean 'rating'?)"]
    assert main(["analyze", "anova", str(tmp_path / "nope.csv"), "--dv", "x", "--within", "A"]) == 2
    assert "nope.csv: file not found" in capsys.readouterr().err


def test_reporting_thesis_style():
    gg_row = {"effect": "shape", "num_df": 4, "den_df": 80, "F": 178.666, "p": 1e-30, "mauchly_W": 0.1,
              "mauchly_p": 0.001, "gg_eps": 0.495, "p_gg": 1e-20, "pes": 0.9}
    assert format_effect(gg_row, pes=False) == "F*(1.98, 39.6) = 178.67, p < 0.0001, ε = 0.495"
    plain = dict(gg_row, mauchly_p=0.3, F=44.23)
    assert format_effect(plain, pes=False) == "F(4, 80) = 44.23, p < 0.0001"
    assert format_effect(dict(plain, p=0.021)) == "F(4, 80) = 44.23, p = 0.021, ηp² = 0.900"
    t = rm_anova(pd.read_csv(W2), "rating", "id", ["A", "B"])
    text = anova_text(t)
    assert text.splitlines()[0].startswith("- **A**: F(2, 14) = 10.42, p = 0.002")
    assert markdown_table(t).splitlines()[1].startswith("|---|")


def _write_study(tmp_path, n_subjects=8, **extra):
    factors = {"shape": ["s0", "s1", "s2"], "material": ["m0", "m1", "m2"]}
    scales = {"appeal": ScaleModel(mean=lambda c: 4 - (c["shape"] - c["material"]) ** 2 * 0.5),
              "reassurance": ScaleModel(mean=lambda c: 4 - (c["shape"] - c["material"]) ** 2 * 0.4)}
    df = simulate_ratings(factors, scales, n_subjects=n_subjects, repetitions=2, seed=3, **extra)
    write_bids(df, tmp_path / "data", "t")
    study = tmp_path / "study.yaml"
    study.write_text("kind: ratings\ndata: data/sub-*/ses-*/beh/*_beh.tsv\nwithin: [shape, material]\n"
                     "contrasts: [{factor: shape}]\nfigures: {interactions: [{x: material, trace: shape}]}\n")
    return study, df


def test_ratings_command_writes_report(tmp_path):
    study, _ = _write_study(tmp_path)
    out = tmp_path / "out"
    assert main(["analyze", "ratings", str(study), "--out", str(out)]) == 0
    for f in ("report.md", "index.html", "results.json", "provenance.json", "reliability.csv",
              "appeal/anova.csv", "appeal/interaction_material_by_shape.png",
              "appeal/interaction_material_by_shape.svg", "reassurance/contrasts_shape.csv"):
        assert (out / f).is_file(), f
    res = json.loads((out / "results.json").read_text())
    assert set(res["scales"]) == {"appeal", "reassurance"}
    assert res["scales"]["appeal"]["analysis"] == "rm-ANOVA"
    sm = {r["effect"]: r for r in res["scales"]["appeal"]["anova"]}
    assert sm["shape:material"]["p"] < 0.001  # the simulated mismatch effect is found
    assert res["reliability"][0]["alpha"] > 0.5
    assert (out / "appeal" / "posthoc_shape_x_material.csv").is_file()


def test_ratings_command_with_two_participants(tmp_path):
    """Two participants: 1 error df, so no Mauchly and no HF ε; the report says so instead of failing."""
    study, _ = _write_study(tmp_path, n_subjects=2)
    out = tmp_path / "out"
    assert main(["analyze", "ratings", str(study), "--out", str(out)]) == 0
    rows = {r["effect"]: r for r in json.loads((out / "results.json").read_text())["scales"]["appeal"]["anova"]}
    assert rows["shape"]["den_df"] == 2 and rows["shape"]["hf_eps"] is None and rows["shape"]["mauchly_W"] is None
    assert rows["shape"]["gg_eps"] == pytest.approx(0.5)  # rank-1 error matrix: the lower bound 1/d
    assert "HF ε undefined" in rows["shape"]["note"]
    report = (out / "report.md").read_text()
    assert "nan" not in report.lower().replace("nanopore", "") and "HF ε undefined" in report


def test_ratings_incomplete_design_uses_mixed_model(tmp_path):
    study, _ = _write_study(tmp_path)
    f = sorted((tmp_path / "data").rglob("sub-02_*_beh.tsv"))[0]
    df = pd.read_csv(f, sep="\t")
    df = df[~((df["shape"] == "s1") & (df["material"] == "m2"))]
    df.to_csv(f, sep="\t", index=False)
    out = tmp_path / "out"
    assert main(["analyze", "ratings", str(study), "--out", str(out)]) == 0
    res = json.loads((out / "results.json").read_text())
    assert res["scales"]["appeal"]["analysis"] == "mixed model"
    assert res["scales"]["appeal"]["dropped"] == ["sub-02"]
    assert "linear mixed model" in (out / "report.md").read_text()


def test_study_file_errors(tmp_path):
    base = {"kind": "ratings", "data": "x/*.tsv", "within": ["shape"]}
    with pytest.raises(StudyFileError) as e:
        validate_data({**base, "levels": {"colour": [1, 2]}}, RatingsAnalysis, source="s.yaml", base_dir=tmp_path)
    assert "s.yaml: (top level): levels: colour is not a within or between factor (expected one of: shape)" in str(e.value)
    with pytest.raises(StudyFileError) as e:
        validate_data({**base, "data": "missing.csv"}, RatingsAnalysis, source="s.yaml", base_dir=tmp_path)
    assert str(e.value).startswith("s.yaml: data: file not found:")
    with pytest.raises(StudyFileError) as e:
        validate_data({**base, "alpha": 2}, RatingsAnalysis, source="s.yaml", base_dir=tmp_path)
    assert "s.yaml: alpha: must be < 1 (got 2)" in str(e.value)


def test_simulator_is_deterministic_and_bids_like(tmp_path):
    factors, scales = exp2_design()
    a = simulate_ratings(factors, scales, n_subjects=3, seed=5)
    b = simulate_ratings(factors, scales, n_subjects=3, seed=5)
    pd.testing.assert_frame_equal(a, b)
    assert len(a) == 3 * 250
    assert {"participant_id", "trial", "block", "stimulus", "shape", "response_appeal", "rt_realism"} <= set(a.columns)
    assert a.response_appeal.between(1, 7).all() and (a.response_appeal % 1 == 0).all()
    files = write_bids(a, tmp_path, "exp2")
    assert [p.name for p in files][0] == "sub-01_ses-1_task-exp2_beh.tsv"
    # the realism model: shape dominates, realistic shapes are rated more realistic
    big = simulate_ratings(factors, scales, n_subjects=21, seed=1)
    t = rm_anova(big, "response_realism", "participant_id", list(factors), aggregate="mean").set_index("effect")
    assert t.loc["shape", "pes"] > 0.8 and t.loc["shape", "mauchly_p"] < 0.05
    m = big.groupby("shape")["response_realism"].mean()
    assert np.all(np.diff(m.to_numpy()) > 0)


@pytest.mark.parametrize("fmt", ["parquet", "tsv"])
def test_anova_reads_parquet_and_tsv_like_csv(tmp_path, fmt):
    """The same long-format table as CSV, TSV or Parquet gives the same ANOVA table."""
    df = pd.read_csv(OBK)
    other = tmp_path / f"obk.{fmt}"
    if fmt == "parquet":
        df.to_parquet(other, index=False)
    else:
        df.to_csv(other, sep="\t", index=False)
    args = ["--dv", "value", "--subject", "id", "--within", "phase", "hour", "--between", "treatment", "gender"]
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    assert main(["analyze", "anova", OBK, *args, "--json", str(a)]) == 0
    assert main(["analyze", "anova", str(other), *args, "--json", str(b)]) == 0
    assert json.loads(a.read_text()) == json.loads(b.read_text())
