"""A reference (photographs rated at the end) beside the matched shape/material levels (thesis
§6.4): per-participant means, paired t-tests and Holm's adjustment agree with R."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from analysis.stats.reference import matched_levels, reference_table
from appeal.errors import AppealInputError
from r_reference_numbers import r_reference

DATA = Path(__file__).parent / "data" / "stats_reference.csv"
LEVELS = {"shape": ["1.0", "0.5", "0.0"], "material": ["flat", "blur50", "original"]}


def _table() -> pd.DataFrame:
    d = pd.read_csv(DATA, dtype={"shape": str})
    return reference_table(d[d.phase == "end"], d[d.phase == "main"], "rating", "participant_id", ["shape", "material"],
                           LEVELS, name="photograph")


def test_reference_table_agrees_with_r():
    # numbers: Rscript tests/r_reference/reference_comparison_reference.R (base R t.test(paired = TRUE),
    # p.adjust(method = "holm")); one participant has no photograph ratings: n 6 for the tests
    ref = r_reference("reference_comparison_reference")["R_REFERENCE"]
    t = _table().set_index("condition")
    assert list(t.index) == list(ref)
    for cond, want in ref.items():
        for k, v in want.items():
            assert t.loc[cond, k] == pytest.approx(v, abs=1e-6), (cond, k)
    assert np.isnan(t.loc["photograph", "p"])


def test_levels_pair_by_position_and_mismatches_are_one_line():
    d = pd.DataFrame({"shape": [0.0, 0.5, 1.0, 10.0], "material": ["a", "b", "c", "d"]})
    assert matched_levels(d, ["shape", "material"]) == [("0.0", "a"), ("0.5", "b"), ("1.0", "c"), ("10.0", "d")]
    with pytest.raises(AppealInputError, match=r"the same number of levels \(shape: 4, material: 2\)"):
        matched_levels(d.iloc[:2].assign(material=["a", "a"]).pipe(lambda x: pd.concat([d, x])), ["shape", "material"],
                       {"material": ["a", "b"]})
    with pytest.raises(AppealInputError, match="no column 'texture'"):
        matched_levels(d, ["shape", "texture"])


def test_a_study_file_with_a_reference_writes_table_figure_and_text(tmp_path, capsys):
    from appeal_cli import main

    study = tmp_path / "ref.yaml"
    study.write_text(yaml.safe_dump({
        "kind": "ratings", "title": "reference", "data": str(DATA), "within": ["shape", "material"],
        "scales": ["rating"], "levels": {"shape": [1.0, 0.5, 0.0], "material": LEVELS["material"]},
        "reference": {"name": "photograph", "rows": {"phase": ["end"]}, "matched": ["shape", "material"]}}))
    assert main(["analyze", "ratings", str(study), "--out", str(tmp_path / "o")]) == 0, capsys.readouterr().err
    out = tmp_path / "o" / "rating"
    table = pd.read_csv(out / "reference_photograph.csv")
    assert len(table) == 4 and table.loc[0, "condition"] == "photograph"
    assert (out / "reference_photograph.png").is_file() and (out / "reference_photograph.svg").is_file()
    assert "photograph: mean 5.18 (SD 0.64, n = 6)" in (tmp_path / "o" / "report.md").read_text()
    # without reference rows (Exp. 2 run without photographs) the comparison is left out, said so
    none = tmp_path / "none.yaml"
    spec = yaml.safe_load(study.read_text())
    spec["reference"]["rows"] = {"phase": ["nothing"]}
    none.write_text(yaml.safe_dump(spec))
    assert main(["analyze", "ratings", str(none), "--out", str(tmp_path / "n")]) == 0
    assert "No photograph ratings in the data" in (tmp_path / "n" / "report.md").read_text()
    assert not (tmp_path / "n" / "rating" / "reference_photograph.csv").exists()
    bad = tmp_path / "bad.yaml"
    spec = yaml.safe_load(study.read_text())
    spec["reference"]["matched"] = ["colour", "material"]
    bad.write_text(yaml.safe_dump(spec))
    assert main(["validate", str(bad)]) == 2
    assert "reference.matched: 'colour' is not a within factor" in capsys.readouterr().err


def test_study_file_levels_match_the_runners_numbers():
    """The runner writes shape 1.0 as "1" next to "photograph" rows; a study file says 1.0."""
    from analysis.stats.design import factor_levels, level_key

    assert level_key("1") == level_key(1.0) == level_key("1.0") and level_key("flat") == ("s", "flat")
    assert level_key(True) == ("s", "True")
    assert factor_levels(pd.Series(["1", "0.5", "0"]), [1.0, 0.75, 0.5, 0.0]) == [1.0, 0.5, 0.0]
    with pytest.raises(ValueError, match="values 2 are not among the given levels"):
        factor_levels(pd.Series(["1", "2"]), [1.0, 0.5])
