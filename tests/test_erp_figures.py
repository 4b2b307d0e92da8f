"""ERP report figures: no label, tick, title or legend overlaps another, or sits on the data.

The figures are built from data shaped like the thesis design (6 stylisation levels x 3
emotions, BioSemi 128, N170 / EPN / LPP windows, a 7 mm source grid) and checked with the
text extents matplotlib itself computes when drawing.
"""

from __future__ import annotations

import itertools

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from analysis.erp import figures as figs  # noqa: E402
from figure_checks import overlaps  # noqa: E402

LEVELS = {"stylisation": [0, 1, 2, 3, 4, 5], "emotion": ["angry", "neutral", "happy"]}
FACTORS = ["stylisation", "emotion"]
WINDOWS = {"N170": (0.150, 0.190), "EPN": (0.250, 0.400), "LPP": (0.400, 0.600)}


@pytest.fixture(scope="module")
def grand():
    rng = np.random.default_rng(0)
    times = np.arange(-0.1, 0.6, 1 / 128)
    n170 = -6e-6 * np.exp(-((times - 0.17) / 0.02) ** 2)
    lpp = 8e-6 * np.exp(-((times - 0.5) / 0.08) ** 2)
    out = {}
    for s, e in itertools.product(*LEVELS.values()):
        noise = np.cumsum(rng.normal(0, 3e-7, (128, len(times))), axis=1)
        out[(s, e)] = noise + n170 * (1 + 0.1 * abs(s - 2.5)) + lpp * (1 + 0.2 * s)
    return out, times


def test_waveforms_have_no_overlaps(grand):
    from analysis.erp.channels import make_montage

    data, times = grand
    fig = figs.waveforms_figure(data, times, make_montage("biosemi128").ch_names, {"PO8": "B5", "CPPz": "A3"},
                                FACTORS, LEVELS, WINDOWS)
    assert overlaps(fig) == []


def test_topomaps_have_no_overlaps(grand):
    import mne

    from analysis.erp.channels import make_montage

    data, times = grand
    mont = make_montage("biosemi128")
    info = mne.create_info(mont.ch_names, 128.0, "eeg")
    info.set_montage(mont)
    fig = figs.difference_topomaps_figure(data, info, FACTORS, LEVELS, "emotion", "neutral",
                                          {k: v for k, v in WINDOWS.items() if k != "LPP"}, times)
    assert overlaps(fig) == []


@pytest.mark.parametrize("n_subjects", [1, 12])
def test_bars_have_no_overlaps(n_subjects):
    rng = np.random.default_rng(1)
    rows = [{"subject": k, "stylisation": s, "emotion": e, "component": "N170", "cluster": c,
             "mean_uV": -5 - 0.4 * abs(s - 2.5) + rng.normal(0, 1)}
            for k in range(n_subjects) for s, e in itertools.product(*LEVELS.values()) for c in ("left", "right")]
    fig = figs.window_bars_figure(pd.DataFrame(rows), "N170", FACTORS, LEVELS)
    assert overlaps(fig) == []


def test_source_map_has_no_overlaps():
    g = np.arange(-70, 71, 7.0)
    xyz = np.array(list(itertools.product(g, g - 20, g + 10)))
    mni = xyz[np.linalg.norm((xyz - [0, -20, 10]) / [70, 95, 75], axis=1) <= 1]
    t = 30 * np.exp(-np.linalg.norm(mni - [0, -60, 45], axis=1) ** 2 / 800)
    fig = figs.source_map_figure(mni, t, 5.84, "LPP: 5 > 0 (sLORETA, p < 0.005 uncorrected)")
    assert overlaps(fig) == []


@pytest.mark.parametrize("n_subjects", [3, 30])
def test_sme_has_no_overlaps(n_subjects):
    rng = np.random.default_rng(2)
    rows = [{"subject": f"{k + 1:02d}", "stylisation": s, "emotion": e, "component": comp, "cluster": c,
             "sme_uV": abs(rng.normal(0.8, 0.3))}
            for k in range(n_subjects) for s, e in itertools.product(*LEVELS.values())
            for comp, c in (("N170", "left"), ("N170", "right"), ("LPP", "parietal"))]
    sme = pd.DataFrame(rows)
    sme["flagged"] = sme["sme_uV"] > 1.2
    fig = figs.sme_figure(sme, 1.2)
    assert overlaps(fig) == []
