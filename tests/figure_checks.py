"""Layout checks for report figures: no label, tick, title or legend overlaps another, or sits
on the data — with the text extents matplotlib itself computes when drawing. Used by the ERP
and the rating-study figure tests."""

from __future__ import annotations

import itertools

import numpy as np
from matplotlib.legend import Legend
from matplotlib.transforms import Bbox


def _visible_ticks(axis, lim) -> list:
    lo, hi = sorted(lim)
    return [lab for t in axis.get_major_ticks() if t.get_visible() and lo - 1e-9 <= t.get_loc() <= hi + 1e-9
            for lab in (t.label1, t.label2) if lab.get_visible() and lab.get_text()]


def _legends(ax) -> list:
    """The axes' legends: the current one and any added with ``ax.add_artist``."""
    return [a for a in ax.get_children() if isinstance(a, Legend) and a.get_visible()]


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
        out += [(f"axes {i} legend {k}", i, leg) for k, leg in enumerate(_legends(ax))]
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
        over += [(f"axes {i} legend {k}", leg.get_window_extent(r)) for k, leg in enumerate(_legends(ax))]
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
