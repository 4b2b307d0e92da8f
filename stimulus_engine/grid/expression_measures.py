"""How far each expression moves the face, per stylisation level, in units of the face's own size.

A grid carries each expression from its character's rig onto every stylised shape
(:func:`stimulus_engine.grid.prepare.posed_vertices`); a transfer that does not keep an
expression's intensity gives a cartoon surprise a smaller mouth opening than the realistic one.
:func:`expression_measures` measures every expression against the same character's neutral at
the same shape level from the grid's ``landmarks.csv``; :func:`level_agreement` says how far the
levels agree; :func:`plot_expression_measures` draws it and :func:`write_expression_measures`
writes ``expression_measures.csv``, ``expression_agreement.csv`` and ``expression_measures.png``
beside the contact sheets.

**Units.** Every value is a fraction of the face length ``L`` = |forehead_top - chin| of that
level's neutral face: the grid's camera frames every face by exactly that length
(:func:`stimulus_engine.render.face_camera` with ``render.face_fraction``), so a face unit is the
same share of the image height at every level, and values of different levels compare as they
appear on screen.

**The face's own axes** (of the level's neutral): ``across`` = the eye line, from the right
eye centre to the left one (eyeball centres, which no expression moves); ``up`` = the component
of chin -> forehead_top perpendicular to it, i.e. perpendicular to the eye line within the
frontal plane (the plane of the eye line and the face's length, which the camera sees face on).
A point ``p`` of a geometry has the face coordinates
``f(p) = ((p - c) . across, (p - c) . up) / L``, ``c`` the midpoint of that geometry's own eye
centres, so every position is relative to the eye centres and nothing depends on where the head
sits, how it is turned or how large it is.

**Measures** (neutral ``N``, expression ``E`` at one shape level; ``|.|`` a length in the
frontal plane, face coordinates; ``.u`` the up coordinate):

=====================  =====================================================================
mouth_opening          |f_E(mouth_top) - f_E(mouth_bottom)| - |f_N(mouth_top) - f_N(mouth_bottom)|
mouth_width            |f_E(mouth_left) - f_E(mouth_right)| - |f_N(mouth_left) - f_N(mouth_right)|
mouth_corner_raise     mean over mouth_left, mouth_right of f_E(p).u - f_N(p).u  (up positive)
brow_raise             mean over brow_left, brow_right of f_E(p).u - f_N(p).u  (the brows'
                       height above the eye centres; up positive)
eye_opening            mean over both eyes of the change of |f(eye_X_top) - f(eye_X_bottom)|
total                  RMS over every landmark but the eyeballs' (eye_left/right, pupil_left/right)
                       of the 3-D displacement |(p_E - c_E) - (p_N - c_N)| / L: how far the
                       expression moves the face overall, depth included
=====================  =====================================================================

**Agreement across levels** (:func:`level_agreement`), per character x expression x measure,
against the realistic level (the character's smallest shape value, 0 in a grid from realistic
to cartoon): ``ratio`` = largest / smallest magnitude over the levels, and
``largest_relative_difference`` = max over levels of |v - v_realistic| / |v_realistic| (a sign
that flips counts as a difference of at least 1). A ratio or a relative difference is only
meaningful where the realistic level moves that feature: a measure is ``judged`` when its
realistic magnitude is at least :data:`JUDGED_FRACTION` of the largest realistic magnitude among
that expression's measures (``total`` included); the others (a happy face's brows, an angry
face's mouth width ...) are reported with ``judged: False`` and left out of the expression's
summary and the figure.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from appeal.errors import AppealInputError

if TYPE_CHECKING:
    from stimulus_engine.grid.schema import GridFile

__all__ = ["EYEBALL_LANDMARKS", "JUDGED_FRACTION", "MEASURES", "expression_measures", "expression_spread", "face_measures",
           "level_agreement", "plot_expression_measures", "write_expression_measures"]

logger = logging.getLogger(__name__)

#: The measures, in table order (see the module docstring).
MEASURES: tuple[str, ...] = ("mouth_opening", "mouth_width", "mouth_corner_raise", "brow_raise", "eye_opening",
                             "total")
#: A measure is judged across levels when its realistic magnitude is at least this fraction of the
#: largest realistic magnitude among the same expression's measures.
JUDGED_FRACTION: float = 0.25
#: Landmarks on the eyeballs (centres and pupil rings): no expression moves them.
EYEBALL_LANDMARKS: tuple[str, ...] = ("eye_right", "eye_left", "pupil_right", "pupil_left")

NEUTRAL = "neutral"
_COLUMNS = ("character", "shape", "stylisation", "expression", "landmark", "x", "y", "z")
#: Frontal-plane distances: measure -> pairs of landmarks whose distance changes (mean of the pairs).
_DISTANCES: dict[str, tuple[tuple[str, str], ...]] = {
    "mouth_opening": (("mouth_top", "mouth_bottom"),),
    "mouth_width": (("mouth_left", "mouth_right"),),
    "eye_opening": (("eye_left_top", "eye_left_bottom"), ("eye_right_top", "eye_right_bottom")),
}
#: Vertical moves: measure -> landmarks whose up coordinate changes (mean of them).
_RAISES: dict[str, tuple[str, ...]] = {
    "mouth_corner_raise": ("mouth_left", "mouth_right"),
    "brow_raise": ("brow_left", "brow_right"),
}
_NEEDED = ("forehead_top", "chin", "eye_left", "eye_right",
           *dict.fromkeys(n for pairs in _DISTANCES.values() for pair in pairs for n in pair),
           *dict.fromkeys(n for names in _RAISES.values() for n in names))


def _checked(landmarks: pd.DataFrame) -> pd.DataFrame:
    """The landmark table with its columns and landmark names checked (AppealInputError otherwise)."""
    missing = [c for c in _COLUMNS if c not in landmarks.columns]
    if missing:
        raise AppealInputError(f"landmarks table lacks column(s) {', '.join(missing)} "
                               f"(expected {', '.join(_COLUMNS)}, as a grid's landmarks.csv)")
    absent = [n for n in _NEEDED if n not in set(landmarks["landmark"])]
    if absent:
        raise AppealInputError(f"landmarks table lacks landmark(s) {', '.join(absent)} "
                               "(expected the rig's landmarks, stimulus_engine.characters.rig.LANDMARK_NAMES)")
    if landmarks[["x", "y", "z"]].isna().to_numpy().any():
        raise AppealInputError("landmarks table has empty coordinates (expected x, y, z of every landmark)")
    dup = landmarks.duplicated(["character", "shape", "expression", "landmark"])
    if dup.any():
        r = landmarks[dup].iloc[0]
        raise AppealInputError(f"landmarks table lists '{r['landmark']}' twice for {r['character']} at shape "
                               f"{r['shape']}, {r['expression']} (expected one row per geometry and landmark)")
    return landmarks


def _points(g: pd.DataFrame) -> dict[str, np.ndarray]:
    """Landmark name -> (3,) point of one geometry's rows."""
    xyz = g[["x", "y", "z"]].to_numpy(np.float64)
    return dict(zip(g["landmark"], xyz))


