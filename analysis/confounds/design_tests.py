"""Do the low-level image measures of a stimulus set differ between the levels of its factors?

An audit table (``appeal stimuli audit``: one row per image, its factor columns and its
measures) is tested factor by factor. For a factor F and a measure m:

* the **mean per level** of F (over every image at that level) and their **range** (largest
  minus smallest level mean), compared with the measure's **threshold**: a range above it is
  *flagged*. Thresholds are in the measure's own units (:data:`DEFAULT_THRESHOLDS`, each the
  size of a difference a reviewer would ask about) and the user can set any of them;
* a **test across the items**. The items of F are the images' combinations of the other factors
  crossed with F (for Exp. 2's shape: character × material × expression, 50 items seen at 5 shape
  levels each; a grid's photograph material, found at the photograph level only, is not crossed
  with shape and is averaged within the items), or the column(s) the user names as item (the
  other factors then averaged within an item). A factor that is the only one (faces against
  houses, say) has the images themselves as items.
  Items seen at every level of F: a one-way repeated-measures ANOVA with the items as subjects
  (:func:`analysis.stats.rm_anova`, Greenhouse–Geisser p beside the uncorrected one). Items each
  seen at one level: a one-way between-items ANOVA (:func:`scipy.stats.f_oneway`). Anything else
  (one image per level, a level with one item, items seen at some levels only): means only, and
  the reason in ``test``.

The flag is the threshold, not the p value: rendered stimuli are deterministic, so a tiny but
perfectly consistent difference is "significant" with many items; whether it matters is the
size, which the user judges (the p value says whether it holds across the items).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from appeal.errors import AppealInputError
from appeal.levels import sort_levels

__all__ = ["DEFAULT_THRESHOLDS", "TEST_COLUMNS", "parse_thresholds", "level_means", "design_tests", "flagged"]

#: Flag thresholds in each measure's units: the range of level means above which a measure is
#: flagged. L*, a*, b*: 2 units (about one just-noticeable colour difference, ΔE*ab ≈ 2.3);
#: RMS contrast: 0.02 (sd of L*/100); spectrum slope: 0.1 (natural images spread about ±0.3
#: around -1); energy shares and edge density: 2 and 1 percentage points; face area: 2 % of the
#: image; eye positions and inter-ocular distance: 3 px (dlib's landmarks move 1-2 px between renders
#: of one face).
DEFAULT_THRESHOLDS: dict[str, float] = {
    "face_L_mean": 2.0, "face_a_mean": 2.0, "face_b_mean": 2.0, "face_rms_contrast": 0.02, "face_edge_density": 0.01,
    "image_L_mean": 2.0, "image_a_mean": 2.0, "image_b_mean": 2.0, "image_rms_contrast": 0.02,
    "image_edge_density": 0.01, "spectrum_slope": 0.1, "energy_low": 0.02, "energy_mid": 0.02, "energy_high": 0.02,
    "face_area": 0.02, "eye_left_x": 3.0, "eye_left_y": 3.0, "eye_right_x": 3.0, "eye_right_y": 3.0, "iod_px": 3.0,
}

#: The columns of :func:`design_tests`, in order.
TEST_COLUMNS = ["factor", "measure", "n_levels", "lowest_level", "lowest_mean", "highest_level", "highest_mean",
                "range", "threshold", "flagged", "relative_range", "test", "n_items", "F", "num_df", "den_df", "p",
                "mauchly_p", "gg_eps", "p_gg", "effect_size", "effect_size_kind", "note"]


def parse_thresholds(items: Sequence[str], source: str = "--threshold") -> dict[str, float]:
    """``["face_L_mean=1.5", ...]`` as a dict; a malformed item or unknown measure is a one-line error."""
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = str(item).partition("=")
        name = name.strip()
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not sep or not name or not math.isfinite(number) or number < 0:
            raise AppealInputError(f"{source}: '{item}': expected MEASURE=VALUE with a number >= 0, e.g. face_L_mean=1.5")
        if name not in DEFAULT_THRESHOLDS:
            raise AppealInputError(f"{source}: unknown measure '{name}' (expected one of: {', '.join(DEFAULT_THRESHOLDS)})")
        out[name] = number
    return out


def _measures(table: pd.DataFrame, thresholds: Mapping[str, float]) -> list[str]:
    return [m for m in thresholds if m in table.columns and pd.to_numeric(table[m], errors="coerce").notna().any()]


def level_means(table: pd.DataFrame, factors: Sequence[str], measures: Sequence[str] | None = None) -> pd.DataFrame:
    """Tidy means per level: one row per factor × level × measure with ``mean``, ``sd`` and ``n``
    (images with the measure), levels in :func:`appeal.levels.sort_levels` order."""
    measures = list(measures) if measures is not None else _measures(table, DEFAULT_THRESHOLDS)
    rows = []
    for factor in factors:
        for level in sort_levels(table[factor].dropna().unique()):
            sel = table[table[factor] == level]
            for m in measures:
                v = pd.to_numeric(sel[m], errors="coerce").dropna()
                rows.append({"factor": factor, "level": level, "measure": m, "mean": float(v.mean()) if len(v) else math.nan,
                             "sd": float(v.std(ddof=1)) if len(v) > 1 else math.nan, "n": int(len(v))})
    return pd.DataFrame(rows, columns=["factor", "level", "measure", "mean", "sd", "n"])


def _crossed(table: pd.DataFrame, factor: str, other: str) -> bool:
    """Every level of ``other`` occurs at every level of ``factor`` (a grid's photographs, with their
    own material level at the photograph shape level only, are not crossed with shape)."""
    seen = table.groupby(other, sort=False)[factor].nunique()
    return bool((seen == table[factor].nunique()).all())


def _item_ids(table: pd.DataFrame, factor: str, factors: Sequence[str], item: Sequence[str] | None) -> pd.Series:
    if item and factor not in item:
        cols = list(item)
    else:
        cols = [f for f in factors if f != factor and _crossed(table, factor, f)]
    if cols:
        return table[cols].astype(str).agg(" / ".join, axis=1)
    if any(f != factor for f in factors):
        return pd.Series(["all"] * len(table), index=table.index)
    # the only factor (faces vs houses, say): each image is an item
    return table["file"].astype(str) if "file" in table else pd.Series(table.index.astype(str), index=table.index)


def _rm_test(data: pd.DataFrame, factor: str, n_items: int) -> dict:
    from analysis.stats.anova import rm_anova

    res = rm_anova(data, dv="y", subject="item", within=[factor], aggregate="mean").iloc[0]
    return {"test": f"rm-ANOVA across {n_items} items", "F": float(res["F"]), "num_df": float(res["num_df"]),
            "den_df": float(res["den_df"]), "p": float(res["p"]), "mauchly_p": float(res["mauchly_p"]),
            "gg_eps": float(res["gg_eps"]), "p_gg": float(res["p_gg"]), "effect_size": float(res["pes"]), "effect_size_kind": "partial eta^2", "note": str(res.get("note", "") or "")}


def _between_test(data: pd.DataFrame, factor: str, n_items: int) -> dict:
    from scipy import stats

    groups = [g["y"].to_numpy(float) for _, g in data.groupby(factor)]
    k, n = len(groups), sum(len(g) for g in groups)
    grand = np.concatenate(groups).mean()
    ss_between = sum(len(g) * (g.mean() - grand) ** 2 for g in groups)
    ss_total = float(((np.concatenate(groups) - grand) ** 2).sum())
    with np.errstate(divide="ignore", invalid="ignore"):
        F, p = stats.f_oneway(*groups)
    return {"test": f"one-way ANOVA between {n_items} items", "F": float(F), "num_df": float(k - 1),
            "den_df": float(n - k), "p": float(p), "mauchly_p": math.nan, "gg_eps": math.nan, "p_gg": math.nan,
            "effect_size": float(ss_between / ss_total) if ss_total > 0 else math.nan, "effect_size_kind": "eta^2",
            "note": ""}


def _test(table: pd.DataFrame, factor: str, measure: str, items: pd.Series) -> dict:
    """The factor's test for one measure, or why there is none (``test`` says)."""
    data = pd.DataFrame({"item": items, factor: table[factor], "y": pd.to_numeric(table[measure], errors="coerce")})
    data = data.dropna()
    # average repeats of an item at one level (the other factors when the user named the item)
    cells = data.groupby(["item", factor], sort=False)["y"].mean().reset_index()
    n_levels = cells[factor].nunique()
    per_item = cells.groupby("item")[factor].nunique()
    per_level = cells.groupby(factor)["item"].nunique()
    n_items = int(per_item.size)
    if n_levels < 2:
        return {"test": "none: one level has this measure", "n_items": n_items}
    if n_items >= 2 and (per_item == n_levels).all():
        return {**_rm_test(cells, factor, n_items), "n_items": n_items}
    if (per_item == 1).all() and (per_level >= 2).all() and n_items > n_levels:
        return {**_between_test(cells, factor, n_items), "n_items": n_items}
    if (data.groupby(factor).size() == 1).all():
        why = "one image per level"
    elif n_items < 2:
        why = "one item (no other factor crossed with it; name the items)"
    elif (per_item == 1).all():
        why = "a level with one item"
    else:
        why = "items seen at some levels only"
    return {"test": f"none: {why}", "n_items": n_items}


