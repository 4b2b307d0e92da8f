"""Facial expressions from FACS recipes on delta-blendshape rigs, and deformation transfer.

Expressions act on a :class:`~stimulus_engine.characters.rig.FaceRig`, whose blendshapes are per-vertex
*deltas* from the neutral (the ICT Face Model, :func:`stimulus_engine.characters.ict.load_ict_rig`, or a
head made by code, :func:`stimulus_engine.characters.procedural_head.procedural_head`).

Expressions are built from FACS action-unit recipes kept in a data file
(``stimulus_engine/data/facs_recipes.yaml``): an expression is a weighted set of AUs, an AU a set
of blendshapes; ``intensity`` scales all weights. On the rig's own neutral the result is
``neutral + Σ w_k δ_k``. On a *stylised* shape in the same topology (from
:func:`stimulus_engine.stylisation.shape.stylise` or a correspondence fit) the deltas would be wrong in
size and direction (thesis ch. 4), so the expression is carried over by deformation transfer
(Sumner & Popović 2004): each triangle's deformation gradient of the source expression is
applied to the target's triangle and the target vertices are solved in the least-squares sense.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import yaml

from appeal.errors import AppealInputError
from stimulus_engine.characters.rig import FaceRig
from stimulus_engine.data import DATA_DIR

__all__ = [
    "EXPRESSIONS",
    "apply_expression",
    "check_blendshapes",
    "deformation_transfer",
    "expression_delta",
    "expression_weights",
    "facs_recipes",
    "pose_weights",
    "resolve_expression",
]

_RECIPES = DATA_DIR / "facs_recipes.yaml"

#: The thesis's five expressions (ch. 5, §6.3).
EXPRESSIONS: tuple[str, ...] = ("neutral", "anger", "happiness", "sadness", "surprise")

# --------------------------------------------------------------------------------------------
# Recipes
# --------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=4)
def facs_recipes(path: str | None = None) -> dict:
    """The FACS recipe file (``action_units``, ``expressions``, ``aliases``) as a dict."""
    p = Path(path) if path else _RECIPES
    try:
        data = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise AppealInputError(f"{p}: cannot read FACS recipes ({exc})".splitlines()[0]) from None
    for key in ("action_units", "expressions"):
        if not isinstance(data.get(key), dict):
            raise AppealInputError(f"{p}: {key}: missing (expected a mapping)")
    for expr, aus in data["expressions"].items():
        for au in aus or {}:
            if au not in data["action_units"]:
                raise AppealInputError(f"{p}: expressions.{expr}: unknown action unit '{au}'")
    data.setdefault("aliases", {})
    return data


def resolve_expression(name: str) -> str:
    """The canonical recipe name for ``name`` (aliases like ``happy`` → ``happiness``)."""
    rec = facs_recipes()
    key = str(name).strip().lower()
    key = rec["aliases"].get(key, key)
    if key not in rec["expressions"]:
        known = sorted(set(rec["expressions"]) | set(rec["aliases"]))
        raise ValueError(f"unknown expression '{name}' (expected one of: {', '.join(known)})")
    return key


def expression_weights(name: str, intensity: float = 1.0) -> dict[str, float]:
    """Blendshape weights of an expression: Σ over its AUs of AU weight × intensity per shape.

    Examples
    --------
    >>> w = expression_weights("happiness")
    >>> w["mouthSmile_L"], w["cheekSquint_R"]
    (1.0, 0.8)
    """
    rec = facs_recipes()
    weights: dict[str, float] = {}
    for au, w in (rec["expressions"][resolve_expression(name)] or {}).items():
        for shape in rec["action_units"][au]:
            weights[shape] = weights.get(shape, 0.0) + float(w) * float(intensity)
    return weights


# --------------------------------------------------------------------------------------------
# Deformation transfer
# --------------------------------------------------------------------------------------------


def _frames(v: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Per-triangle 3 × 3 frames [e1, e2, n / sqrt|n|] (Sumner & Popović's fourth vertex)."""
    e1 = v[faces[:, 1]] - v[faces[:, 0]]
    e2 = v[faces[:, 2]] - v[faces[:, 0]]
    n = np.cross(e1, e2)
    n = n / np.sqrt(np.linalg.norm(n, axis=1, keepdims=True) + 1e-300)
    return np.stack([e1, e2, n], axis=2)