def _frame(neutral: dict[str, np.ndarray], where: str) -> tuple[np.ndarray, float]:
    """(2, 3) rows ``across``, ``up`` and the face length of a level's neutral (module docstring)."""
    length = float(np.linalg.norm(neutral["forehead_top"] - neutral["chin"]))
    across = neutral["eye_left"] - neutral["eye_right"]
    width = float(np.linalg.norm(across))
    if length <= 0 or width <= 0:
        raise AppealInputError(f"landmarks of {where}: degenerate neutral face (forehead_top on chin, or both eye "
                               "centres at one point)")
    across = across / width
    up = neutral["forehead_top"] - neutral["chin"]
    up = up - across * (up @ across)
    if np.linalg.norm(up) <= 1e-9 * length:
        raise AppealInputError(f"landmarks of {where}: the face's length runs along its eye line (expected the "
                               "forehead above the chin)")
    return np.stack([across, up / np.linalg.norm(up)]), length


def _face_coords(points: dict[str, np.ndarray], axes: np.ndarray, length: float) -> dict[str, np.ndarray]:
    """Each landmark's (across, up) in face lengths, from the geometry's own eye-centre midpoint."""
    centre = (points["eye_left"] + points["eye_right"]) / 2
    return {k: axes @ (p - centre) / length for k, p in points.items()}


def face_measures(neutral: dict[str, np.ndarray], posed: dict[str, np.ndarray], where: str) -> dict[str, float]:
    """The measures of one posed geometry (``posed``: landmark name -> point) against its level's
    ``neutral`` (:data:`MEASURES`, module docstring); ``where`` names the level in errors."""
    axes, length = _frame(neutral, where)
    fn, fe = _face_coords(neutral, axes, length), _face_coords(posed, axes, length)
    out: dict[str, float] = {}
    for name, pairs in _DISTANCES.items():
        out[name] = float(np.mean([np.linalg.norm(fe[a] - fe[b]) - np.linalg.norm(fn[a] - fn[b]) for a, b in pairs]))
    for name, names in _RAISES.items():
        out[name] = float(np.mean([fe[n][1] - fn[n][1] for n in names]))
    cn = (neutral["eye_left"] + neutral["eye_right"]) / 2
    ce = (posed["eye_left"] + posed["eye_right"]) / 2
    skin = [k for k in neutral if k not in EYEBALL_LANDMARKS]
    moves = np.array([(posed[k] - ce) - (neutral[k] - cn) for k in skin])
    out["total"] = float(np.sqrt(np.mean(np.sum(moves ** 2, axis=1)))) / length
    return {m: out[m] for m in MEASURES}


