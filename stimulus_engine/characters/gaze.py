"""Where the eyes look: each eye's line of sight, and eyeballs turned to look at a point.

A rig marks each eye with two landmark vertex sets (:data:`~stimulus_engine.characters.rig.LANDMARK_NAMES`):
``eye_right`` / ``eye_left``, the eyeball, whose fitted sphere's centre is the eye's centre of
rotation, and ``pupil_right`` / ``pupil_left``, a ring of eyeball vertices about the gaze axis
(:func:`pupil_ring`), whose mean lies on that axis. Both sets belong to the topology, so the
line of sight follows the eyeball through every expression, stylised shape and mesh
correspondence without any bookkeeping: it is always the ray from the ball's centre through
the pupil ring's mean (:func:`lines_of_sight`).

Expressions move eyeball vertices too (deformation transfer does not keep them rigid, and a
scan's drawn eyeball follows the rig's by a best-fitting similarity), so a posed character's
eyes drift: on the james scan the irises sat 0.56 / 0.45 of the way between the eye corners in
neutral and crossed in anger. :func:`aim_eyes` turns each eyeball rigidly about its centre, by
the smallest rotation, until its line of sight passes through a target (the grid's camera by
default, so the face looks at the viewer, as the people in a photograph set look into the lens).
"""

from __future__ import annotations

import numpy as np

from stimulus_engine.geometry.rotation import rotation_onto

__all__ = ["SIDES", "aim_eyes", "lines_of_sight", "pupil_ring", "sight_misses"]

#: The two eyes, as landmark names say them (the subject's right first).
SIDES: tuple[str, str] = ("right", "left")


def pupil_ring(vertices: np.ndarray, ball: np.ndarray, centre: np.ndarray, axis: np.ndarray,
               angle_deg: float = 12.0) -> np.ndarray:
    """The eyeball vertices within ``angle_deg`` of its gaze axis (at least the 6 nearest to it).

    Parameters
    ----------
    vertices : (N, 3) array
    ball : int array
        The eyeball's vertices.
    centre, axis : (3,) arrays
        Its centre and gaze direction.

    Returns
    -------
    int array
        Vertex indices, sorted: a ring about the pupil whose mean lies on the axis.
    """
    ball = np.asarray(ball, np.int64)
    d = np.asarray(vertices, np.float64)[ball] - np.asarray(centre, np.float64)
    cos = d @ (np.asarray(axis, np.float64) / np.linalg.norm(axis)) / np.maximum(np.linalg.norm(d, axis=1), 1e-12)
    near = cos >= np.cos(np.radians(angle_deg))
    if near.sum() < 6:
        near = np.zeros(len(ball), bool)
        near[np.argsort(-cos)[:6]] = True
    return np.sort(ball[near])


def _centre(points: np.ndarray) -> np.ndarray:
    from stimulus_engine.parts.eyes import fit_sphere

    return fit_sphere(points)[0]


def lines_of_sight(landmarks: dict[str, np.ndarray], vertices: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each eye's centre of rotation and unit gaze direction on ``vertices``.

    Parameters
    ----------
    landmarks : dict
        A rig's landmark vertex sets (``eye_right``, ``pupil_right``, ``eye_left``, ``pupil_left``).
    vertices : (N, 3) array
        Any pose of the rig's topology.

    Returns
    -------
    dict of side to (centre, direction)
        Only the sides the rig marks.
    """
    v = np.asarray(vertices, np.float64)
    out = {}
    for side in SIDES:
        ball, pupil = landmarks.get(f"eye_{side}"), landmarks.get(f"pupil_{side}")
        if ball is None or pupil is None or not len(ball) or not len(pupil):
            continue
        c = _centre(v[ball])
        a = v[pupil].mean(axis=0) - c
        out[side] = (c, a / np.linalg.norm(a))
    return out


def aim_eyes(landmarks: dict[str, np.ndarray], vertices: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``vertices`` with each eyeball turned about its centre to look at ``target``.

    Parameters
    ----------
    landmarks : dict
        The rig's landmark vertex sets (see :func:`lines_of_sight`); a rig without them is
        returned unchanged.
    vertices : (N, 3) array
        A pose of the rig.
    target : (3,) array
        The point both lines of sight pass through (e.g. the camera's position).

    Returns
    -------
    (N, 3) array
        A copy; only the eyeballs' vertices move (rigidly, by the smallest rotation).

    Examples
    --------
    >>> d = np.random.default_rng(0).normal(size=(200, 3)); d /= np.linalg.norm(d, axis=1, keepdims=True)
    >>> ball = np.arange(200); pupil = pupil_ring(d, ball, np.zeros(3), np.array([0.0, 0.0, 1.0]))
    >>> lm = {"eye_right": ball, "pupil_right": pupil}
    >>> v = aim_eyes(lm, d, np.array([10.0, 0.0, 10.0]))
    >>> c, a = lines_of_sight(lm, v)["right"]
    >>> np.round(a, 6).tolist()
    [0.707107, 0.0, 0.707107]
    """
    out = np.array(vertices, np.float64, copy=True)
    target = np.asarray(target, np.float64)
    for side, (c, a) in lines_of_sight(landmarks, out).items():
        want = target - c
        r = rotation_onto(a, want / np.linalg.norm(want))
        ball = landmarks[f"eye_{side}"]
        out[ball] = c + (out[ball] - c) @ r.T
    return out


def sight_misses(landmarks: dict[str, np.ndarray], vertices: np.ndarray, target: np.ndarray) -> dict[str, float]:
    """How far each eye's line of sight (a ray from its centre) passes from ``target``."""
    target = np.asarray(target, np.float64)
    out = {}
    for side, (c, a) in lines_of_sight(landmarks, vertices).items():
        t = max(float((target - c) @ a), 0.0)
        out[side] = float(np.linalg.norm(target - (c + t * a)))
    return out
