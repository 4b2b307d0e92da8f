"""Stimulus audit measures as covariates (issue 32): the audit joined to trials by stimulus, the
centred covariate in the linear mixed model (against lme4 + lmerTest), the ANCOVA-style
adjustment of the rm-ANOVA path (against R's ``lm`` and afex), and the one-line errors.

Reference numbers: ``tests/r_reference/covariates_reference.R`` (output ``covariates_reference.out``)
on the data it writes: ``tests/data/covariates_ratings.csv`` (16 participants × 12 stimuli × 2
repetitions; 3 shape levels with 4 characters each) and ``tests/data/covariates_audit.csv``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.stats.covariates import (ancova_adjust, centre_covariates, check_estimable, join_audit,
                                       prepare_covariates, read_audit)
from appeal.errors import AppealInputError, StudyFileError
from r_reference_numbers import r_reference

R = r_reference("covariates_reference")
DATA = Path(__file__).parent / "data"
AUDIT = DATA / "covariates_audit.csv"
RANDOM = "(1 | participant_id) + (1 | stimulus)"
TOL = 1e-5


def rel(a, b, floor=1e-12):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), floor)))


@pytest.fixture(scope="module")
def trials() -> pd.DataFrame:
    return pd.read_csv(DATA / "covariates_ratings.csv")


def one_line(exc: pytest.ExceptionInfo) -> str:
    text = str(exc.value)
    assert "\n" not in text
    return text


# ---------------------------------------------------------------- the mixed model
def test_lmm_covariate_equals_lmertest(trials, tmp_path):
    from analysis.stats.lmm_report import lmm_section

    cov = prepare_covariates(trials, AUDIT, ["face_L_mean"])
    assert cov.dropped == 0 and abs(cov.data["face_L_mean"].mean()) < 1e-12
    sec = lmm_section(cov.data, "rating", "rating", ["shape"], ["participant_id", "stimulus"], tmp_path,
                      random=RANDOM, covariates=["face_L_mean"], covariate_means=cov.means)
    r = R["R_LMM"]
    assert sec.fit.formula.text == r["formula"]
    assert abs(sec.fit.deviance - r["reml_deviance"]) < 1e-6
    coefs = pd.read_csv(tmp_path / "lmm_coefficients.csv")
    assert list(coefs.term) == r["coef_names"]
    for ours, theirs in [("estimate", "beta"), ("se", "se"), ("df", "df"), ("t", "t"), ("p", "p")]:
        assert rel(coefs[ours], r[theirs]) < TOL, ours
    table = pd.read_csv(tmp_path / "lmm_anova.csv")
    assert list(table.effect) == r["anova_terms"]
    assert rel(table.F, r["F"]) < TOL and rel(table.den_df, r["den_df"]) < TOL
    assert list(table.num_df) == r["num_df"]
    text = " ".join(sec.text)
    assert "Covariates (stimulus audit measures" in text and "face_L_mean: b = 0.05128" in text
    assert sec.records["covariates"][0]["term"] == "face_L_mean"


def test_covariates_get_no_random_slopes(trials):
    from analysis.stats.random_structures import fallback_structures
    from analysis.stats.formula import parse_formula

    cov = prepare_covariates(trials, AUDIT, ["face_L_mean"]).data
    structures = fallback_structures(cov, parse_formula("rating ~ shape + face_L_mean"), ["participant_id"],
                                     fixed_only=["face_L_mean"])
    assert structures[0][1][0].terms == (("shape",),)


# ---------------------------------------------------------------- the ANCOVA-style adjustment
def test_ancova_slope_equals_lm_and_afex(trials):
    from analysis.stats.anova import fit_design
    from analysis.stats.design import prepare_design

    cov = prepare_covariates(trials, AUDIT, ["face_L_mean"])
    adjusted, adj = ancova_adjust(cov.data, "rating", ["shape"], "participant_id", ["face_L_mean"], means=cov.means)
    r = R["R_ANCOVA"]
    assert rel(adj.slopes["face_L_mean"], r["slope"]) < 1e-9
    # by hand: least squares on [cell indicators, participant indicators, x] (R: lm(y ~ cell + participant + x))
    d = cov.data
    X = np.hstack([pd.get_dummies(d["shape"]).to_numpy(float), pd.get_dummies(d.participant_id).to_numpy(float),
                   d[["face_L_mean"]].to_numpy()])
    b = np.linalg.lstsq(X, d.rating.to_numpy(), rcond=None)[0][-1]
    assert abs(b - adj.slopes["face_L_mean"]) < 1e-10
    np.testing.assert_allclose(adjusted.rating, d.rating - b * d.face_L_mean, rtol=1e-12)
    cells = adjusted.groupby(["participant_id", "shape"]).rating.mean()
    expected = pd.Series(r["cell_means"], index=pd.MultiIndex.from_arrays([r["cell_means_participant"],
                                                                          r["cell_means_shape"]]))
    assert rel(cells.loc[expected.index], expected) < 1e-12
    table = fit_design(prepare_design(adjusted, "rating", "participant_id", ["shape"], aggregate="mean")).table
    assert rel(table.F.iloc[0], r["F"]) < TOL and (table.num_df.iloc[0], table.den_df.iloc[0]) == (r["num_df"], r["den_df"])
    assert "b = 0.05128" in adj.text and "shape" in adj.text


# ---------------------------------------------------------------- joining and errors
def test_join_drops_rows_without_stimulus_and_normalises_paths(trials):
    audit = read_audit(AUDIT, ["face_L_mean", "face_rms_contrast"])
    extra = pd.DataFrame({"participant_id": ["p01", "p01"], "stimulus": [np.nan, ""], "shape": ["s1", "s1"],
                          "rating": [4.0, 5.0]})
    data = pd.concat([trials.assign(stimulus="./" + trials.stimulus), extra], ignore_index=True)
    joined, dropped = join_audit(data, audit, ["face_L_mean", "face_rms_contrast"], "stimulus", "ratings.tsv")
    assert dropped == 2 and len(joined) == len(trials)
    first = audit.set_index("file").loc["s1/c1.png", "face_L_mean"]
    assert joined.loc[joined.stimulus == "./s1/c1.png", "face_L_mean"].eq(first).all()
    centred, means = centre_covariates(joined, ["face_L_mean"])
    assert abs(means["face_L_mean"] - joined.face_L_mean.mean()) < 1e-12 and abs(centred.face_L_mean.mean()) < 1e-10


def test_unknown_measure_lists_available(tmp_path):
    with pytest.raises(AppealInputError) as exc:
        read_audit(AUDIT, ["face_L_mean", "luminance"])
    msg = one_line(exc)
    assert str(AUDIT) in msg and "luminance" in msg and "available measures: face_L_mean, face_rms_contrast" in msg
    bad = tmp_path / "audit.csv"
    bad.write_text("image,face_L_mean\na.png,3\n")
    with pytest.raises(AppealInputError, match=r"no 'file' column") as exc:
        read_audit(bad, ["face_L_mean"])
    assert str(bad) in one_line(exc)
    with pytest.raises(AppealInputError, match="file not found") as exc:
        read_audit(tmp_path / "missing.csv", ["face_L_mean"])
    one_line(exc)


def test_missing_stimulus_names_audit_count_and_first(trials):
    audit = read_audit(AUDIT, ["face_L_mean"])
    data = trials.assign(stimulus=trials.stimulus.replace({"s2/c3.png": "s2/c9.png", "s3/c1.png": "s3/c0.png"}))
    with pytest.raises(AppealInputError) as exc:
        join_audit(data, audit, ["face_L_mean"], "stimulus", "ratings.tsv")
    msg = one_line(exc)
    assert msg.startswith(str(AUDIT)) and "2 stimuli of ratings.tsv" in msg and "the first s2/c9.png" in msg
    with pytest.raises(AppealInputError, match="covariates.by: no column 'image'"):
        join_audit(data, audit, ["face_L_mean"], "image", "ratings.tsv")


def test_collinear_covariates_are_refused(trials, tmp_path):
    from analysis.stats.lmm_report import lmm_section

    cov = prepare_covariates(trials, AUDIT, ["face_L_mean"]).data
    # character as a fixed factor: each shape × character cell is one stimulus
    with pytest.raises(AppealInputError) as exc:
        lmm_section(cov, "rating", "rating", ["shape", "character"], ["participant_id", "stimulus"], tmp_path,
                    random=RANDOM, covariates=["face_L_mean"], source="ratings.tsv: mixed")
    msg = one_line(exc)
    assert ("face_L_mean is constant within every cell of shape × character, so it cannot be separated from those "
            "factors") in msg and "leave a factor such as character out" in msg
    # a measure that depends on the cell only
    per_shape = cov.assign(face_L_mean=cov["shape"].map({"s1": -1.0, "s2": 0.5, "s3": 0.5}))
    with pytest.raises(AppealInputError, match="constant within every cell of shape"):
        check_estimable(per_shape, ["face_L_mean"], [["shape"]])
    with pytest.raises(AppealInputError, match="constant within every cell of shape \\+ participant_id"):
        ancova_adjust(per_shape, "rating", ["shape"], "participant_id", ["face_L_mean"])
    # two measures, one a linear function of the other and the cells
    twin = cov.assign(face_rms_contrast=2 * cov.face_L_mean + cov["shape"].map({"s1": 0.0, "s2": 1.0, "s3": 3.0}))
    with pytest.raises(AppealInputError) as exc:
        check_estimable(twin, ["face_L_mean", "face_rms_contrast"], [["shape"]], source="ratings.tsv")
    assert "face_L_mean, face_rms_contrast are collinear within the cells of shape" in one_line(exc)
    check_estimable(cov, ["face_L_mean"], [["shape"]])  # varies within cells: fine


# ---------------------------------------------------------------- study files
def _ratings_file(trials: pd.DataFrame, tmp_path: Path, **extra) -> dict:
    trials.to_csv(tmp_path / "ratings.csv", index=False)
    (tmp_path / "audit").mkdir(exist_ok=True)
    (tmp_path / "audit" / "audit.csv").write_text(AUDIT.read_text())
    return {"kind": "ratings", "data": "ratings.csv", "within": ["shape"], "scales": ["rating"], "scale_range": None,
            "covariates": {"audit": "audit/audit.csv", "measures": ["face_L_mean"]}, **extra}


def test_schema_resolves_audit_and_checks_measures(trials, tmp_path):
    from analysis.ratings_schema import RatingsAnalysis
    from appeal.studyfile import validate_data

    doc = _ratings_file(trials, tmp_path)
    cfg = validate_data(doc, RatingsAnalysis, source="study.yaml", base_dir=tmp_path)
    assert cfg.covariates.audit == (tmp_path / "audit" / "audit.csv").resolve() and cfg.covariates.by == "stimulus"
    doc["covariates"]["measures"] = ["face_L_mean", "face_luminance"]
    with pytest.raises(StudyFileError) as exc:
        validate_data(doc, RatingsAnalysis, source="study.yaml", base_dir=tmp_path)
    assert "face_luminance not in" in str(exc.value) and "available measures: face_L_mean, face_rms_contrast" in str(exc.value)
    doc["covariates"] = {"audit": "nowhere.csv", "measures": ["face_L_mean"]}
    with pytest.raises(StudyFileError, match="file not found"):
        validate_data(doc, RatingsAnalysis, source="study.yaml", base_dir=tmp_path)
    doc["covariates"] = {"audit": "audit/audit.csv", "measures": ["shape"]}
    with pytest.raises(StudyFileError, match="is also a factor or the subject column"):
        validate_data(doc, RatingsAnalysis, source="study.yaml", base_dir=tmp_path)


def test_rating_study_with_covariate(trials, tmp_path):
    from analysis.ratings_schema import RatingsAnalysis
    from analysis.stats.study import analyze_rating_study
    from appeal.studyfile import validate_data

    doc = _ratings_file(trials, tmp_path, model="both", mixed={"random": RANDOM}, posthoc={"max_order": 0 + 1})
    cfg = validate_data(doc, RatingsAnalysis, source="study.yaml", base_dir=tmp_path)
    out = tmp_path / "out"
    (out / "rating").mkdir(parents=True)
    res = analyze_rating_study(cfg, out)
    anova = pd.read_csv(out / "rating" / "anova.csv")
    assert rel(anova.F.iloc[0], R["R_ANCOVA"]["F"]) < TOL
    coefs = pd.read_csv(out / "rating" / "lmm_coefficients.csv")
    assert rel(coefs.estimate, R["R_LMM"]["beta"]) < TOL and rel(coefs.df, R["R_LMM"]["df"]) < TOL
    info = res.summary["scales"]["rating"]
    assert rel(info["ancova"]["slopes"]["face_L_mean"], R["R_ANCOVA"]["slope"]) < 1e-9
    assert res.summary["covariates"]["measures"] == ["face_L_mean"]
    report = res.report_md.read_text()
    assert "ANCOVA-style adjustment for the audit measure(s) face_L_mean" in report
    assert "Covariates (stimulus audit measures, centred" in report


def test_erp_config_covariates_need_mixed_and_beh(tmp_path):
    from analysis.erp_schema import ErpConfig
    from appeal.studyfile import validate_data

    base = {"kind": "erp", "recordings": "sub-*.bdf", "montage": "none", "events": {1: {"shape": "s1"}, 2: {"shape": "s2"}},
            "covariates": {"audit": str(AUDIT), "measures": ["face_rms_contrast"]}}
    with pytest.raises(StudyFileError, match="set mixed: {enabled: true}"):
        validate_data(base, ErpConfig, base_dir=tmp_path)
    with pytest.raises(StudyFileError, match="need beh"):
        validate_data({**base, "mixed": {"enabled": True}}, ErpConfig, base_dir=tmp_path)
    cfg = validate_data({**base, "mixed": {"enabled": True}, "beh": "sub-*_beh.tsv"}, ErpConfig, base_dir=tmp_path)
    assert cfg.covariates.measures == ["face_rms_contrast"]


def test_erp_single_trial_model_with_covariate(trials, tmp_path):
    from analysis.erp.report import ErpOutputs, single_trial_models
    from analysis.erp_schema import ErpConfig
    from appeal.studyfile import validate_data

    cfg = validate_data({"kind": "erp", "recordings": "sub-*.bdf", "montage": "none",
                         "events": {1: {"shape": "s1"}, 2: {"shape": "s2"}, 3: {"shape": "s3"}},
                         "mixed": {"enabled": True, "random": "(1 | subject) + (1 | stimulus)"}, "beh": "sub-*_beh.tsv",
                         "covariates": {"audit": str(AUDIT), "measures": ["face_L_mean"]}}, ErpConfig, base_dir=tmp_path)
    single = trials.rename(columns={"participant_id": "subject", "rating": "mean_uV"}).assign(component="N170",
                                                                                              cluster="left")
    o = ErpOutputs(out=tmp_path, amplitudes=tmp_path / "a.csv", qc=tmp_path / "qc.csv", report=tmp_path / "report.md")
    text = single_trial_models(single, ["shape"], cfg, tmp_path, o)
    assert "Covariates (stimulus audit measures" in text and "Not fitted" not in text
    coefs = pd.read_csv(tmp_path / "N170_left" / "lmm_coefficients.csv")
    assert rel(coefs.estimate, R["R_LMM"]["beta"]) < TOL and rel(coefs.se, R["R_LMM"]["se"]) < TOL
