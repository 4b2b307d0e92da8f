"""A participant's model of each expression from reverse-correlation answers (Jack et al. 2012).

Input: per trial, which AUs moved (the presence matrix ``X``, ``n_trials x n_aus``, 0/1) and the
participant's answer (an emotion, or "don't know"). For every emotion ``e`` and AU ``j``:

Mutual information
    ``MI(X_j; Y_e)`` in bits between the AU's presence and the binary answer ``Y_e = (answer ==
    e)``, from the 2 x 2 table of counts (plug-in estimate, ``0 log 0 = 0``). ``direction`` is
    ``P(Y_e | X_j = 1) - P(Y_e | X_j = 0)``: an AU that makes the answer likelier (> 0) belongs to
    the model; one that makes it rarer (< 0) is informative but not part of it.
Permutation test, corrected across AUs
    The answers are shuffled across trials ``n_permutations`` times (one shuffle serves every AU and
    emotion); per emotion the maximum MI over the AUs of each shuffle gives the null distribution of
    the largest MI, and an AU's ``p`` is the share of shuffles whose maximum reaches its MI (with the
    observed one counted: ``(1 + #) / (1 + n)``), family-wise over the AUs (the max statistic,
    Nichols & Holmes 2002). The **model** of ``e``: the AUs with ``p < alpha`` and ``direction > 0``.
Classification image (the logistic alternative)
    :func:`logistic_image`: per emotion a logistic regression of ``Y_e`` on all AUs' presence
    (ridge 1e-3, Newton-Raphson), its coefficients and Wald z.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from appeal.errors import AppealInputError

__all__ = ["mutual_information", "mi_permutation_test", "au_models", "logistic_image", "model_recovery"]


def _xlogx(p: NDArray) -> NDArray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(p > 0, p * np.log2(np.where(p > 0, p, 1.0)), 0.0)


def mutual_information(x: ArrayLike, y: ArrayLike) -> NDArray:
    """``MI(X_j; Y_e)`` in bits for every column ``j`` of ``x`` and ``e`` of ``y`` (both 0/1).

    ``x`` is ``(n, J)``, ``y`` ``(n, E)`` or ``(P, n, E)`` (a stack of shuffles); the result is
    ``(J, E)`` or ``(P, J, E)``.

    Examples
    --------
    >>> x = np.array([[1], [1], [0], [0]]); round(float(mutual_information(x, x)[0, 0]), 6)
    1.0
    >>> round(float(mutual_information(x, np.array([[1], [0], [1], [0]]))[0, 0]), 6)
    0.0
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    n = x.shape[0]
    n11 = np.einsum("nj,...ne->...je", x, y)
    nx = x.sum(axis=0)[:, None]
    ny = y.sum(axis=-2)[..., None, :]
    n10, n01 = nx - n11, ny - n11
    n00 = n - n11 - n10 - n01
    px1, py1 = nx / n, ny / n
    h = lambda p: -(_xlogx(p) + _xlogx(1 - p))  # noqa: E731
    joint = -(_xlogx(n11 / n) + _xlogx(n10 / n) + _xlogx(n01 / n) + _xlogx(n00 / n))
    return np.maximum(h(px1) + h(py1) - joint, 0.0)