def expression_measures(landmarks: pd.DataFrame) -> pd.DataFrame:
    """How far each expression moves the face at each shape level, in face lengths (module docstring).

    Parameters
    ----------
    landmarks : DataFrame
        A grid's long landmark table (``landmarks.csv``: character, shape, stylisation,
        expression, landmark, x, y, z), with a ``neutral`` geometry at every (character, shape)
        that has another expression.

    Returns
    -------
    DataFrame
        Tidy: character, shape, stylisation, expression, measure (:data:`MEASURES`), value; one
        row per character x shape x expression (neutral left out) x measure, characters and
        expressions in table order, shapes increasing.

    Raises
    ------
    AppealInputError
        A column or landmark missing, a landmark listed twice, a level without its neutral, a
        degenerate neutral face.

    Examples
    --------
    >>> pts = {"forehead_top": (0, 10), "chin": (0, -10), "eye_left": (3, 2), "eye_right": (-3, 2),
    ...        "mouth_top": (0, -5), "mouth_bottom": (0, -6), "mouth_left": (2, -5.5), "mouth_right": (-2, -5.5),
    ...        "brow_left": (3, 4), "brow_right": (-3, 4), "eye_left_top": (3, 2.5), "eye_left_bottom": (3, 1.5),
    ...        "eye_right_top": (-3, 2.5), "eye_right_bottom": (-3, 1.5)}
    >>> rows = lambda e, move: [dict(character="a", shape=0.0, stylisation=0, expression=e, landmark=k, x=x,
    ...                             y=y - (move if k == "mouth_bottom" else 0), z=0.0) for k, (x, y) in pts.items()]
    >>> t = expression_measures(pd.DataFrame(rows("neutral", 0) + rows("surprise", 2)))  # the jaw drops 2 of 20
    >>> t.set_index("measure")["value"].round(4).to_dict()["mouth_opening"]
    0.1
    """
    lm = _checked(landmarks)
    rows = []
    for (ch, shape), level in lm.groupby(["character", "shape"], sort=False):
        geoms = dict(tuple(level.groupby("expression", sort=False)))
        if set(geoms) == {NEUTRAL}:
            continue
        if NEUTRAL not in geoms:
            raise AppealInputError(f"landmarks of {ch} at shape {shape}: no neutral geometry to measure the "
                                   f"expressions against (expected a '{NEUTRAL}' row per landmark)")
        neutral = _points(geoms[NEUTRAL])
        for expr, g in geoms.items():
            if expr == NEUTRAL:
                continue
            posed = _points(g)
            if set(posed) != set(neutral):
                raise AppealInputError(f"landmarks of {ch} at shape {shape}: '{expr}' lists other landmarks than "
                                       "its neutral (expected the same set)")
            values = face_measures(neutral, posed, f"{ch} at shape {shape}")
            stylisation = g["stylisation"].iloc[0]
            rows += [{"character": ch, "shape": shape, "stylisation": stylisation, "expression": expr,
                      "measure": m, "value": v} for m, v in values.items()]
    table = pd.DataFrame(rows, columns=["character", "shape", "stylisation", "expression", "measure", "value"])
    return _ordered(table, lm)


def _ordered(table: pd.DataFrame, like: pd.DataFrame) -> pd.DataFrame:
    """``table`` sorted by character and expression as first met in ``like``, then shape, then measure."""
    order = {c: {v: i for i, v in enumerate(dict.fromkeys(like[c]))} for c in ("character", "expression")}
    key = pd.DataFrame({"c": table["character"].map(order["character"]),
                        "e": table["expression"].map(order["expression"]),
                        "s": table["shape"].astype(float),
                        "m": table["measure"].map({m: i for i, m in enumerate(MEASURES)})})
    return table.loc[key.sort_values(["c", "e", "s", "m"], kind="stable").index].reset_index(drop=True)


