"""Synthetic actors with a known truth: marker performances for testing retargeting (thesis ch. 4, issue 50).

A captured actor is another face whose blendshapes are not the rig's: its proportions differ and
so does its range of motion (one person's jaw opens further, another's smile is smaller; Figs
4.2–4.3). :func:`synthetic_actor` builds such an actor from a second neutral face in the rig's
topology (another ICT identity, a fitted scan):

- its blendshapes are the rig's carried onto its face by deformation transfer, each scaled by a
  factor of ``scale_range`` (log-uniform), modulated by a smooth gain field over the face
  (± ``gain_field``) and turned by a small rotation (at most ``rotation_deg``);
- markers sit on ``n_markers`` of its vertices (the rig's feature landmarks, then farthest-point
  samples of the moving face, :func:`~stimulus_engine.characters.markers.marker_vertices`);
- the performance: frame 0 neutral, a range-of-motion warm-up (each blendshape alone, then each
  bilateral pair, ramping to 1 and back; with ``mixing`` the ramps overlap and other shapes twitch
  faintly, as a real warm-up does), then ``n_test`` test frames, half the FACS recipe expressions
  at random intensities and half random mixtures of 1–4 shapes, weights in ``test_range``;
- every frame, the neutral included, carries isotropic Gaussian marker noise (``noise``, cm).

:func:`recovery` scores recovered weights against the truth on the test frames: the RMS error,
the correlation and, per blendshape, the gain (slope of recovered on true weight; 1 is faithful).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from stimulus_engine.characters.rig import FaceRig

__all__ = ["SyntheticActor", "recovery", "recovery_table", "synthetic_actor", "warm_up_weights"]


@dataclass
class SyntheticActor:
    """A marker performance with its truth.

    Attributes
    ----------
    names : list of str
        The rig's blendshapes, in the weights' column order.
    markers : (M,) int array
        The rig vertex under each marker.
    neutral : (M, 3) array
        The actor's captured neutral (frame 0, with its noise).
    positions : (F, M, 3) array
        The captured performance (frame 0 included), cm.
    weights : (F, K) array
        The true weights of every frame, in the actor's own blendshapes.
    blendshapes : (K, M, 3) array
        The actor's true blendshapes at the markers.
    scales : (K,) array
        Each blendshape's range relative to the rig's.
    test : (F,) bool array
        The test frames (after the warm-up).
    """

    names: list[str]
    markers: np.ndarray
    neutral: np.ndarray
    positions: np.ndarray
    weights: np.ndarray
    blendshapes: np.ndarray
    scales: np.ndarray
    test: np.ndarray


def _pairs(names: list[str]) -> list[tuple[int, int]]:
    idx = {n: i for i, n in enumerate(names)}
    return [(idx[n], idx[n[:-2] + "_R"]) for n in names if n.endswith("_L") and n[:-2] + "_R" in idx]


def warm_up_weights(names: list[str], rng: np.random.Generator, *, steps: int = 4, hold: int = 2,
                    mixing: bool = True) -> np.ndarray:
    """A range-of-motion warm-up as weights (F, K): each blendshape alone, then each bilateral pair,
    rising in ``steps`` frames to 1, held ``hold`` frames and falling back. With ``mixing`` each ramp
    starts while the previous one falls (they overlap by ``steps // 2`` frames) and one or two other
    shapes move faintly (weights up to 0.15) during each."""
    k = len(names)
    targets = [np.eye(k)[i] for i in range(k)]
    for i, j in _pairs(names):
        targets.append(np.eye(k)[i] + np.eye(k)[j])
    ramp = np.concatenate([np.arange(1, steps + 1) / steps, np.ones(hold), np.arange(steps - 1, -1, -1) / steps])
    n = len(ramp)
    shift = n - steps // 2 if mixing else n
    out = np.zeros((1 + shift * (len(targets) - 1) + n, k))
    for t, target in enumerate(targets):
        seg = ramp[:, None] * target[None]
        if mixing:
            rest = np.flatnonzero(target == 0)
            others = rng.choice(rest, min(int(rng.integers(1, 3)), len(rest)), replace=False)
            seg[:, others] += np.sin(np.linspace(0, np.pi, n))[:, None] * rng.uniform(0.03, 0.15, len(others))
        out[1 + t * shift:1 + t * shift + n] += seg
    return np.clip(out, 0.0, 1.0)


def _test_weights(names: list[str], n: int, lo: float, hi: float, rng: np.random.Generator) -> np.ndarray:
    from stimulus_engine.characters.expressions import expression_weights, facs_recipes

    idx = {nm: i for i, nm in enumerate(names)}
    recipes = []
    for e in sorted(facs_recipes()["expressions"]):
        w = {s: x for s, x in expression_weights(e).items() if s in idx}
        if w:
            v = np.zeros(len(names))
            for s, x in w.items():
                v[idx[s]] = x
            recipes.append(v / v.max())
    out = np.zeros((n, len(names)))
    for f in range(n):
        if f % 2 == 0 and recipes:
            out[f] = recipes[rng.integers(len(recipes))] * rng.uniform(lo, hi)
        else:
            pick = rng.choice(len(names), rng.integers(1, 5), replace=False)
            out[f, pick] = rng.uniform(lo, hi, len(pick))
    return out


def _rotation(rng: np.random.Generator, degrees: float) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    axis = rng.normal(size=3)
    return Rotation.from_rotvec(axis / np.linalg.norm(axis) * np.radians(rng.uniform(0, degrees))).as_matrix()


def synthetic_actor(rig: FaceRig, actor: np.ndarray, *, seed: int = 0, noise: float = 0.02,
                    scale_range: tuple[float, float] = (0.6, 1.6), gain_field: float = 0.1,
                    rotation_deg: float = 3.0, n_markers: int = 90, n_test: int = 108,
                    test_range: tuple[float, float] = (0.15, 0.95), mixing: bool = True) -> SyntheticActor:
    """A marker performance of the neutral ``actor`` (N, 3; the rig's topology) with known weights.

    Parameters
    ----------
    rig : FaceRig
        The rig whose blendshapes the actor's are made from (and which retargeting will use).
    actor : (N, 3) array
        The actor's neutral face in ``rig``'s topology.
    seed : int
        Seeds the ranges, the gain field, the rotation, the warm-up's mixing, the test frames and the noise.
    noise : float
        Standard deviation of every marker coordinate's noise, cm (0.02: 0.2 mm).
    scale_range : (float, float)
        Range of the per-blendshape scale factors (``(1, 1)``: the rig's ranges).
    gain_field : float
        Amplitude of the smooth gain over the face (0.1: ± 10 %).
    rotation_deg : float
        Largest rotation of each blendshape's motion (degrees, about a random axis).
    n_markers : int
    n_test : int
    test_range : (float, float)
        Range of the test frames' weights.
    mixing : bool
        Whether the warm-up's ramps overlap and other shapes twitch (:func:`warm_up_weights`).

    Returns
    -------
    SyntheticActor
    """
    from stimulus_engine.characters.expressions import deformation_transfer
    from stimulus_engine.characters.markers import marker_vertices

    rng = np.random.default_rng(seed)
    names = sorted(rig.blendshapes)
    actor = np.asarray(actor, np.float64)
    if actor.shape != rig.vertices.shape:
        raise ValueError(f"actor has {actor.shape} vertices, expected the rig's {rig.vertices.shape}")
    mk = marker_vertices(rig, n_markers)
    lo, hi = scale_range
    scales = np.exp(rng.uniform(np.log(lo), np.log(hi), len(names))) if hi > lo else np.full(len(names), lo)
    pts = actor[mk]
    span = np.ptp(pts, axis=0).max()
    truth = []
    for i, n in enumerate(names):
        d = (deformation_transfer(rig.vertices, rig.vertices + rig.blendshapes[n], actor, rig.faces) - actor)[mk]
        direction = rng.normal(size=3)
        gain = 1.0 + gain_field * np.sin(2 * np.pi * (pts @ (direction / np.linalg.norm(direction))) / span
                                         + rng.uniform(0, 2 * np.pi))
        truth.append(scales[i] * gain[:, None] * d @ _rotation(rng, rotation_deg).T)
    truth = np.stack(truth)
    warm = warm_up_weights(names, rng, mixing=mixing)
    test = _test_weights(names, n_test, *test_range, rng)
    w = np.vstack([warm, test])
    clean = pts[None] + np.einsum("fk,kmc->fmc", w, truth)
    positions = clean + rng.normal(0.0, noise, clean.shape)
    is_test = np.zeros(len(w), bool)
    is_test[len(warm):] = True
    return SyntheticActor(names, mk, positions[0].copy(), positions, w, truth, scales, is_test)


def recovery(estimated: np.ndarray, actor: SyntheticActor, *, which: np.ndarray | None = None) -> dict[str, float]:
    """How well ``estimated`` (F, K) weights recover ``actor``'s on its test frames.

    Parameters
    ----------
    estimated : (F, K) array
    actor : SyntheticActor
    which : (K,) bool array, optional
        The blendshapes scored (default all).

    Returns
    -------
    dict
        ``rms`` (weight RMS error), ``corr`` (Pearson over all scored weights), ``gain`` (median
        |gain − 1|, gain the least-squares slope of recovered on true weight per blendshape),
        ``n`` (blendshapes scored).
    """
    which = np.ones(len(actor.names), bool) if which is None else np.asarray(which, bool)
    est = np.asarray(estimated, np.float64)[actor.test][:, which]
    true = actor.weights[actor.test][:, which]
    slope = []
    for j in range(true.shape[1]):
        x, y = true[:, j], est[:, j]
        if np.sum(x > 0) >= 3:
            xc = x - x.mean()
            slope.append(float(xc @ (y - y.mean()) / (xc @ xc)))
    return {"rms": float(np.sqrt(np.mean((est - true) ** 2))), "corr": float(np.corrcoef(est.ravel(), true.ravel())[0, 1]),
            "gain": float(np.median(np.abs(np.asarray(slope) - 1.0))) if slope else float("nan"), "n": int(which.sum())}


def recovery_table(results: dict[str, np.ndarray], actor: SyntheticActor) -> pd.DataFrame:
    """:func:`recovery` of each method's weights, on all blendshapes and on those whose range differs
    (scale < 0.8 or > 1.25), as a tidy table (method, blendshapes, rms, corr, gain, n)."""
    differ = (actor.scales < 0.8) | (actor.scales > 1.25)
    rows = []
    for method, w in results.items():
        for label, which in (("all", None), ("range differs", differ)):
            if which is not None and not which.any():
                continue
            rows.append({"method": method, "blendshapes": label, **recovery(w, actor, which=which)})
    return pd.DataFrame(rows)
