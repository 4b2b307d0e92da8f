"""The shape axis toward a design: each person's own cartoon, and the morphs on the way (thesis §3.4, §6.4).

A design (:class:`~stimulus_engine.characters.design.Design`, in the rig's topology) is of no one in
particular. :func:`own_cartoon` makes it *this* character's cartoon by carrying over the character's
own proportions: the deformation from the rig's mean face to the character's face (its identity:
a longer nose, wider-set eyes, a broader jaw) is transferred onto the design triangle by triangle
(deformation transfer, Sumner & Popović 2004, as the expressions are), so each feature changes
relative to its own stylised size, and applied at ``identity`` strength (1: all of it; 0: the
design as drawn). james's cartoon and Lee Perry-Smith's are then two people in one design language.

:func:`designed_shape` gives the levels between a character (0) and its cartoon (1): a linear morph
of corresponding vertices, part-based when ``eyes_ahead`` > 0 — the eyes (the design's most
salient change) reach their cartoon size before the rest of the face, as a stylisation by an artist
would lead with them. Eyeballs stay spheres at every level.
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.characters.rig import FaceRig

__all__ = ["IDENTITY_NOISE", "own_cartoon", "on_character", "designed_shape", "part_levels", "model_identity"]


def _rigid_eyeballs(rig: FaceRig, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """``after`` with each eyeball moved as a whole (the best similarity from ``before``): a deformation
    carried triangle by triangle would bend the sphere."""
    from stimulus_engine.correspondence import umeyama

    out = np.array(after, np.float64, copy=True)
    for ball in rig.rigid_sets:
        ball = np.asarray(ball)
        out[ball] = umeyama(before[ball], after[ball]).apply(before[ball])
    return out


#: The residual, as a fraction of the mean face's width, that a face's fit by the model's identity
#: components allows for (:func:`model_identity`): a scan-fitted rig holds what no face of the model
#: has (the correspondence's folds, noise, the scan's hair), and a looser fit copied those into the
#: cartoon as wrinkles; this keeps the face's proportions (its length and width, the set of its eyes,
#: nose and jaw). Measured on james and Lee Perry-Smith: identity weights of norm 2.7 and 8.0 (the
#: model's prior expects about 10 for 100 components); at 0.16 they reached 11 and 26, and their
#: cartoons were folded.
IDENTITY_NOISE = 0.5


def model_identity(basis: np.ndarray, mean: np.ndarray, character: np.ndarray, region: np.ndarray,
                   noise: float = IDENTITY_NOISE) -> tuple[np.ndarray, np.ndarray]:
    """The character's face as the face model explains it: ``mean + Σ αₖ bₖ``.

    The character is aligned onto the mean face first (the best similarity over ``region``: no head
    pose or size in the identity), then the weights α are the maximum a posteriori fit of the
    model's components on ``region`` under their standard-normal prior (the ICT model's identity
    weights are drawn from N(0, 1)) with Gaussian residuals of ``noise`` times the mean face's width
    per coordinate (:data:`IDENTITY_NOISE`).

    Parameters
    ----------
    basis : (K, N, 3) array
        The model's identity components as deltas from ``mean``
        (:func:`~stimulus_engine.characters.ict.ict_identity_basis`).
    mean, character : (N, 3) arrays
    region : int array
        The vertices that were fitted to the person (a scan's face).
    noise : float
        The residual allowed, a fraction of the mean face's width.

    Returns
    -------
    face : (N, 3) array
        The model's face of the character, in the mean's frame.
    weights : (K,) array
    """
    from stimulus_engine.correspondence import umeyama

    region = np.asarray(region)
    aligned = umeyama(character[region], mean[region]).apply(np.asarray(character, np.float64))
    A = basis[:, region].reshape(len(basis), -1).T
    y = (aligned - mean)[region].ravel()
    width = float(np.ptp(mean[region, 0]))
    w = np.linalg.solve(A.T @ A + (noise * width) ** 2 * np.eye(len(basis)), A.T @ y)
    return mean + np.tensordot(w, basis, axes=1), w


def own_cartoon(rig: FaceRig, mean: np.ndarray, character: np.ndarray, design: np.ndarray,
                identity: float = 1.0) -> np.ndarray:
    """The design as this character's cartoon (module docstring).

    Parameters
    ----------
    rig : FaceRig
        The topology (faces, eyeballs) the three shapes share, with its lid shapes (the cartoon's lids
        are opened again to the design's eye height over width where the character's eyes narrowed them).
    mean, character, design : (N, 3) arrays
        The rig's mean face, the character's face and the design, in one frame.
    identity : float
        How much of the character's own proportions the cartoon takes (0 … 1, or beyond to
        caricature them).

    Returns
    -------
    (N, 3) array
    """
    from stimulus_engine.characters.design import feature_sizes, open_lids
    from stimulus_engine.characters.expressions import deformation_transfer

    design = np.asarray(design, np.float64)
    if identity == 0:
        return design.copy()
    moved = deformation_transfer(mean, character, design, rig.faces)
    moved = _rigid_eyeballs(rig, design, moved)
    out = design + identity * (moved - design)
    # a person's narrower eyes narrow the cartoon's: its lids opened again as far as the design's
    return open_lids(rig, out, feature_sizes(rig, design))[0]


def on_character(rig: FaceRig, cartoon: np.ndarray, reference: np.ndarray, character: np.ndarray,
                 region: np.ndarray) -> np.ndarray:
    """The cartoon in the character's own frame, standing on the character's own neck.

    A cartoon is made in the mean face's frame (the design's, and the model's face of the character);
    the best similarity over ``region`` from ``reference`` (the character's face in that frame, or
    the mean face) to ``character`` moves it onto the character's head, and below the jaw
    (:func:`~stimulus_engine.characters.design.neck_weights`) it keeps the character's neck: the body
    a grid draws under every level is bound to that neck, and a neck moving with the head (a fifth of
    Lee Perry-Smith's head height, measured) pulled the garment's collar and shoulders with it.

    Parameters
    ----------
    rig : FaceRig
    cartoon, reference, character : (N, 3) arrays
    region : int array
        The vertices the frames are matched on (the face).

    Returns
    -------
    (N, 3) array
    """
    from stimulus_engine.characters.design import neck_weights
    from stimulus_engine.correspondence import umeyama

    region = np.asarray(region)
    character = np.asarray(character, np.float64)
    placed = umeyama(np.asarray(reference, np.float64)[region], character[region]).apply(np.asarray(cartoon, np.float64))
    w = neck_weights(rig, character)[:, None]
    return placed * (1 - w) + character * w


def part_levels(rig: FaceRig, level: float, eyes_ahead: float = 0.0) -> np.ndarray:
    """Each vertex's morph weight at ``level``: ``level`` itself, and for the eyes (eyeballs, lids and
    the skin around them, blended out smoothly) ``min(1, level · (1 + eyes_ahead))``."""
    from stimulus_engine.characters.design import FEATURE_BLOCKS, feature_falloff

    t = np.full(len(rig.vertices), float(level))
    if eyes_ahead <= 0 or level in (0.0, 1.0):
        return t
    lm = rig.landmark_points()
    ahead = min(1.0, float(level) * (1 + eyes_ahead))
    for name, centre, (a, b), r1, r2 in FEATURE_BLOCKS:
        if not name.startswith("eye_"):
            continue
        size = float(np.linalg.norm(lm[a] - lm[b]))
        c = np.mean([lm[k] for k in centre], axis=0)
        w = feature_falloff(np.linalg.norm(rig.vertices - c, axis=1), r1 * size, r2 * size)
        w[np.asarray(rig.landmarks[name])] = 1.0
        t = np.maximum(t, level + (ahead - level) * w)
    return t


def designed_shape(rig: FaceRig, character: np.ndarray, cartoon: np.ndarray, level: float,
                   eyes_ahead: float = 0.0) -> np.ndarray:
    """The character's shape ``level`` of the way (0 … 1) to its cartoon (module docstring).

    Parameters
    ----------
    rig : FaceRig
        The topology.
    character, cartoon : (N, 3) arrays
        The realistic end (the character's neutral) and the cartoon end (:func:`own_cartoon`).
    level : float
        0 (the character) … 1 (its cartoon).
    eyes_ahead : float
        How far the eyes lead (0: one linear morph).

    Returns
    -------
    (N, 3) array
    """
    if not 0.0 <= float(level) <= 1.0:
        raise ValueError(f"a designed shape level must be within 0..1 (got {level})")
    character, cartoon = np.asarray(character, np.float64), np.asarray(cartoon, np.float64)
    t = part_levels(rig, level, eyes_ahead)[:, None]
    out = character * (1 - t) + cartoon * t
    return _rigid_eyeballs(rig, character, out) if eyes_ahead > 0 else out
