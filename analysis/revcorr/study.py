"""``appeal analyze revcorr``: every participant's AU model of every emotion, per stimulus level.

For each participant (x level, when the trials carry level columns) :func:`~analysis.revcorr.models.au_models`
gives the mutual information of each AU with each answer, its family-wise permutation p and the
model; :func:`~analysis.revcorr.models.logistic_image` the logistic alternative. For the AUs of a
model, :func:`temporal_profiles` averages the six temporal parameters over the trials answered with
that emotion on which the AU moved (beside the same average over every trial it moved on) and
correlates its peak amplitude with the intensity rating (Spearman). Across participants,
:func:`consensus` is the share of participants whose model holds each AU and the mean pairwise
Hamming distance between their models (AUs in one model and not the other). With one level column
and two participants or more, :mod:`analysis.revcorr.levels` tests whether the level changes the
models (a mixed model of MI per emotion x AU) and lists each participant's changes.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.revcorr.models import au_models, logistic_image
from analysis.revcorr.trials import RevcorrTrials
from appeal.cells import write_table
from appeal.progress import progress
from appeal.revcorr.grammar import PARAMETER_RANGES, presence_matrix
from appeal.revcorr.observers import EMOTIONS

__all__ = ["RevcorrResult", "temporal_profiles", "consensus", "analyze_revcorr"]


@dataclass
class RevcorrResult:
    """The tables (DataFrames), the files written and the report."""

    models: pd.DataFrame
    logistic: pd.DataFrame
    temporal: pd.DataFrame
    consensus: pd.DataFrame
    agreement: pd.DataFrame
    level_effects: pd.DataFrame | None = None
    level_agreement: pd.DataFrame | None = None
    files: list[Path] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)
    index_html: Path | None = None


def temporal_profiles(trials: list, table: pd.DataFrame, models: pd.DataFrame) -> pd.DataFrame:
    """The temporal parameters and intensity weight of each model AU (one group's trials)."""
    from scipy.stats import spearmanr

    rows = []
    motions = [{m.au: m for m in t.motions} for t in trials]
    answers = table["response"].to_numpy()
    intensity = pd.to_numeric(table.get("intensity", pd.Series(np.nan, index=table.index)), errors="coerce").to_numpy()
    for _, m in models[models["in_model"]].iterrows():
        moved = np.array([m["au"] in mv for mv in motions])
        chosen = moved & (answers == m["emotion"])
        row = {"emotion": m["emotion"], "au": m["au"], "n_trials": int(chosen.sum())}
        for p in PARAMETER_RANGES:
            row[p] = float(np.mean([getattr(motions[i][m["au"]], p) for i in np.nonzero(chosen)[0]]))
            row[f"{p}_all"] = float(np.mean([getattr(motions[i][m["au"]], p) for i in np.nonzero(moved)[0]]))
        amp = np.array([motions[i][m["au"]].peak_amplitude for i in np.nonzero(chosen)[0]])
        rated = ~np.isnan(intensity[chosen])
        row["intensity_rho"] = (float(spearmanr(amp[rated], intensity[chosen][rated])[0])
                                if rated.sum() >= 5 and np.ptp(intensity[chosen][rated]) > 0 else np.nan)
        rows.append(row)
    cols = ["emotion", "au", "n_trials", *[c for p in PARAMETER_RANGES for c in (p, f"{p}_all")], "intensity_rho"]
    return pd.DataFrame(rows, columns=cols)


def consensus(models: pd.DataFrame, subject: str, levels: tuple[str, ...]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Share of participants whose model holds each AU (per level x emotion x AU), and the mean
    pairwise Hamming distance of the participants' models (per level x emotion)."""
    keys = [*levels, "emotion"]
    share = (models.groupby([*keys, "au"], sort=False)["in_model"].mean().rename("share").reset_index())
    rows = []
    for key, sub in models.groupby(keys, sort=False):
        key = key if isinstance(key, tuple) else (key,)
        wide = sub.pivot(index=subject, columns="au", values="in_model").astype(int)
        pairs = list(itertools.combinations(range(len(wide)), 2))
        dist = [int(np.sum(wide.iloc[a].to_numpy() != wide.iloc[b].to_numpy())) for a, b in pairs]
        rows.append({**dict(zip(keys, key)), "participants": len(wide),
                     "mean_model_size": float(wide.sum(axis=1).mean()),
                     "mean_hamming": float(np.mean(dist)) if dist else np.nan})
    return share, pd.DataFrame(rows)


def _groups(data: RevcorrTrials, subject: str):
    keys = [subject, *data.levels]
    for key, sub in data.table.groupby(keys, sort=True):
        key = key if isinstance(key, tuple) else (key,)
        yield dict(zip(keys, key)), sub, [data.trials[i] for i in sub.index]


def _plot_models(models: pd.DataFrame, title: str, path: Path, value: str = "mi") -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from appeal.figures import plain_text

    @plain_text
    def draw() -> Path:
        emotions = list(dict.fromkeys(models["emotion"]))
        aus = list(dict.fromkeys(models["au"]))
        grid = models.pivot(index="emotion", columns="au", values=value).reindex(index=emotions, columns=aus)
        fig, ax = plt.subplots(figsize=(0.42 * len(aus) + 2.2, 0.42 * len(emotions) + 1.4))
        im = ax.imshow(grid.to_numpy(), cmap="magma_r" if value == "mi" else "Greens", aspect="auto",
                       vmin=0, vmax=None if value == "mi" else 1)
        if "in_model" in models:
            flags = models.pivot(index="emotion", columns="au", values="in_model").reindex(index=emotions, columns=aus)
            for (i, j) in zip(*np.nonzero(flags.fillna(False).to_numpy().astype(bool))):
                ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, ec="#1f77b4", lw=2))
        ax.set_xticks(range(len(aus)), aus, rotation=90, fontsize=8)
        ax.set_yticks(range(len(emotions)), emotions, fontsize=9)
        ax.set_title(title, fontsize=9)
        fig.colorbar(im, ax=ax, label="mutual information (bits)" if value == "mi" else "share of participants",
                     shrink=0.8)
        fig.tight_layout()
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=120)
        plt.close(fig)
        return path

    return draw()