def _agreement_row(g: pd.DataFrame) -> dict:
    """Spread of one character x expression x measure across levels (rows sorted by shape)."""
    v = g["value"].to_numpy(np.float64)
    real = v[0]
    mags = np.abs(v)
    rel = np.abs(v - real) / abs(real) if real != 0 else np.full(len(v), np.nan)
    worst = int(np.nanargmax(rel)) if np.isfinite(rel).any() else 0
    return {"realistic": real, "smallest": float(v.min()), "largest": float(v.max()),
            "ratio": float(mags.max() / mags.min()) if mags.min() > 0 else np.inf,
            "largest_relative_difference": float(rel[worst]), "at_shape": g["shape"].iloc[worst]}


def level_agreement(table: pd.DataFrame, fraction: float = JUDGED_FRACTION) -> pd.DataFrame:
    """How far the shape levels agree on each expression's measures (module docstring).

    Parameters
    ----------
    table : DataFrame
        :func:`expression_measures`'s table.
    fraction : float
        A measure is judged when its realistic magnitude is at least this fraction of the largest
        realistic magnitude among the expression's measures (:data:`JUDGED_FRACTION`).

    Returns
    -------
    DataFrame
        One row per character x expression x measure: character, expression, measure, levels
        (how many), realistic (the value at the smallest shape), smallest, largest (signed, over
        the levels), ratio (largest / smallest magnitude; inf where a level does not move it),
        largest_relative_difference (max |v - realistic| / |realistic|; NaN where the realistic
        level does not move it), at_shape (the level of that difference), share (|realistic| /
        the expression's largest), judged.

    Examples
    --------
    >>> t = pd.DataFrame({"character": "a", "shape": [0.0, 1.0, 0.0, 1.0], "stylisation": [1, 0, 1, 0],
    ...                   "expression": "surprise", "measure": ["mouth_opening"] * 2 + ["brow_raise"] * 2,
    ...                   "value": [0.1, 0.05, 0.01, 0.03]})
    >>> level_agreement(t)[["measure", "ratio", "largest_relative_difference", "judged"]]
             measure  ratio  largest_relative_difference  judged
    0  mouth_opening    2.0                          0.5    True
    1     brow_raise    3.0                          2.0   False
    """
    need = {"character", "shape", "expression", "measure", "value"}
    if not need <= set(table.columns):
        missing = ", ".join(sorted(need - set(table.columns)))
        raise AppealInputError(f"expression measures table lacks column(s) {missing}")
    if not 0.0 <= fraction <= 1.0:
        raise AppealInputError(f"judged fraction must be within 0..1 (got {fraction})")
    rows = []
    for (ch, expr, measure), g in table.groupby(["character", "expression", "measure"], sort=False):
        g = g.assign(_s=g["shape"].astype(float)).sort_values("_s", kind="stable")
        rows.append({"character": ch, "expression": expr, "measure": measure, "levels": len(g), **_agreement_row(g)})
    cols = ["character", "expression", "measure", "levels", "realistic", "smallest", "largest", "ratio",
            "largest_relative_difference", "at_shape", "share", "judged"]
    out = pd.DataFrame(rows, columns=[c for c in cols if c not in ("share", "judged")])
    top = out.groupby(["character", "expression"], sort=False)["realistic"].transform(lambda s: s.abs().max())
    out["share"] = np.where(top > 0, out["realistic"].abs() / top.where(top > 0, 1.0), 0.0)
    out["judged"] = (top > 0) & (out["share"] >= fraction)
    return out[cols]


def expression_spread(agreement: pd.DataFrame) -> pd.DataFrame:
    """Per character x expression, the judged measure whose levels differ most from the realistic one.

    Returns
    -------
    DataFrame
        character, expression, measure, largest_relative_difference, at_shape, judged (how many
        measures were judged); expressions with no judged measure are left out.
    """
    judged = agreement[agreement["judged"]]
    rows = []
    for (ch, expr), g in judged.groupby(["character", "expression"], sort=False):
        worst = g.loc[g["largest_relative_difference"].idxmax()]
        rows.append({"character": ch, "expression": expr, "measure": worst["measure"],
                     "largest_relative_difference": worst["largest_relative_difference"],
                     "at_shape": worst["at_shape"], "judged": len(g)})
    return pd.DataFrame(rows, columns=["character", "expression", "measure", "largest_relative_difference",
                                       "at_shape", "judged"])


def _relative_to_realistic(table: pd.DataFrame, agreement: pd.DataFrame) -> pd.DataFrame:
    """The judged rows of ``table`` with ``realistic`` (its measure's realistic value) and
    ``relative`` (value / realistic), sorted by shape (the figure's lines)."""
    keys = ["character", "expression", "measure"]
    judged = agreement.loc[agreement["judged"], keys + ["realistic"]]
    rows = table.merge(judged, on=keys, how="inner").assign(_s=lambda d: d["shape"].astype(float))
    return rows.assign(relative=rows["value"] / rows["realistic"]).sort_values("_s", kind="stable")


