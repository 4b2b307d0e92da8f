"""Mimicry measures with the paper's information measures (Nagle et al. §5.1), and
``appeal stimuli morphpca mimicry`` on synthetic people with known expressions."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from appeal.errors import AppealInputError
from stimulus_engine.morphpca.mimicry import information_measures


def test_information_measures_agree_with_theory_and_scikit_learn():
    from sklearn.metrics import mutual_info_score

    rng = np.random.default_rng(0)
    n, r = 200_000, 0.8
    x = rng.normal(size=n)
    y = r * x + np.sqrt(1 - r * r) * rng.normal(size=n)
    t = information_measures(x[:, None], y[:, None], bins=60).iloc[0]
    # a bivariate normal's mutual information is -log2(1 - r^2) / 2 = 0.737 bits (histogram: 0.735)
    assert t["mutual_information"] == pytest.approx(-0.5 * np.log2(1 - r * r), rel=0.02)
    # the same histogram's MI from scikit-learn (nats) on the bin labels
    edges = np.linspace(min(x.min(), y.min()), max(x.max(), y.max()), 61)
    lx, ly = np.clip(np.digitize(x, edges) - 1, 0, 59), np.clip(np.digitize(y, edges) - 1, 0, 59)
    assert t["mutual_information"] == pytest.approx(mutual_info_score(lx, ly) / np.log(2), abs=1e-9)
    # a perfect mimicry carries all the information; an unrelated one none
    same = information_measures(x[:2000, None], x[:2000, None]).iloc[0]
    assert same["mutual_information"] == pytest.approx(same["entropy_source"]) and same["normalised_mi"] == pytest.approx(1)
    other = information_measures(x[:20000, None], rng.normal(size=(20000, 1)), bins=20).iloc[0]
    assert other["normalised_mi"] < 0.01  # (the histogram estimator's small positive bias)
    with pytest.raises(AppealInputError, match="at least 2 frames"):
        information_measures(x[:1, None], y[:1, None])
    with pytest.raises(AppealInputError, match="differ in shape"):
        information_measures(np.zeros((5, 2)), np.zeros((5, 3)))


@pytest.mark.slow
def test_mimicry_cli_tells_a_good_mimic_from_a_bad_one(tmp_path, capsys):
    from appeal_cli import main
    from stimulus_engine.morphpca import random_identity, render_synthetic_face, synthetic_set
    from stimulus_engine.morphpca.io import save_image

    people = {"a": random_identity(11), "b": random_identity(12)}
    for d in ("a", "b", "src", "good", "bad"):
        (tmp_path / d).mkdir()
    for name, who in people.items():  # a model of each person from 24 frames, with their keypoints
        imgs, _, kps = synthetic_set(who, 24, {"a": 0, "b": 1}[name])
        rows = []
        for i, (img, kp) in enumerate(zip(imgs, kps)):
            save_image(tmp_path / name / f"f{i:02d}.png", img)
            rows.append({"image": f"f{i:02d}.png", **dict(zip(["left_eye_x", "left_eye_y", "right_eye_x", "right_eye_y",
                                                                "philtrum_x", "philtrum_y"], kp.ravel()))})
        pd.DataFrame(rows).to_csv(tmp_path / f"{name}.csv", index=False)
        assert main(["stimuli", "morphpca", "build", str(tmp_path / name), "--keypoints", str(tmp_path / f"{name}.csv"),
                     "--out", str(tmp_path / f"model_{name}")]) == 0
    t = np.linspace(0, 1, 12)
    clip = np.zeros((12, 6))
    clip[:, 0] = np.sin(np.pi * t)  # a smile that comes and goes
    clip[:, 1] = np.clip(2 * t - 1, 0, 1)  # the jaw opening in the second half
    bad = clip[::-1].copy()  # the same moves, in the wrong order
    for name, who, weights in (("src", people["a"], clip), ("good", people["b"], clip), ("bad", people["b"], bad)):
        for i, w in enumerate(weights):
            save_image(tmp_path / name / f"t{i:02d}.png", render_synthetic_face(who, w)[0])
    results = {}
    for mimic in ("good", "bad"):
        out = tmp_path / f"m_{mimic}"
        assert main(["stimuli", "morphpca", "mimicry", str(tmp_path / "model_a" / "model.npz"),
                     str(tmp_path / "model_b" / "model.npz"), "--source", str(tmp_path / "src"), "--mimic",
                     str(tmp_path / mimic), "--bins", "4", "--out", str(out)]) == 0, capsys.readouterr().err
        results[mimic] = json.loads((out / "mimicry.json").read_text())
        comps = pd.read_csv(out / "components.csv")
        results[mimic]["first3"] = comps["correlation"].iloc[:3].mean()
        assert {"correlation", "entropy_source", "entropy_mimic", "mutual_information", "normalised_mi"} <= set(comps)
        assert len(pd.read_csv(out / "frames.csv")) == 12
        assert (out / "loadings.png").is_file() and (out / "sheet.png").is_file()
    good, bad = results["good"], results["bad"]
    # measured: distance 1306 vs 1713, frame correlation 0.58 vs 0.22, first three components'
    # correlation over time 0.66 vs -0.31, normalised MI 0.39 vs 0.22
    assert good["mean_euclidean"] < 0.85 * bad["mean_euclidean"]
    assert good["mean_frame_correlation"] > bad["mean_frame_correlation"] + 0.2
    assert good["first3"] > 0.4 and bad["first3"] < 0.0
    assert good["mean_normalised_mi"] > bad["mean_normalised_mi"] + 0.1
    capsys.readouterr()
    rc = main(["stimuli", "morphpca", "mimicry", str(tmp_path / "model_a" / "model.npz"),
               str(tmp_path / "model_b" / "model.npz"), "--source", str(tmp_path / "src"), "--mimic",
               str(tmp_path / "good" / "t00.png"), "--out", str(tmp_path / "m_x")])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1 and "one mimic frame per source frame (12), got 1" in err[0]
    assert not (tmp_path / "m_x").exists()  # nothing written
