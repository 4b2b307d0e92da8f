"""Artist-free shape stylisation: move a realistic face continuously toward neotenic proportions.

:func:`stylise` applies smooth displacement fields anchored at a rig's landmarks, each scaled by
``level`` in [0, 1] (0 = the input, 1 = the full cartoon), so one scan gives a whole
stylisation axis (thesis ch. 5: shape levels 1…5; §7.3 and Fig. 7.10 list the neotenic
features that change along it). The operations, in order:

1. **eyes larger** — each eye region (eyeball, lids, socket) scales about the eye centre by
   ``1 + eye_scale·level`` inside a core radius, fading smoothly to no change further out
   (eyeballs scale rigidly, so they stay spheres);
2. **nose smaller** and 3. **mouth smaller** — the same kind of field with a factor < 1;
4. **jaw shorter / chin up** — points below the nose move up in proportion to their distance
   below it, and the lower face narrows slightly;
5. **cranium / forehead larger** — points above the eyes move up and out (eyes sit lower in
   the head, a neotenic cue);
6. **smoother surface** — Taubin smoothing of the skin (λ/μ steps that do not shrink), number of
   steps proportional to the level.

Every field is continuous in space and in ``level``; level 0 returns the input unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from stimulus_engine.characters.rig import FaceRig
from stimulus_engine.geometry.ramps import smoothstep

__all__ = ["StyliseParams", "stylise", "stylise_rig"]


@dataclass(frozen=True)
class StyliseParams:
    """Strength of each neotenic change at level 1 (fractions of the feature's size)."""

    eye_scale: float = 0.30  # 0.45 until the continuum was measured: Lee Perry-Smith's cartoon then lay
    # as far from his realistic face as from james's (dlib descriptors; 0.30: 0.69 vs 0.75)
    nose_scale: float = -0.35
    mouth_scale: float = -0.30
    jaw_shorten: float = 0.18
    cranium_grow: float = 0.12
    smooth_steps: int = 12


def _radial_scale(v: np.ndarray, centre: np.ndarray, factor: float, r0: float, r1: float) -> np.ndarray:
    """Scale about ``centre`` by ``factor`` inside ``r0``, blending to identity at ``r1``."""
    d = v - centre
    r = np.linalg.norm(d, axis=1)
    w = 1 - smoothstep((r - r0) / max(r1 - r0, 1e-9))
    return v + d * ((factor - 1) * w)[:, None]


def _laplacian(faces: np.ndarray, n: int) -> sp.csr_matrix:
    """Uniform graph Laplacian ``L = I − D⁻¹A`` (rows of isolated vertices are zero)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.concatenate([e, e[:, ::-1]])
    A = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    A.data[:] = 1.0
    deg = np.asarray(A.sum(axis=1)).ravel()
    inv = np.where(deg > 0, 1.0 / np.maximum(deg, 1), 0.0)
    return sp.identity(n, format="csr") - sp.diags(inv) @ A


def _taubin(v: np.ndarray, faces: np.ndarray, idx: np.ndarray, steps: float, lam: float = 0.5,
            mu: float = -0.53) -> np.ndarray:
    """Taubin-smooth the vertices ``idx`` (others fixed) for a possibly fractional number of steps."""
    if steps <= 0 or idx.size == 0:
        return v
    sel = np.zeros(len(v), bool)
    sel[idx] = True
    f = faces[sel[faces].all(axis=1)]
    L = _laplacian(f, len(v))
    out = v.copy()
    whole = int(np.floor(steps))
    frac = steps - whole
    for k in range(whole + (1 if frac > 0 else 0)):
        s = 1.0 if k < whole else frac
        for c in (lam, mu):
            delta = -(L @ out)
            out[sel] += s * c * delta[sel]
    return out


def stylise(rig: FaceRig, level: float, params: StyliseParams | None = None,
            vertices: np.ndarray | None = None) -> np.ndarray:
    """Vertices of ``rig`` moved ``level`` of the way toward neotenic/cartoon proportions.

    Parameters
    ----------
    rig : FaceRig
        Supplies topology, landmarks, eyeball sets and skin vertices.
    level : float
        0 (unchanged) … 1 (full stylisation); values in between interpolate every effect.
    params : StyliseParams, optional
        Strengths at level 1.
    vertices : (N, 3) array, optional
        Start shape (default: the rig's neutral).

    Returns
    -------
    (N, 3) array
    """
    if not 0.0 <= float(level) <= 1.0:
        raise ValueError(f"stylisation level must be within 0..1 (got {level})")
    p = params or StyliseParams()
    v = np.array(rig.vertices if vertices is None else vertices, dtype=np.float64)
    if level == 0:
        return v
    lm = rig.landmark_points(v)
    eye_r, eye_l = lm["eye_right"], lm["eye_left"]
    iod = float(np.linalg.norm(eye_l - eye_r))  # inter-ocular distance sets every radius
    eye_w = float(np.linalg.norm(lm["eye_right_outer"] - lm["eye_right_inner"]))
    # 1. eyes (eyeballs rigidly: their own field value at the centre)
    f_eye = 1 + p.eye_scale * level
    for centre, ball in ((eye_r, rig.landmarks["eye_right"]), (eye_l, rig.landmarks["eye_left"])):
        before = v[ball].copy()
        v = _radial_scale(v, centre, f_eye, 0.62 * eye_w, 0.62 * eye_w + 0.38 * iod)
        if ball.size:
            v[ball] = centre + (before - centre) * f_eye
    # 2. nose
    nose_c = (lm["nose_tip"] + lm["subnasale"] + lm["nose_right"] + lm["nose_left"]) / 4
    nose_len = float(np.linalg.norm(lm["nasion"] - lm["subnasale"]))
    v = _radial_scale(v, nose_c, 1 + p.nose_scale * level, 0.45 * nose_len, 1.1 * nose_len)
    # 3. mouth
    mouth_c = (lm["mouth_right"] + lm["mouth_left"]) / 2
    mouth_w = float(np.linalg.norm(lm["mouth_left"] - lm["mouth_right"]))
    v = _radial_scale(v, mouth_c, 1 + p.mouth_scale * level, 0.55 * mouth_w, 1.05 * mouth_w)
    # 4. jaw: compress below the subnasale vertically, narrow slightly
    y0 = float(lm["subnasale"][1])
    chin_drop = y0 - float(lm["chin"][1])
    below = np.clip((y0 - v[:, 1]) / max(chin_drop, 1e-9), 0, None)
    t = smoothstep(below) * np.minimum(below, 1.0) + np.maximum(below - 1, 0)
    v[:, 1] += p.jaw_shorten * level * chin_drop * t
    v[:, 0] *= 1 - 0.08 * level * smoothstep(below)
    # 5. cranium: above the eyes, move up (and outwards a little)
    ye = float((eye_r[1] + eye_l[1]) / 2)
    above = np.clip((v[:, 1] - ye) / iod, 0, None)
    v[:, 1] += p.cranium_grow * level * iod * above
    v[:, [0, 2]] *= (1 + 0.05 * level * smoothstep(above))[:, None]
    # 6. smoother skin
    return _taubin(v, rig.faces, rig.skin, p.smooth_steps * level)


def stylise_rig(rig: FaceRig, level: float, params: StyliseParams | None = None) -> FaceRig:
    """A copy of ``rig`` whose neutral is :func:`stylise` d; blendshapes stay the source's deltas.

    Use :func:`stimulus_engine.characters.expressions.apply_expression` with ``target=`` (deformation
    transfer) rather than adding those deltas to the stylised neutral.
    """
    return rig.with_vertices(stylise(rig, level, params), name=f"{rig.name}_s{level:g}")
