"""Simulated rating data with chosen effects (for tests, the demo and power checks).

Ratings are ``cell mean + subject intercept + subject slope × (centred level index of one
factor) + noise``, rounded and clipped to a Likert scale. The subject slopes make
the variances of that factor's levels differ, i.e. violate sphericity, as real rating
data do. Output rows look like the experiment runner's BIDS ``*_beh.tsv`` files.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from appeal.cells import write_table
from appeal.labels import check_label, check_session
from appeal.outputs import require_inside

__all__ = ["ScaleModel", "simulate_ratings", "exp2_design", "write_bids"]


@dataclass
class ScaleModel:
    """How one rating scale depends on the factors.

    Attributes
    ----------
    mean : callable or float
        ``mean(levels: dict factor -> level index) -> float``, the population cell mean,
        or a constant.
    subject_sd : float
        SD of the subject intercepts.
    slope_sd : float
        SD of the subject slopes along ``slope_factor`` (sphericity violations).
    slope_factor : str or None
        The factor the subject slopes run along (default: the first factor).
    noise_sd : float
        SD of the trial noise.
    low, high : float
        Scale range; values are clipped to it.
    discrete : bool
        Round to whole numbers (Likert).
    rt_mean : float
        Mean response time in seconds (log-normal).
    """

    mean: object = 4.0
    subject_sd: float = 0.6
    slope_sd: float = 0.2
    noise_sd: float = 0.9
    low: float = 1
    high: float = 7
    discrete: bool = True
    rt_mean: float = 1.6
    slope_factor: str | None = None


def simulate_ratings(
    factors: Mapping[str, Sequence[str]],
    scales: Mapping[str, ScaleModel],
    n_subjects: int = 21,
    repetitions: int = 1,
    seed: int = 0,
    missing: float = 0.0,
    session: str = "1",
) -> pd.DataFrame:
    """Simulate a full within-subject rating experiment.

    Parameters
    ----------
    factors : mapping of str to sequence of str
        Within factors and their levels, e.g. ``{"shape": ["s0", …], "material": […]}``.
    scales : mapping of str to ScaleModel
        The rating scales (column ``response_<name>`` and ``rt_<name>`` each).
    n_subjects : int
        Participants ``sub-01`` … .
    repetitions : int
        Presentations of every stimulus (blocks).
    seed : int
        Seed of all randomness.
    missing : float
        Probability that a trial's responses are missing (skipped trials).
    session : str
        Session label.

    Returns
    -------
    DataFrame
        participant_id, session, block, trial, stimulus, one column per factor,
        response_<scale>, rt_<scale>; trials in a random order per block.
    """
    rng = np.random.default_rng(seed)
    names = list(factors)
    cells = list(itertools.product(*(range(len(factors[f])) for f in names)))
    slopes, means = {}, {}
    for s, model in scales.items():
        axis = names.index(model.slope_factor) if model.slope_factor else 0
        x = np.array([c[axis] for c in cells], float)
        slopes[s] = x - x.mean()
        m = model.mean
        means[s] = np.array([m(dict(zip(names, c))) if callable(m) else float(m) for c in cells])
    rows = []
    for i in range(n_subjects):
        pid = f"sub-{i + 1:02d}"
        effects = {s: (rng.normal(0, sc.subject_sd), rng.normal(0, sc.slope_sd)) for s, sc in scales.items()}
        trial = 0
        for block in range(1, repetitions + 1):
            for k in rng.permutation(len(cells)):
                trial += 1
                labels = [factors[f][j] for f, j in zip(names, cells[k])]
                row = {"participant_id": pid, "session": session, "block": block, "trial": trial,
                       "stimulus": "_".join(map(str, labels)), **dict(zip(names, labels))}
                skip = rng.random() < missing
                for s, sc in scales.items():
                    u, b = effects[s]
                    y = means[s][k] + u + b * slopes[s][k] + rng.normal(0, sc.noise_sd)
                    y = float(np.clip(np.round(y) if sc.discrete else y, sc.low, sc.high))
                    row[f"response_{s}"] = np.nan if skip else y
                    row[f"rt_{s}"] = np.nan if skip else round(float(rng.lognormal(np.log(sc.rt_mean), 0.35)), 3)
                rows.append(row)
    return pd.DataFrame(rows)


def exp2_design(n_characters: int = 2, n_levels: int = 5, n_expressions: int = 5):
    """Factors and scale models like thesis Experiment 2 (§6.4, Figs. 6.12/6.13).

    Realism grows with shape stylisation level, and material matters more the more realistic
    the shape (the curves spread out); appeal is highest where shape and material levels match,
    lower for the most realistic material and for angry faces.

    Returns
    -------
    factors : dict
        character × shape (s0–s4) × material (m0–m4) × expression.
    scales : dict of str to ScaleModel
        ``realism`` and ``appeal``.
    """
    expressions = ["angry", "happy", "neutral", "sad", "surprise"][:n_expressions]
    factors = {
        "character": ["female", "male"][:n_characters],
        "shape": [f"s{i}" for i in range(n_levels)],
        "material": [f"m{i}" for i in range(n_levels)],
        "expression": expressions,
    }
    top = n_levels - 1

    def realism(c):
        s, m = c["shape"] / top * 4, c["material"] / top * 4
        return 1.3 + 0.8 * s + 0.12 * m * s + (0.15 if expressions[c["expression"]] in ("neutral", "sad") else 0.0)

    def appeal(c):
        s, m = c["shape"] / top * 4, c["material"] / top * 4
        return (4.7 - 0.22 * (s - m) ** 2 + (0.4 if 1.5 < s < 3.5 else 0.0) - (0.6 if c["material"] == top else 0.0)
                - (0.9 if expressions[c["expression"]] == "angry" else 0.0) + 0.1 * c["character"])

    scales = {
        "realism": ScaleModel(mean=realism, subject_sd=0.5, slope_sd=0.3, noise_sd=0.8, slope_factor="shape"),
        "appeal": ScaleModel(mean=appeal, subject_sd=0.7, slope_sd=0.2, noise_sd=1.0, slope_factor="material"),
    }
    return factors, scales


def write_bids(data: pd.DataFrame, folder: str | Path, task: str) -> list[Path]:
    """Write one ``sub-<id>_ses-<n>_task-<task>_beh.tsv`` per participant and session.

    Returns
    -------
    list of Path
        The files written.
    """
    folder = Path(folder)
    check_label(task, "task")
    out = []
    for (pid, ses), part in data.groupby(["participant_id", "session"], sort=True):
        # the labels name folders and files: BIDS labels only, and the path checked to stay in ``folder``
        label = check_label(str(pid).removeprefix("sub-"), "participant_id")
        ses = check_session(ses.item() if isinstance(ses, np.generic) else ses, "session")
        path = folder / f"sub-{label}" / f"ses-{ses}" / "beh" / f"sub-{label}_ses-{ses}_task-{task}_beh.tsv"
        require_inside(folder, path, "write_bids")
        path.parent.mkdir(parents=True, exist_ok=True)
        write_table(part, path, sep="\t", na_rep="n/a")
        out.append(path)
    return out
