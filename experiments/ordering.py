"""Trial orders under constraints: random, no identical stimulus twice in a row, maximum runs.

Pure functions on lists; all randomness comes from the ``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from appeal.errors import AppealInputError

__all__ = ["constrained_order", "check_order", "run_lengths"]


def _violates(seq: Sequence[str], cand: str, attrs: Mapping[str, Mapping[str, str]],
              no_repeat: bool, max_run: Mapping[str, int]) -> bool:
    if not seq:
        return False
    if no_repeat and seq[-1] == cand:
        return True
    for factor, limit in max_run.items():
        level = attrs[cand][factor]
        run = 0
        for prev in reversed(seq):
            if attrs[prev][factor] != level:
                break
            run += 1
            if run >= limit:
                return True
    return False


def constrained_order(
    items: Sequence[str],
    attrs: Mapping[str, Mapping[str, str]],
    rng: np.random.Generator,
    *,
    no_repeat: bool = False,
    max_run: Mapping[str, int] | None = None,
    history: Sequence[str] = (),
    max_attempts: int = 500,
) -> list[str]:
    """A random order of ``items`` (stimulus ids, repeats allowed) obeying the constraints.

    Without constraints this is a uniformly random permutation. With constraints, each
    position is drawn among the items that keep every constraint, with probability
    proportional to how many copies remain (so every stimulus stays equally likely at every
    position); a dead end restarts the draw.

    Parameters
    ----------
    items : sequence of str
        The multiset to order (e.g. 36 stimulus ids, each 15 times).
    attrs : mapping
        ``attrs[item][factor]`` -> level, for the factors in ``max_run``.
    rng : numpy.random.Generator
        Source of randomness.
    no_repeat : bool
        Never the same item twice in a row.
    max_run : mapping of str to int, optional
        factor -> most consecutive items sharing a level.
    history : sequence of str
        Items already presented just before (constraints hold across the boundary).
    max_attempts : int
        Restarts before giving up.

    Returns
    -------
    list of str
        The order.

    Raises
    ------
    AppealInputError
        When the constraints cannot be met (e.g. one stimulus is more than half the trials).
    """
    max_run = dict(max_run or {})
    items = list(items)
    if not items:
        return []
    if not no_repeat and not max_run:
        return [items[i] for i in rng.permutation(len(items))]
    names, counts0 = np.unique(np.array(items, dtype=object), return_counts=True)
    names = [str(n) for n in names]
    if no_repeat and counts0.max() > (len(items) + 1) // 2:
        worst = names[int(counts0.argmax())]
        raise AppealInputError(f"order.no_immediate_repeat: cannot be met: '{worst}' is {counts0.max()} of "
                               f"{len(items)} trials (at most {(len(items) + 1) // 2} possible)")
    for _ in range(max_attempts):
        counts = counts0.astype(float).copy()
        seq: list[str] = list(history)
        start = len(seq)
        ok = True
        for _pos in range(len(items)):
            allowed = np.array([c > 0 and not _violates(seq, n, attrs, no_repeat, max_run)
                                for n, c in zip(names, counts)])
            if not allowed.any():
                ok = False
                break
            w = counts * allowed
            k = int(rng.choice(len(names), p=w / w.sum()))
            seq.append(names[k])
            counts[k] -= 1
        if ok:
            return seq[start:]
    raise AppealInputError(f"order: no order of {len(items)} trials meets no_immediate_repeat={no_repeat} "
                           f"and max_run={max_run} after {max_attempts} attempts")


def run_lengths(values: Sequence[object]) -> list[int]:
    """Lengths of the runs of equal consecutive values (``[a, a, b] -> [2, 1]``)."""
    runs: list[int] = []
    prev = object()
    for v in values:
        if runs and v == prev:
            runs[-1] += 1
        else:
            runs.append(1)
        prev = v
    return runs


def check_order(seq: Sequence[str], attrs: Mapping[str, Mapping[str, str]], *,
                no_repeat: bool = False, max_run: Mapping[str, int] | None = None) -> list[str]:
    """Every violated constraint of ``seq`` as a message (empty list: the order is valid)."""
    problems = []
    if no_repeat:
        for i in range(1, len(seq)):
            if seq[i] == seq[i - 1]:
                problems.append(f"positions {i - 1},{i}: '{seq[i]}' twice in a row")
    for factor, limit in (max_run or {}).items():
        longest = max(run_lengths([attrs[s][factor] for s in seq]), default=0)
        if longest > limit:
            problems.append(f"{factor}: a run of {longest} > {limit}")
    return problems
