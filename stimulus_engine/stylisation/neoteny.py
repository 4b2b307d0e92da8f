"""Neoteny measures of face stimuli from 3D landmarks (thesis §7.3, Fig. 7.10).

Per stimulus geometry, with face width ``W`` = distance between the left and right face-contour
landmarks and face length ``L`` = forehead top to chin (vertical distance):

=====================  ===========================================================
eye_width              mean over both eyes of |outer − inner corner| / W
eye_height             mean over both eyes of |top − bottom lid| / L
nose_length            |nasion − subnasale| / L
nose_width             |nose left − nose right| / W
mouth_width            |mouth left − mouth right| / W
forehead_height        (forehead top − brow centre) height / L
eye_position           (eye centre − chin) height / L  (lower = more neotenic)
eye_area               mean eye width × mean eye height / (W × L)  (a share of the face's area)
eye_roundness          mean eye height / mean eye width  (an adult's almond ~0.3, a cartoon's round ≥ 0.5)
=====================  ===========================================================
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["MEASURES", "neoteny_measures", "neoteny_table", "plot_neoteny"]

#: The measures, in table order.
MEASURES: tuple[str, ...] = ("eye_width", "eye_height", "nose_length", "nose_width", "mouth_width",
                             "forehead_height", "eye_position", "eye_area", "eye_roundness")


def neoteny_measures(lm: dict[str, np.ndarray]) -> dict[str, float]:
    """The neoteny measures of one face from its landmark points (names of :data:`stimulus_engine.characters.rig.LANDMARK_NAMES`).

    Examples
    --------
    >>> import numpy as np
    >>> p = lambda x, y: np.array([x, y, 0.0])
    >>> lm = dict(face_left=p(5, 0), face_right=p(-5, 0), forehead_top=p(0, 8), chin=p(0, -12),
    ...           eye_left_outer=p(4, 2), eye_left_inner=p(1, 2), eye_right_outer=p(-4, 2),
    ...           eye_right_inner=p(-1, 2), eye_left_top=p(2.5, 2.5), eye_left_bottom=p(2.5, 1.5),
    ...           eye_right_top=p(-2.5, 2.5), eye_right_bottom=p(-2.5, 1.5), eye_left=p(2.5, 2),
    ...           eye_right=p(-2.5, 2), nasion=p(0, 2), subnasale=p(0, -3), nose_left=p(1, -3),
    ...           nose_right=p(-1, -3), mouth_left=p(2, -6), mouth_right=p(-2, -6),
    ...           brow_left=p(2.5, 4), brow_right=p(-2.5, 4))
    >>> m = neoteny_measures(lm)
    >>> round(m["eye_width"], 3), round(m["eye_position"], 3), round(m["forehead_height"], 3)
    (0.3, 0.7, 0.2)
    """
    W = float(np.linalg.norm(lm["face_left"] - lm["face_right"]))
    L = float(lm["forehead_top"][1] - lm["chin"][1])
    if W <= 0 or L <= 0:
        raise ValueError("degenerate face: width and length must be positive")
    d = lambda a, b: float(np.linalg.norm(lm[a] - lm[b]))  # noqa: E731
    eye_w = (d("eye_left_outer", "eye_left_inner") + d("eye_right_outer", "eye_right_inner")) / 2
    eye_h = (d("eye_left_top", "eye_left_bottom") + d("eye_right_top", "eye_right_bottom")) / 2
    brow_y = float((lm["brow_left"][1] + lm["brow_right"][1]) / 2)
    eye_y = float((lm["eye_left"][1] + lm["eye_right"][1]) / 2)
    return {
        "eye_width": eye_w / W, "eye_height": eye_h / L, "nose_length": d("nasion", "subnasale") / L,
        "nose_width": d("nose_left", "nose_right") / W, "mouth_width": d("mouth_left", "mouth_right") / W,
        "forehead_height": (float(lm["forehead_top"][1]) - brow_y) / L,
        "eye_position": (eye_y - float(lm["chin"][1])) / L,
        "eye_area": eye_w * eye_h / (W * L), "eye_roundness": eye_h / eye_w,
    }


def neoteny_table(landmarks: pd.DataFrame) -> pd.DataFrame:
    """Measures per geometry from a grid's long ``landmarks.csv`` table (tidy: one row per measure)."""
    need = {"character", "shape", "stylisation", "expression", "landmark", "x", "y", "z"}
    missing = need - set(landmarks.columns)
    if missing:
        raise ValueError(f"landmarks table lacks column(s) {', '.join(sorted(missing))}")
    rows = []
    for key, g in landmarks.groupby(["character", "shape", "stylisation", "expression"], sort=False):
        lm = {r.landmark: np.array([r.x, r.y, r.z], float) for r in g.itertuples()}
        for name, value in neoteny_measures(lm).items():
            rows.append(dict(zip(["character", "shape", "stylisation", "expression"], key), measure=name, value=value))
    return pd.DataFrame(rows)


def plot_neoteny(table: pd.DataFrame, path: str | Path) -> list[Path]:
    """Measures against stylisation level, one panel per measure, a line per character (PNG + SVG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    neutral = table[table["expression"] == "neutral"] if (table["expression"] == "neutral").any() else table
    fig, axes = plt.subplots(2, 5, figsize=(16, 6), constrained_layout=True)
    for ax, m in zip(axes.ravel(), MEASURES):
        sub = neutral[neutral["measure"] == m]
        for ch, g in sub.groupby("character", sort=False):
            g = g.groupby("shape", as_index=False)["value"].mean().sort_values("shape")
            ax.plot(g["shape"].astype(float), g["value"], marker="o", label=str(ch))
        ax.set_title(m.replace("_", " "))
        ax.set_xlabel("shape level (0 realistic, 1 cartoon)")
    axes.ravel()[-1].axis("off")
    axes.ravel()[0].legend(fontsize=8)
    fig.suptitle("Neoteny measures across stylisation (relative to face width / length)")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    out = [path.with_suffix(".png"), path.with_suffix(".svg")]
    fig.savefig(out[0], dpi=110)
    fig.savefig(out[1])
    plt.close(fig)
    return out