#: Weak pull towards "target + source delta": fixes what edges alone leave free (the position of
#: parts that touch no fixed vertex, e.g. the lower teeth under jawOpen).
_DT_LAMBDA = 1e-4
_DT_SYSTEMS: dict[tuple, tuple] = {}


def _dt_system(src_rest: np.ndarray, faces: np.ndarray, moved: np.ndarray) -> tuple:
    """The target-independent part of :func:`deformation_transfer`, cached.

    The triangles used, their inverse rest frames, the free vertices, the edge matrix ``A`` and
    the factorisation of ``AᵀA + λI`` depend only on the source rest shape, the faces and which
    vertices the source moves, not on the target: every stylisation level of a character with
    the same expression reuses them (Exp. 2: 32 → 8 factorisations). Same numbers as solving
    afresh, so results are bit-identical.
    """
    key = tuple(hashlib.sha1(np.ascontiguousarray(a).tobytes()).hexdigest() for a in (src_rest, faces, moved))
    hit = _DT_SYSTEMS.get(key)
    if hit is not None:
        return hit
    tri = moved[faces].any(axis=1)
    fr = _frames(src_rest, faces[tri])
    ok = np.abs(np.linalg.det(fr)) > 1e-12
    tri_ids = np.flatnonzero(tri)[ok]
    f = faces[tri_ids]
    free = np.flatnonzero(moved)
    col = np.full(len(src_rest), -1)
    col[free] = np.arange(len(free))
    heads = np.concatenate([f[:, 1], f[:, 2]])
    tails = np.concatenate([f[:, 0], f[:, 0]])
    rows = np.arange(len(heads))
    data, ri, ci = [], [], []
    for idx, sign in ((heads, 1.0), (tails, -1.0)):
        c = col[idx]
        is_free = c >= 0
        ri.append(rows[is_free]); ci.append(c[is_free]); data.append(np.full(is_free.sum(), sign))
    A = sp.csr_matrix((np.concatenate(data), (np.concatenate(ri), np.concatenate(ci))),
                      shape=(len(rows), len(free)))
    AtA = (A.T @ A).tocsc() + sp.identity(len(free), format="csc") * _DT_LAMBDA
    out = (tri_ids, np.linalg.inv(fr[ok]), free, A, spla.factorized(AtA))
    if len(_DT_SYSTEMS) >= 16:
        _DT_SYSTEMS.clear()
    _DT_SYSTEMS[key] = out
    return out


def deformation_transfer(src_rest: np.ndarray, src_deformed: np.ndarray, tgt_rest: np.ndarray,
                         faces: np.ndarray, *, tol: float = 1e-7) -> np.ndarray:
    """Carry the deformation ``src_rest → src_deformed`` onto ``tgt_rest`` (same topology).

    Each triangle's deformation gradient ``S = F_def F_rest⁻¹`` (frames of two edges and the
    scaled normal) is applied to the target triangle's edges; vertices the source does not move
    stay fixed and the moved ones are solved by sparse least squares on edge vectors.

    Parameters
    ----------
    src_rest, src_deformed, tgt_rest : (N, 3) arrays
    faces : (F, 3) int array
    tol : float
        Vertices moving less than this are held fixed.

    Returns
    -------
    (N, 3) array
        The deformed target. With ``tgt_rest == src_rest`` it equals ``src_deformed`` (up to
        solver precision).
    """
    src_rest, src_deformed, tgt_rest = (np.asarray(a, np.float64) for a in (src_rest, src_deformed, tgt_rest))
    faces = np.asarray(faces, np.int64)
    moved = np.linalg.norm(src_deformed - src_rest, axis=1) > tol
    out = tgt_rest.copy()
    if not moved.any():
        return out
    tri_ids, inv_fr, free, A, solve = _dt_system(src_rest, faces, moved)
    f = faces[tri_ids]
    S = _frames(src_deformed, f) @ inv_fr
    e1 = tgt_rest[f[:, 1]] - tgt_rest[f[:, 0]]
    e2 = tgt_rest[f[:, 2]] - tgt_rest[f[:, 0]]
    d = np.concatenate([np.einsum("tij,tj->ti", S, e1), np.einsum("tij,tj->ti", S, e2)])  # (2T, 3)
    col = np.full(len(tgt_rest), -1)
    col[free] = np.arange(len(free))
    heads = np.concatenate([f[:, 1], f[:, 2]])
    tails = np.concatenate([f[:, 0], f[:, 0]])
    b = d.copy()
    for idx, sign in ((heads, 1.0), (tails, -1.0)):
        fixed = col[idx] < 0
        b[fixed] -= sign * tgt_rest[idx[fixed]]
    lam = _DT_LAMBDA
    Atb = A.T @ b + lam * (tgt_rest[free] + src_deformed[free] - src_rest[free])
    out[free] = np.column_stack([solve(Atb[:, k]) for k in range(3)])
    return out


