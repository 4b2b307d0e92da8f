"""Rating-study figures: the realism-vs-appeal diagram (thesis Fig. 6.16) has no overlapping
labels or legends, and shows every graph and node."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from analysis.stats.intervals import within_ci  # noqa: E402
from analysis.stats.plots import realism_vs_appeal_figure  # noqa: E402
from analysis.stats.simulate import ScaleModel, exp2_design, simulate_ratings  # noqa: E402
from figure_checks import overlaps  # noqa: E402


def _cis(factors, scales, n_subjects):
    df = simulate_ratings(factors, scales, n_subjects=n_subjects, seed=1)
    within = list(factors)
    return [within_ci(df, f"response_{s}", "participant_id", within, factors=["shape", "material"], aggregate="mean")
            for s in ("realism", "appeal")]


@pytest.mark.parametrize("n_subjects", [2, 20])
def test_exp2_diagram_has_no_overlaps(n_subjects):
    """The shipped Exp. 2 design: 5 shapes x 5 materials, nodes close together."""
    cx, cy = _cis(*exp2_design(), n_subjects)
    fig = realism_vs_appeal_figure(cx, cy, "shape", "material")
    try:
        assert overlaps(fig) == []
        ax = fig.axes[0]
        nodes = [ln for ln in ax.lines if len(ln.get_xdata()) == 1]
        assert len(nodes) == 25 and len({ln.get_marker() for ln in nodes}) == 5  # a marker per material
        legends = [a for a in ax.get_children() if isinstance(a, matplotlib.legend.Legend)]
        assert sorted(leg.get_title().get_text() for leg in legends) == ["material", "shape"]
    finally:
        plt.close(fig)


def test_many_levels_have_no_overlaps():
    """Eight graphs of eight nodes: the two legends beside the plot still do not meet."""
    levels = [f"l{i}" for i in range(8)]
    factors = {"shape": levels, "material": levels}
    scales = {"realism": ScaleModel(mean=lambda c: 1 + 0.4 * c["shape"] + 0.3 * c["material"]),
              "appeal": ScaleModel(mean=lambda c: 4 - 0.1 * (c["shape"] - c["material"]) ** 2)}
    cx, cy = _cis(factors, scales, 6)
    fig = realism_vs_appeal_figure(cx, cy, "shape", "material")
    try:
        assert overlaps(fig) == []
    finally:
        plt.close(fig)