def mi_permutation_test(x: ArrayLike, y: ArrayLike, n_permutations: int = 1000, seed: int = 0,
                        chunk: int = 100) -> tuple[NDArray, NDArray, NDArray]:
    """MI, its direction and the family-wise (max over AUs) permutation p per AU and emotion.

    Returns ``(mi, direction, p)``, each ``(J, E)``.
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    if x.shape[0] != y.shape[0]:
        raise AppealInputError(f"revcorr: {x.shape[0]} trials of AUs but {y.shape[0]} answers")
    mi = mutual_information(x, y)
    with np.errstate(invalid="ignore", divide="ignore"):
        on = (x.T @ y) / x.sum(axis=0)[:, None]
        off = ((1 - x).T @ y) / (1 - x).sum(axis=0)[:, None]
    direction = np.nan_to_num(on - off)
    rng = np.random.default_rng(seed)
    exceed = np.zeros_like(mi)
    done = 0
    while done < n_permutations:
        k = min(chunk, n_permutations - done)
        perms = np.stack([y[rng.permutation(len(y))] for _ in range(k)])
        null_max = mutual_information(x, perms).max(axis=1)  # (k, E)
        exceed += (null_max[:, None, :] >= mi[None]).sum(axis=0)
        done += k
    return mi, direction, (1 + exceed) / (1 + n_permutations)


def au_models(x: ArrayLike, answers: Sequence[str], aus: Sequence[str], emotions: Sequence[str], *,
              n_permutations: int = 1000, alpha: float = 0.05, seed: int = 0) -> pd.DataFrame:
    """One participant's AU model of every emotion: a tidy row per emotion x AU.

    Columns: ``emotion, au, mi, direction, p, in_model`` (``p < alpha`` and ``direction > 0``) and
    ``n_answers`` (trials answered with the emotion).
    """
    answers = np.asarray(answers, dtype=object)
    y = np.stack([(answers == e).astype(float) for e in emotions], axis=1)
    mi, direction, p = mi_permutation_test(x, y, n_permutations, seed)
    rows = [{"emotion": e, "au": au, "mi": float(mi[j, k]), "direction": float(direction[j, k]), "p": float(p[j, k]),
             "in_model": bool(p[j, k] < alpha and direction[j, k] > 0), "n_answers": int(y[:, k].sum())}
            for k, e in enumerate(emotions) for j, au in enumerate(aus)]
    return pd.DataFrame(rows)


def logistic_image(x: ArrayLike, answers: Sequence[str], aus: Sequence[str], emotions: Sequence[str],
                   ridge: float = 1e-3, max_iter: int = 50) -> pd.DataFrame:
    """Per emotion, the logistic regression ``logit P(answer = e) = b0 + sum_j b_j X_j``: a tidy row
    per emotion x AU with ``coef``, ``se`` and Wald ``z`` (Newton-Raphson, ridge on the slopes)."""
    x = np.asarray(x, float)
    design = np.c_[np.ones(len(x)), x]
    pen = np.full(design.shape[1], ridge)
    pen[0] = 0.0
    answers = np.asarray(answers, dtype=object)
    rows = []
    for e in emotions:
        y = (answers == e).astype(float)
        b = np.zeros(design.shape[1])
        for _ in range(max_iter):
            p = 1 / (1 + np.exp(-design @ b))
            w = p * (1 - p)
            hess = design.T @ (design * w[:, None]) + np.diag(pen) * len(y)
            step = np.linalg.solve(hess, design.T @ (y - p) - pen * len(y) * b)
            b += step
            if np.max(np.abs(step)) < 1e-10:
                break
        se = np.sqrt(np.diag(np.linalg.inv(hess)))
        rows += [{"emotion": e, "au": au, "coef": float(b[j + 1]), "se": float(se[j + 1]),
                  "z": float(b[j + 1] / se[j + 1])} for j, au in enumerate(aus)]
    return pd.DataFrame(rows)


def model_recovery(models: pd.DataFrame, templates: dict[str, Sequence[str]],
                   expected_mi: pd.DataFrame | None = None) -> pd.DataFrame:
    """How well :func:`au_models` recovered known templates: a row per emotion with ``hits`` (template
    AUs in the model), ``template_size``, ``false_aus`` (model AUs outside the template) and, with
    ``expected_mi`` (the same table from a very long run of the same observer), ``mi_corr``: the
    correlation of the emotion's MI over the AUs with the expected MI."""
    rows = []
    for e, tmpl in templates.items():
        sub = models[models["emotion"] == e].set_index("au")
        model = set(sub.index[sub["in_model"]])
        row = {"emotion": e, "template_size": len(tmpl), "hits": len(model & set(tmpl)),
               "false_aus": len(model - set(tmpl))}
        if expected_mi is not None:
            ref = expected_mi[expected_mi["emotion"] == e].set_index("au")["mi"].reindex(sub.index)
            row["mi_corr"] = float(np.corrcoef(sub["mi"], ref)[0, 1])
        rows.append(row)
    return pd.DataFrame(rows)
