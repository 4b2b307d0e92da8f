"""Does a stimulus level change the participants' models? (Reverse correlation across stylisation.)

:func:`level_effects`: for every emotion x AU, the linear mixed model ``mi ~ level + (1 | participant)``
of the participants' mutual information at each level (the project's LMM, REML, type-III F with
Satterthwaite dfs, as lme4 + lmerTest), its p and the Benjamini-Hochberg q over all emotion x AU
tests (:func:`scipy.stats.false_discovery_control`), beside each level's mean MI and the share of
participants whose model holds the AU. :func:`level_agreement`: per participant and emotion, the
Hamming distance between their models at every pair of levels (AUs in one and not the other).
"""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd

from appeal.logs import logger

__all__ = ["level_effects", "level_agreement"]


def level_effects(models: pd.DataFrame, subject: str, level: str) -> pd.DataFrame:
    """One row per emotion x AU: ``F, num_df, den_df, p, q`` of the level effect on MI, the mean MI
    and model share at each level (``mi_<level>``, ``share_<level>``), and a ``note`` where no test
    could be made (fewer than two participants or levels, no variation)."""
    from scipy.stats import false_discovery_control

    from analysis.stats.lmm import fit_lmm
    from analysis.stats.lmm_anova import lmm_anova

    rows = []
    levels = sorted(models[level].astype(str).unique())
    for (emotion, au), sub in models.groupby(["emotion", "au"], sort=False):
        data = pd.DataFrame({"mi": sub["mi"].to_numpy(float), "level": sub[level].astype(str).to_numpy(),
                             "participant": sub[subject].astype(str).to_numpy()})
        row = {"emotion": emotion, "au": au}
        for lv in levels:
            at = sub[sub[level].astype(str) == lv]
            row[f"mi_{lv}"] = float(at["mi"].mean())
            row[f"share_{lv}"] = float(at["in_model"].mean())
        row.update({"F": np.nan, "num_df": np.nan, "den_df": np.nan, "p": np.nan, "note": ""})
        if data["participant"].nunique() < 2 or data["level"].nunique() < 2:
            row["note"] = "fewer than two participants or levels"
        elif np.ptp(data["mi"]) == 0:
            row["note"] = "no variation"
        else:
            try:
                fit = fit_lmm("mi ~ level + (1 | participant)", data, factors=["level"], source=f"{emotion} {au}")
                test = lmm_anova(fit).set_index("effect").loc["level"]
                row.update({k: float(test[k]) for k in ("F", "num_df", "den_df", "p")})
                row["note"] = "singular fit" if fit.singular else ""
            except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
                logger.warning("revcorr level effect %s %s: no test (%s)", emotion, au, exc)
                row["note"] = f"no test: {str(exc).splitlines()[0][:80]}"
        rows.append(row)
    out = pd.DataFrame(rows)
    tested = out["p"].notna()
    out["q"] = np.nan
    if tested.any():
        out.loc[tested, "q"] = false_discovery_control(out.loc[tested, "p"].to_numpy())
    cols = ["emotion", "au", "F", "num_df", "den_df", "p", "q",
            *[c for lv in levels for c in (f"mi_{lv}", f"share_{lv}")], "note"]
    return out[cols]


def level_agreement(models: pd.DataFrame, subject: str, level: str) -> pd.DataFrame:
    """Per participant x emotion x pair of levels: the Hamming distance between the two models and
    the AUs each adds (``only_<a>``, ``only_<b>``, as ``AU6+AU12``)."""
    rows = []
    for (pid, emotion), sub in models.groupby([subject, "emotion"], sort=False):
        held = {str(lv): set(g.loc[g["in_model"], "au"]) for lv, g in sub.groupby(level)}
        for a, b in itertools.combinations(sorted(held), 2):
            rows.append({subject: pid, "emotion": emotion, "level_a": a, "level_b": b,
                         "hamming": len(held[a] ^ held[b]), "only_a": "+".join(sorted(held[a] - held[b])),
                         "only_b": "+".join(sorted(held[b] - held[a]))})
    return pd.DataFrame(rows, columns=[subject, "emotion", "level_a", "level_b", "hamming", "only_a", "only_b"])