def check_blendshapes(rig: FaceRig, weights: dict[str, float]) -> None:
    """ValueError naming the blendshapes of ``weights`` that ``rig`` lacks."""
    missing = sorted(s for s in weights if s not in rig.blendshapes)
    if missing:
        raise ValueError(f"rig '{rig.name}' lacks blendshape(s) {', '.join(missing)}")


def expression_delta(rig: FaceRig, weights: dict[str, float]) -> np.ndarray:
    """``Σ w_k δ_k`` of ``rig``'s blendshapes (the weights' names must be the rig's; ValueError names
    those it lacks)."""
    check_blendshapes(rig, weights)
    delta = np.zeros_like(rig.vertices)
    for s, w in sorted(weights.items()):
        if w:
            delta += w * rig.blendshapes[s]
    return delta


def pose_weights(rig: FaceRig, weights: dict[str, float], *, target: np.ndarray | None = None,
                 method: str = "deformation_transfer") -> np.ndarray:
    """Vertices of ``rig`` (or of a ``target`` neutral in its topology) posed by blendshape weights.

    Parameters
    ----------
    rig : FaceRig
    weights : dict of str to float
        Blendshape name -> weight (e.g. :func:`expression_weights`, or one frame of a retargeted
        animation).
    target : (N, 3) array, optional
        Another neutral in the rig's topology (a stylised shape). Default: the rig's own.
    method : {"deformation_transfer", "delta"}
        How ``rig``'s deformation is carried onto ``target``: deformation transfer of the
        whole pose (Sumner & Popović 2004), or the deltas added unchanged.
    """
    delta = expression_delta(rig, weights)
    if target is None:
        return rig.vertices + delta
    target = np.asarray(target, np.float64)
    if method == "delta" or not any(weights.values()):
        return target + delta
    if method != "deformation_transfer":
        raise ValueError(f"unknown method '{method}' (expected deformation_transfer or delta)")
    return deformation_transfer(rig.vertices, rig.vertices + delta, target, rig.faces)


def apply_expression(rig: FaceRig, expression: str, intensity: float = 1.0, *,
                     target: np.ndarray | None = None, method: str = "deformation_transfer") -> np.ndarray:
    """Vertices of ``rig`` (or of a stylised ``target`` in its topology) showing an expression.

    Parameters
    ----------
    rig : FaceRig
        Supplies the blendshapes (deltas from ``rig.vertices``).
    expression : str
        A recipe name (``neutral``, ``anger``, ``happiness``, ``sadness``, ``surprise``, ``fear``,
        ``disgust``) or an alias (``angry``, ``happy`` ...).
    intensity : float
        Scales all AU weights (0 = neutral, 1 = the recipe).
    target : (N, 3) array, optional
        A different neutral shape in the rig's topology (e.g. stylised). Default: the rig's own.
    method : {"deformation_transfer", "delta"}
        How to carry the expression onto ``target``; ``delta`` simply adds the deltas.

    Raises
    ------
    ValueError
        Unknown expression, or a recipe shape the rig lacks (the message names it).
    """
    weights = expression_weights(expression, intensity)
    try:
        return pose_weights(rig, weights, target=target, method=method)
    except ValueError as exc:
        if "lacks blendshape" in str(exc):
            raise ValueError(f"{exc} needed by '{expression}'") from None
        raise