def design_tests(table: pd.DataFrame, factors: Sequence[str], *, thresholds: Mapping[str, float] | None = None,
                 item: Sequence[str] | None = None) -> pd.DataFrame:
    """How every measure varies with every factor of an audit table (see the module docstring).

    Parameters
    ----------
    table : DataFrame
        The audit table: one row per image, the factor columns and the measures.
    factors : sequence of str
        The factors to test (each with two levels or more). The items of a factor are the
        combinations of the other factors named here that are crossed with it (each of their
        levels at every level of the factor), unless ``item`` is given.
    thresholds : mapping, optional
        Thresholds that replace those of :data:`DEFAULT_THRESHOLDS` (measure → value in its units).
    item : sequence of str, optional
        Column(s) naming an item (e.g. ``["character"]``): the other factors are averaged within
        each item and level (a factor that is itself an item column keeps the default items).

    Returns
    -------
    DataFrame
        One row per factor × measure, columns :data:`TEST_COLUMNS`: the lowest and highest level
        mean, ``range`` (their difference), ``threshold``, ``flagged`` (range > threshold),
        ``relative_range`` (range / threshold), the test's name, ``n_items``, ``F``, ``num_df``,
        ``den_df``, ``p``, Mauchly's p, ``gg_eps`` and ``p_gg`` (Greenhouse–Geisser; rm-ANOVA with
        three levels or more),
        the effect size and its kind (partial η² or η²) and a note; NaN where there is no test.

    Raises
    ------
    AppealInputError
        A factor or item column the table lacks.
    """
    limits = {**DEFAULT_THRESHOLDS, **dict(thresholds or {})}
    missing = [c for c in [*factors, *(item or [])] if c not in table.columns]
    if missing:
        raise AppealInputError(f"audit table: no column '{missing[0]}' (expected one of: {', '.join(map(str, table.columns))})")
    measures = _measures(table, limits)
    means = level_means(table, factors, measures)
    rows = []
    for factor in factors:
        items = _item_ids(table, factor, factors, item)
        for m in measures:
            lv = means[(means["factor"] == factor) & (means["measure"] == m)].dropna(subset=["mean"])
            if lv.empty:
                continue
            lo, hi = lv.loc[lv["mean"].idxmin()], lv.loc[lv["mean"].idxmax()]
            rng = float(hi["mean"] - lo["mean"])
            thr = float(limits[m])
            row = {"factor": factor, "measure": m, "n_levels": int(len(lv)), "lowest_level": lo["level"],
                   "lowest_mean": float(lo["mean"]), "highest_level": hi["level"], "highest_mean": float(hi["mean"]),
                   "range": rng, "threshold": thr, "flagged": bool(rng > thr),
                   "relative_range": rng / thr if thr > 0 else (math.inf if rng > 0 else 0.0)}
            row.update(_test(table, factor, m, items))
            rows.append(row)
    out = pd.DataFrame(rows).reindex(columns=TEST_COLUMNS)
    return out


def flagged(tests: pd.DataFrame) -> pd.DataFrame:
    """The flagged rows of :func:`design_tests`, largest ``relative_range`` first."""
    if tests.empty:
        return tests
    return tests[tests["flagged"].astype(bool)].sort_values("relative_range", ascending=False).reset_index(drop=True)
