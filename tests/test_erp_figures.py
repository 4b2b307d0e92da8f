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
from matplotlib.transforms import Bbox  # noqa: E402

from analysis.erp import figures as figs  # noqa: E402

LEVELS = {"stylisation": [0, 1, 2, 3, 4, 5], "emotion": ["angry", "neutral", "happy"]}
FACTORS = ["stylisation", "emotion"]
WINDOWS = {"N170": (0.150, 0.190), "EPN": (0.250, 0.400), "LPP": (0.400, 0.600)}


def _visible_ticks(axis, lim) -> list:
    lo, hi = sorted(lim)
    return [lab for t in axis.get_major_ticks() if t.get_visible() and lo - 1e-9 <= t.get_loc() <= hi + 1e-9
            for lab in (t.label1, t.label2) if lab.get_visible() and lab.get_text()]


def _labels(fig) -> list[tuple[str, int | None, object]]:
    """Every piece of text drawn: (name, index of its axes or None, artist)."""
    out = [("suptitle", None, fig._suptitle)] if fig._suptitle is not None else []
    for i, ax in enumerate(fig.axes):
        for name, t in [("title", ax.title), ("xlabel", ax.xaxis.label), ("ylabel", ax.yaxis.label)]:
            if t.get_visible() and t.get_text():
                out.append((f"axes {i} {name} {t.get_text()!r}", i, t))
        out += [(f"axes {i} x tick {t.get_text()!r}", i, t) for t in _visible_ticks(ax.xaxis, ax.get_xlim())]
        out += [(f"axes {i} y tick {t.get_text()!r}", i, t) for t in _visible_ticks(ax.yaxis, ax.get_ylim())]
        out += [(f"axes {i} text {t.get_text()!r}", i, t) for t in ax.texts if t.get_visible() and t.get_text()]
        if ax.get_legend() is not None:
            out.append((f"axes {i} legend", i, ax.get_legend()))
    return out


def _meet(a, b) -> bool:
    inter = Bbox.intersection(a, b)
    return inter is not None and inter.width > 1 and inter.height > 1


def overlaps(fig) -> list[str]:
    """Labels whose boxes intersect each other or another plot's area, and texts or legends
    drawn over plotted lines or bars."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    boxes = [(name, i, a.get_window_extent(r)) for name, i, a in _labels(fig)]
    found = [f"{n1} / {n2}" for (n1, _, b1), (n2, _, b2) in itertools.combinations(boxes, 2) if _meet(b1, b2)]
    for name, i, b in boxes:
        found += [f"{name} / plot area of axes {j}" for j, ax in enumerate(fig.axes)
                  if j != i and _meet(b, ax.get_window_extent(r))]
    for i, ax in enumerate(fig.axes):
        over = [(f"axes {i} text {t.get_text()!r}", t.get_window_extent(r)) for t in ax.texts if t.get_text()]
        if ax.get_legend() is not None:
            over.append((f"axes {i} legend", ax.get_legend().get_window_extent(r)))
        for line in ax.lines:
            xy = ax.transData.transform(np.asarray(line.get_xydata(), float))
            if len(xy) < 3:
                continue  # axhline / axvline: reference lines, not data
            for name, b in over:
                if np.any((xy[:, 0] > b.x0) & (xy[:, 0] < b.x1) & (xy[:, 1] > b.y0) & (xy[:, 1] < b.y1)):
                    found.append(f"{name} over line {line.get_label()!r}")
        bars = [c for c in ax.containers if hasattr(c, "patches")]
        for name, b in over:
            if any(_meet(bar.get_window_extent(r), b) for c in bars for bar in c.patches):
                found.append(f"{name} over a bar")
    return found


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