def plot_expression_measures(table: pd.DataFrame, path: Path, fraction: float = JUDGED_FRACTION) -> Path:
    """Each judged measure against shape level, relative to the realistic level (PNG).

    A row of panels per character, a panel per expression; each line is one judged measure
    (:func:`level_agreement`) divided by its value at the realistic level, so a level that moves
    the face as far as the realistic one sits on the grey line at 1; the legend gives each
    measure's realistic value in face lengths, and each panel names the measures not judged.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    agreement = level_agreement(table, fraction)
    lines = _relative_to_realistic(table, agreement)
    chars, exprs = list(dict.fromkeys(table["character"])), list(dict.fromkeys(table["expression"]))
    colours = dict(zip(MEASURES, plt.get_cmap("tab10").colors))
    fig, axes = plt.subplots(len(chars), len(exprs), figsize=(max(2.9 * len(exprs) + 0.6, 6.4), 2.7 * len(chars) + 1.0),
                             squeeze=False, sharex=True, sharey=True, constrained_layout=True)
    shapes = sorted(table["shape"].astype(float).unique())
    for (i, ch), (j, expr) in ((a, b) for a in enumerate(chars) for b in enumerate(exprs)):
        ax = axes[i, j]
        ax.axhline(1.0, color="0.6", lw=1)
        for m, g in lines[(lines["character"] == ch) & (lines["expression"] == expr)].groupby("measure", sort=False):
            ax.plot(g["_s"], g["relative"], marker="o", ms=3.5, color=colours[m],
                    label=f"{m.replace('_', ' ')} ({g['realistic'].iloc[0]:+.3f})")
        skipped = agreement[(agreement["character"] == ch) & (agreement["expression"] == expr) & ~agreement["judged"]]
        if len(skipped):
            ax.text(0.02, 0.97, "not judged: " + ", ".join(m.replace("_", " ") for m in skipped["measure"]),
                    transform=ax.transAxes, fontsize=6, color="0.4", va="top", wrap=True)
        ax.set_title(f"{ch}: {expr}", fontsize=10)
        ax.set_xticks(shapes, [f"{s:g}" for s in shapes], fontsize=8)
        ax.tick_params(axis="y", labelsize=8)
        if len(ax.lines) > 1:
            ax.legend(fontsize=6.5, loc="lower left", framealpha=0.8, handlelength=1.2)
        if j == 0:
            ax.set_ylabel("movement / realistic's", fontsize=9)
        if i == len(chars) - 1:
            ax.set_xlabel("shape level (0 realistic, 1 cartoon)", fontsize=9)
    rel = lines["relative"].to_numpy(np.float64)
    rel = rel[np.isfinite(rel)]
    axes[0, 0].set_ylim(min(0.0, 1.05 * rel.min(initial=0.0)), max(1.5, 1.05 * rel.max(initial=0.0)))
    fig.suptitle("How far each expression moves the face, relative to the realistic level\n"
                 "(legend: realistic value in face lengths; flat at 1 = the levels agree)", fontsize=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write_expression_measures(out: Path, landmarks: pd.DataFrame, grid: GridFile) -> list[Path]:
    """``expression_measures.csv``, ``expression_agreement.csv`` and ``expression_measures.png`` in ``out``.

    Written when the grid's landmarks have a neutral, at least one other expression and more
    than one shape level (nothing to compare otherwise: returns ``[]``); one log line per
    character x expression with its spread across levels.
    """
    from appeal.cells import write_table

    if landmarks.empty or NEUTRAL not in set(landmarks["expression"]) or landmarks["expression"].nunique() < 2 \
            or landmarks["shape"].nunique() < 2:
        return []
    table = expression_measures(landmarks)
    agreement = level_agreement(table)
    for (ch, expr), g in agreement.groupby(["character", "expression"], sort=False):
        judged = g[g["judged"]]
        logger.info("%s: %s %s across %d shape levels: largest relative difference from realistic %s", grid.name,
                    ch, expr, int(g["levels"].max()),
                    ", ".join(f"{r.measure} {r.largest_relative_difference:.2f} (ratio {r.ratio:.2f})"
                              for r in judged.itertuples()) or "none judged")
    out = Path(out)
    return [write_table(table, out / "expression_measures.csv", float_format="%.6f"),
            write_table(agreement, out / "expression_agreement.csv", float_format="%.5f"),
            plot_expression_measures(table, out / "expression_measures.png")]