def analyze_revcorr(data: RevcorrTrials, out: Path, *, subject: str = "participant_id", n_permutations: int = 1000,
                    alpha: float = 0.05, seed: int = 0) -> RevcorrResult:
    """Models, logistic images, temporal profiles, consensus, figures and the report into ``out``."""
    from appeal.report import ReportSection, write_index_html

    out = Path(out)
    model_rows, logit_rows, temporal_rows = [], [], []
    groups = list(_groups(data, subject))
    figures = []
    for key, sub, trials in progress(groups, total=len(groups), desc="revcorr models", unit="model"):
        x = presence_matrix(trials, data.aus)
        answers = sub["response"].to_numpy()
        m = au_models(x, answers, data.aus, EMOTIONS, n_permutations=n_permutations, alpha=alpha, seed=seed)
        lg = logistic_image(x, answers, data.aus, EMOTIONS)
        tp = temporal_profiles(trials, sub.reset_index(drop=True), m)
        model_rows.append(m.assign(**key, n_trials=len(sub)))
        logit_rows.append(lg.assign(**key))
        temporal_rows.append(tp.assign(**key))
        label = "_".join(f"{k}-{v}" for k, v in key.items() if k != subject)
        name = f"sub-{key[subject]}" + (f"_{label}" if label else "") + "_models.png"
        what = ", ".join(f"{k} {v}" for k, v in key.items() if k != subject)
        figures.append(_plot_models(m, f"participant {key[subject]}{' — ' + what if what else ''}: MI of each AU "
                                       f"with each answer ({len(sub)} trials; outlined: the model, p < {alpha})",
                                    out / "figures" / name))
    keys = [subject, *data.levels]
    order = lambda df: df[[*keys, *[c for c in df.columns if c not in keys]]]  # noqa: E731
    models, logistic = order(pd.concat(model_rows, ignore_index=True)), order(pd.concat(logit_rows, ignore_index=True))
    temporal = order(pd.concat(temporal_rows, ignore_index=True))
    share, agreement = consensus(models, subject, data.levels)
    effects = changes = None
    tables = [("models", models), ("logistic", logistic), ("temporal", temporal), ("consensus", share),
              ("agreement", agreement)]
    if len(data.levels) == 1 and models[subject].nunique() >= 2:
        from analysis.revcorr.levels import level_agreement, level_effects

        effects = level_effects(models, subject, data.levels[0])
        changes = level_agreement(models, subject, data.levels[0])
        tables += [("level_effects", effects), ("level_agreement", changes)]
    files = [write_table(df, out / f"{name}.csv") for name, df in tables]
    group_figs = []
    for key, sub in (share.groupby(list(data.levels), sort=True) if data.levels else [((), share)]):
        key = key if isinstance(key, tuple) else (key,)
        label = "_".join(f"{k}-{v}" for k, v in zip(data.levels, key))
        group_figs.append(_plot_models(sub, "share of participants whose model holds each AU"
                                       + (f" — {', '.join(f'{k} {v}' for k, v in zip(data.levels, key))}" if key else ""),
                                       out / f"consensus{'_' + label if label else ''}.png", value="share"))
    n_part = models[subject].nunique()
    text = [f"{n_part} participants, {len(data.table)} answered trials, {len(data.aus)} AUs; permutation test with "
            f"{n_permutations} shuffles, family-wise over the AUs (max statistic), alpha {alpha}. A model holds the "
            "AUs whose presence makes the answer likelier (direction > 0) at p < alpha (docs/revcorr.md)."]
    for _, row in agreement.iterrows():
        lv = ", ".join(f"{k} {row[k]}" for k in data.levels)
        held = share[(share["emotion"] == row["emotion"]) & (share["share"] >= 0.5)
                     & np.logical_and.reduce([share[k] == row[k] for k in data.levels] or [True])]["au"]
        text.append(f"- {row['emotion']}{' (' + lv + ')' if lv else ''}: AUs in at least half of the models: "
                    f"{', '.join(held) or 'none'}; mean model size {row['mean_model_size']:.1f}, "
                    f"mean pairwise Hamming distance {row['mean_hamming']:.1f}")
    if effects is not None:
        hits = effects[effects["q"] < 0.05]
        text.append(f"\nDoes {data.levels[0]} change the models? Mixed model of MI per emotion x AU "
                    "(mi ~ level + (1 | participant), Satterthwaite), Benjamini-Hochberg q over all tests: "
                    + (", ".join(f"{r.emotion} {r.au} (F {r.F:.1f}, q {r.q:.3g})" for r in hits.itertuples())
                       if len(hits) else "none at q < 0.05") + ".")
        moved = changes[changes["hamming"] > 0]
        text.append(f"Participants' models that differ between levels: {len(moved)} of {len(changes)} "
                    "(participant x emotion x pair of levels; level_agreement.csv says which AUs).")
    sections = [ReportSection("Models", "\n".join(text), group_figs, files[:1] + files[3:]),
                ReportSection("Participants", "Mutual information of each AU with each answer, per participant.",
                              figures, files[1:3])]
    (out / "report.md").write_text("# Reverse correlation\n\n" + "\n".join(text) + "\n", encoding="utf-8")
    html = write_index_html(out / "index.html", "Reverse correlation: AU models of the expressions", sections)
    return RevcorrResult(models, logistic, temporal, share, agreement, effects, changes, files, group_figs + figures,
                         html)
