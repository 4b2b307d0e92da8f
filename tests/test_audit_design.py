"""The audit tested against the design (issue 32 part 2): level means, thresholds, tests across items, the report."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from analysis.confounds import DEFAULT_THRESHOLDS, design_tests, flagged, level_means, parse_thresholds
from analysis.confounds.report import findings_markdown, describe_test
from appeal.errors import AppealInputError
from appeal_cli import main
from grid_fixtures import render_tiny_grid
from stimulus_engine.audit.workflow import audit_factors, paired_factors


def _crossed(seed: int = 0) -> pd.DataFrame:
    """4 characters x 3 shapes x 2 expressions; face_L_mean rises 3 L* per shape level plus noise,
    face_area does not change with shape."""
    rng = np.random.default_rng(seed)
    rows = []
    for c, (k, s), e in itertools.product("abcd", enumerate([0.0, 0.5, 1.0]), ["neutral", "happy"]):
        rows.append({"file": f"{c}_{s}_{e}.png", "character": c, "shape": s, "expression": e,
                     "face_L_mean": 50 + 3 * k + rng.normal(0, 0.5) + (2 if c == "b" else 0),
                     "face_area": 0.3 + rng.normal(0, 0.001)})
    return pd.DataFrame(rows)


def _hand_rm_anova(y: np.ndarray) -> tuple[float, float, float]:
    """One-way repeated-measures ANOVA of ``y`` (items x levels): F, df1, df2."""
    n, k = y.shape
    grand = y.mean()
    ss_level = n * ((y.mean(0) - grand) ** 2).sum()
    ss_item = k * ((y.mean(1) - grand) ** 2).sum()
    ss_error = ((y - grand) ** 2).sum() - ss_level - ss_item
    df1, df2 = k - 1, (k - 1) * (n - 1)
    return (ss_level / df1) / (ss_error / df2), df1, df2


def test_level_means_range_and_flags_are_the_hand_computed_ones():
    t = _crossed()
    tests = design_tests(t, ["character", "shape", "expression"])
    row = tests[(tests["factor"] == "shape") & (tests["measure"] == "face_L_mean")].iloc[0]
    means = t.groupby("shape")["face_L_mean"].mean()
    assert row["lowest_level"] == 0.0 and row["highest_level"] == 1.0
    assert row["lowest_mean"] == pytest.approx(means[0.0]) and row["highest_mean"] == pytest.approx(means[1.0])
    assert row["range"] == pytest.approx(means.max() - means.min()) and row["range"] > 5
    assert row["threshold"] == DEFAULT_THRESHOLDS["face_L_mean"] and row["flagged"]
    assert row["relative_range"] == pytest.approx(row["range"] / 2.0)
    area = tests[(tests["factor"] == "shape") & (tests["measure"] == "face_area")].iloc[0]
    assert not area["flagged"]
    # a threshold the user sets decides the flag
    loose = design_tests(t, ["shape"], thresholds={"face_L_mean": 100.0})
    assert not loose["flagged"].any() and loose.loc[loose["measure"] == "face_L_mean", "threshold"].item() == 100.0
    lm = level_means(t, ["shape"], ["face_L_mean"])
    assert list(lm["level"]) == [0.0, 0.5, 1.0] and list(lm["n"]) == [8, 8, 8]
    assert lm["mean"].tolist() == pytest.approx(means.tolist())
    assert list(flagged(tests)["relative_range"]) == sorted(flagged(tests)["relative_range"], reverse=True)


def test_within_items_test_is_the_hand_computed_rm_anova():
    t = _crossed()
    row = design_tests(t, ["character", "shape", "expression"]).query("factor == 'shape' and measure == 'face_L_mean'").iloc[0]
    # the items of shape: every character x expression, each seen at the three shapes
    y = t.pivot_table(index=["character", "expression"], columns="shape", values="face_L_mean").to_numpy()
    F, df1, df2 = _hand_rm_anova(y)
    assert row["test"] == "rm-ANOVA across 8 items" and row["n_items"] == 8
    assert (row["num_df"], row["den_df"]) == (df1, df2) and row["F"] == pytest.approx(F, rel=1e-10)
    assert row["p"] == pytest.approx(stats.f.sf(F, df1, df2), rel=1e-8) and row["p"] < 1e-6
    assert 0 < row["effect_size"] < 1 and row["effect_size_kind"] == "partial eta^2"
    # items named by the user: the characters, expressions averaged within each
    byc = design_tests(t, ["shape", "expression"], item=["character"]).query("factor == 'shape' and measure == 'face_L_mean'").iloc[0]
    F4, d1, d2 = _hand_rm_anova(t.pivot_table(index="character", columns="shape", values="face_L_mean").to_numpy())
    assert byc["n_items"] == 4 and (byc["num_df"], byc["den_df"]) == (d1, d2) and byc["F"] == pytest.approx(F4, rel=1e-10)
    assert "F(2, 14) = " in describe_test(row) and "ηp²" in describe_test(row)


def test_between_items_test_is_scipys_one_way_anova_with_its_eta_squared():
    rng = np.random.default_rng(1)
    t = pd.DataFrame({"file": [f"p{i}.jpg" for i in range(12)], "group": ["x"] * 6 + ["y"] * 6,
                      "face_L_mean": np.r_[rng.normal(40, 1, 6), rng.normal(45, 1, 6)]})
    t["photo"] = t["file"]
    row = design_tests(t, ["group"], item=["photo"]).query("measure == 'face_L_mean'").iloc[0]
    F, p = stats.f_oneway(t.loc[t.group == "x", "face_L_mean"], t.loc[t.group == "y", "face_L_mean"])
    y = t["face_L_mean"].to_numpy()
    eta2 = 6 * ((y[:6].mean() - y.mean()) ** 2 + (y[6:].mean() - y.mean()) ** 2) / ((y - y.mean()) ** 2).sum()
    assert row["test"] == "one-way ANOVA between 12 items" and (row["num_df"], row["den_df"]) == (1, 10)
    assert row["F"] == pytest.approx(F) and row["p"] == pytest.approx(p) and row["effect_size"] == pytest.approx(eta2)
    assert "η² = " in describe_test(row)


def test_designs_without_a_test_say_why():
    one = pd.DataFrame({"file": ["a.png", "b.png"], "shape": [0, 1], "face_L_mean": [40.0, 50.0]})
    row = design_tests(one, ["shape"]).iloc[0]
    assert row["test"] == "none: one image per level" and math.isnan(row["F"]) and row["flagged"]
    assert describe_test(row) == "none: one image per level"
    ragged = pd.DataFrame({"file": list("abcde"), "shape": [0, 1, 0, 1, 1], "expression": ["n", "n", "h", "h", "s"],
                           "face_L_mean": [40.0, 41, 42, 43, 44]})
    row = design_tests(ragged, ["shape", "expression"]).query("factor == 'shape'").iloc[0]
    assert row["test"] == "none: one item (no other factor crossed with it; name the items)"
    row = design_tests(ragged, ["shape"], item=["expression"]).iloc[0]
    assert row["test"] == "none: items seen at some levels only"
    with pytest.raises(AppealInputError, match="no column 'lighting'"):
        design_tests(one, ["lighting"])


def test_paired_factors_are_tested_once():
    t = _crossed()
    t["material"] = t["shape"].map({0.0: "original", 0.5: "paint1", 1.0: "paint2"})  # one level per shape level
    t["stylisation"] = t["shape"].map({0.0: 0, 0.5: 1, 1.0: 2})
    assert paired_factors(t, ["character", "shape", "stylisation", "material", "expression"]) == {
        "stylisation": "shape", "material": "shape"}
    t.attrs["factors"] = ["character", "shape", "stylisation", "material", "expression"]
    assert audit_factors(t) == ["character", "shape", "expression"]
    text = findings_markdown(design_tests(t, audit_factors(t)), {"stylisation": "shape", "material": "shape"})
    assert "**shape (= stylisation, material: the same split of the images)**" in text
    assert "**expression**: no measure differs beyond its threshold." in text


def test_thresholds_parse_or_give_one_line_errors():
    assert parse_thresholds(["face_L_mean=1.5", "iod_px=4"]) == {"face_L_mean": 1.5, "iod_px": 4.0}
    for bad, what in (("face_L_mean", "expected MEASURE=VALUE"), ("face_L_mean=abc", "expected MEASURE=VALUE"),
                      ("face_L_mean=-1", "expected MEASURE=VALUE"), ("luminance=2", "unknown measure 'luminance'")):
        with pytest.raises(AppealInputError, match=what):
            parse_thresholds([bad])


# ------------------------------------------------------------------------------ the command and the grid's page
@pytest.fixture(scope="module")
def grid_dir(tmp_path_factory) -> Path:
    return render_tiny_grid(tmp_path_factory.mktemp("audit_design"))


def test_audit_command_writes_tests_flags_and_report(grid_dir, tmp_path):
    from PIL import Image

    out = tmp_path / "a"
    assert main(["stimuli", "audit", str(grid_dir), "--out", str(out)]) == 0
    tests = pd.read_csv(out / "design_tests.csv")
    assert set(tests["factor"]) == {"shape", "expression"}
    # the tiny grid's shape levels have one image per expression: the expressions are the items
    assert (tests["test"] == "rm-ANOVA across 2 items").all()
    table = pd.read_csv(out / "audit.csv")
    shape_l = tests.query("factor == 'shape' and measure == 'face_L_mean'").iloc[0]
    m = table.groupby("shape")["face_L_mean"].mean()
    assert shape_l["range"] == pytest.approx(m.max() - m.min())
    report = (out / "report.html").read_text()
    assert "What differs between levels" in report and "flags.png" in report and "design_tests.csv" in report
    md = (out / "report.md").read_text()
    assert md.startswith("# Stimulus audit") and "## All tests" in md
    with Image.open(out / "flags.png") as im:
        assert im.size[0] > 400
    # every threshold raised: nothing flagged, and the report says which were set
    big = [f"--threshold={k}=1e9" for k in DEFAULT_THRESHOLDS]
    assert main(["stimuli", "audit", str(grid_dir), "--out", str(tmp_path / "b"), *big]) == 0
    assert not pd.read_csv(tmp_path / "b" / "design_tests.csv")["flagged"].any()
    assert "**0 differ between levels" in (tmp_path / "b" / "report.md").read_text()


def test_audit_options_give_one_line_errors(grid_dir, tmp_path, capsys):
    for args, what in ((["--threshold", "brightness=3"], "unknown measure 'brightness'"),
                       (["--item", "actor"], "no column 'actor'")):
        assert main(["stimuli", "audit", str(grid_dir), "--out", str(tmp_path / "x"), *args]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and what in err, err
        assert not (tmp_path / "x").exists()


def test_photographs_listed_in_a_csv_are_tested_by_the_columns_named(shared_data, tmp_path):
    """Real photographs (London face set): a smile against the same people's neutral faces, within
    identities; gender between identities (the item named with --item)."""
    root = shared_data / "faces2d" / "london-frl"
    rows = []
    for face, gender in (("001", "female"), ("002", "female"), ("004", "male"), ("005", "male")):
        rows.append({"file": str(root / "neutral_front" / f"{face}_03.jpg"), "face_id": face, "expression": "neutral",
                     "gender": gender})
        rows.append({"file": str(root / "smiling_front" / f"{face}_08.jpg"), "face_id": face, "expression": "smiling",
                     "gender": gender})
    pd.DataFrame(rows).to_csv(tmp_path / "photos.csv", index=False)
    out = tmp_path / "a"
    assert main(["stimuli", "audit", str(tmp_path / "photos.csv"), "--factor", "expression", "--factor", "gender",
                 "--item", "face_id", "--out", str(out)]) == 0
    table = pd.read_csv(out / "audit.csv")
    assert set(table["mask"]) == {"landmarks"} and table["iod_px"].notna().all()
    tests = pd.read_csv(out / "design_tests.csv")
    smile = tests.query("factor == 'expression' and measure == 'face_L_mean'").iloc[0]
    assert smile["test"] == "rm-ANOVA across 4 items" and (smile["num_df"], smile["den_df"]) == (1, 3)
    d = table.pivot_table(index="face_id", columns="expression", values="face_L_mean")
    t = stats.ttest_rel(d["smiling"], d["neutral"])
    assert smile["F"] == pytest.approx(t.statistic ** 2, rel=1e-9) and smile["p"] == pytest.approx(t.pvalue, rel=1e-7)
    sex = tests.query("factor == 'gender' and measure == 'face_L_mean'").iloc[0]
    assert sex["test"] == "one-way ANOVA between 4 items" and (sex["num_df"], sex["den_df"]) == (1, 2)
    per_face = table.groupby(["face_id", "gender"])["face_L_mean"].mean().reset_index()
    F, _ = stats.f_oneway(*(g["face_L_mean"] for _, g in per_face.groupby("gender")))
    assert sex["F"] == pytest.approx(F, rel=1e-9)


def test_an_equalised_set_is_audited_in_the_same_masks_and_its_luminance_no_longer_differs(grid_dir, tmp_path):
    eq = tmp_path / "eq"
    assert main(["stimuli", "equalise", str(grid_dir / "manifest.csv"), "--match", "luminance", "--out", str(eq)]) == 0
    assert (eq / "grid.json").is_file()  # the framing travels with the images
    assert main(["stimuli", "audit", str(eq), "--out", str(tmp_path / "a")]) == 0
    table = pd.read_csv(tmp_path / "a" / "audit.csv")
    assert set(table["mask"]) == {"rendered"}
    tests = pd.read_csv(tmp_path / "a" / "design_tests.csv").set_index(["factor", "measure"])
    for factor in ("shape", "expression"):  # mean and sd of L* inside the mask: equal up to 8-bit rounding
        assert tests.loc[(factor, "face_L_mean"), "range"] < 0.3
        assert tests.loc[(factor, "face_rms_contrast"), "range"] < 0.005
        assert not tests.loc[(factor, "face_L_mean"), "flagged"]


def test_a_grid_with_photographs_measures_them_in_landmark_masks(shared_data, tmp_path):
    """The ERP set's layout: photographs as the top level, with their own material; the audit
    masks them by their landmarks and tests shape across the expressions (material, found at the
    photograph level only, is not crossed with shape)."""
    from grid_fixtures import TINY_GRID

    london = shared_data / "faces2d" / "london-frl"
    spec = TINY_GRID.replace("render: {width: 96, height: 72}", "render: {width: 240, height: 180}") + (
        "photographs:\n  - character: a\n    files: {"
        f"neutral: {london / 'neutral_front' / '001_03.jpg'}, happy: {london / 'smiling_front' / '001_08.jpg'}}}\n")
    (tmp_path / "g.yaml").write_text(spec)
    assert main(["stimuli", "grid", str(tmp_path / "g.yaml"), "--out", str(tmp_path / "o"), "--n-jobs", "1"]) == 0
    table = pd.read_csv(tmp_path / "o" / "audit" / "audit.csv")
    photo = table["shape"].astype(str) == "photograph"
    assert photo.sum() == 2 and set(table.loc[photo, "mask"]) == {"landmarks"}
    assert set(table.loc[~photo, "mask"]) == {"rendered"} and table.loc[photo, "iod_px"].notna().all()
    tests = pd.read_csv(tmp_path / "o" / "audit" / "design_tests.csv")
    by = tests.groupby("factor")["test"].first()
    assert by["shape"] == "rm-ANOVA across 2 items" and by["material"] == "rm-ANOVA across 2 items"
    assert by["expression"] == "rm-ANOVA across 3 items"
