"""Eyes centred in the openings of their lids, as a face looking ahead shows them.

A face looking into the lens shows about as much white on either side of each iris (London's neutral
photographs put the iris 0.42-0.55 of the way from the outer corner to the inner one,
:mod:`stimulus_engine.audit.iris`). The ICT Face Model's eyes rest turned outward and its lids'
openings are centred on the pupils so turned: seen from the front, an eyeball's centre (where the
pupil is when the eye looks straight ahead, as when aimed at the lens) lies 0.57 of the way from the
opening's outer end to its inner one, and ICT-rigged faces looking into the lens looked cross-eyed
(Lee Perry-Smith's irises measured 0.62-0.63 in the image). :func:`visible_span` finds where, along the horizontal
line through an eyeball's centre, the eyeball is the frontmost surface (seen along -z, orthographic);
:func:`centring_shift` is the sideways move that puts a point (the pupil looking ahead) at
:data:`PUPIL_IN_OPENING` of that span; :func:`eye_shifts` finds it for each eyeball of a rig's neutral
shape, and :func:`centre_eyes` moves the eyeballs of a pose by it. The grid does so for every image
whose eyes are aimed (``render: {gaze: camera}`` or a point: :func:`stimulus_engine.grid.prepare.rig_geometry`),
before aiming; the rig itself keeps ICT's placement, which its hair and bust are fitted by (moved
at load, the eyes 5 % further apart set the bust 5 % larger and its collar below a scan's border).
"""

from __future__ import annotations

import numpy as np

__all__ = ["PUPIL_IN_OPENING", "centre_eyes", "centring_shift", "eye_shifts", "front_depth", "visible_span"]

#: Where the pupil goes between the opening's outer (0) and inner (1) ends, seen from the front.
PUPIL_IN_OPENING: float = 0.5


def front_depth(vertices: np.ndarray, faces: np.ndarray, y: float, xs: np.ndarray) -> np.ndarray:
    """The largest z of the surface ``faces`` over each point ``(x, y)`` of ``xs`` (seen along -z),
    ``-inf`` where no triangle covers it: each triangle's crossing of the line ``Y = y`` is a
    segment, its depth linear along it."""
    tri = np.asarray(vertices, np.float64)[np.asarray(faces)]          # (n, 3, 3)
    ty = tri[..., 1]
    crosses = (ty.min(axis=1) <= y) & (ty.max(axis=1) >= y) & (np.ptp(ty, axis=1) > 0)
    tri = tri[crosses]
    out = np.full(len(xs), -np.inf)
    if not len(tri):
        return out
    ends = []
    for i, j in ((0, 1), (1, 2), (2, 0)):  # where each edge meets the line (NaN where it does not)
        a, b = tri[:, i], tri[:, j]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (y - a[:, 1]) / (b[:, 1] - a[:, 1])
            hit = (t >= 0) & (t <= 1) & np.isfinite(t)
            p = a + np.where(hit, t, 0.0)[:, None] * (b - a)
        ends.append(np.where(hit[:, None], p[:, [0, 2]], np.nan))
    ends = np.stack(ends, axis=1)                                       # (n, 3 edges, (x, z))
    x0, x1 = np.nanmin(ends[..., 0], axis=1), np.nanmax(ends[..., 0], axis=1)
    z_at_x0 = np.array([e[np.nanargmin(e[:, 0]), 1] for e in ends])
    z_at_x1 = np.array([e[np.nanargmax(e[:, 0]), 1] for e in ends])
    x = np.asarray(xs, np.float64)[:, None]
    inside = (x >= x0) & (x <= x1)
    w = np.where(x1 > x0, (x - x0) / np.where(x1 > x0, x1 - x0, 1.0), 0.5)
    z = np.where(inside, z_at_x0 + w * (z_at_x1 - z_at_x0), -np.inf)
    return z.max(axis=1)


def visible_span(vertices: np.ndarray, ball_faces: np.ndarray, cover_faces: np.ndarray, centre: np.ndarray,
                 radius: float, samples: int = 600) -> tuple[float, float] | None:
    """The x-interval, on the horizontal line through ``centre``, where the eyeball is in front of
    the skin (``cover_faces``), around the centre; None where it is covered there."""
    xs = centre[0] + np.linspace(-1.6 * radius, 1.6 * radius, samples)
    seen = front_depth(vertices, ball_faces, centre[1], xs) > front_depth(vertices, cover_faces, centre[1], xs)
    mid = int(np.argmin(np.abs(xs - centre[0])))
    if not seen[mid]:
        return None
    lo = mid
    while lo > 0 and seen[lo - 1]:
        lo -= 1
    hi = mid
    while hi < samples - 1 and seen[hi + 1]:
        hi += 1
    return float(xs[lo]), float(xs[hi])


def centring_shift(span: tuple[float, float], pupil_x: float, midline_x: float,
                   target: float = PUPIL_IN_OPENING) -> float:
    """The move along x that puts ``pupil_x`` at ``target`` of ``span`` from its outer end (the end
    away from ``midline_x``, the face's middle)."""
    lo, hi = span
    outer, inner = (lo, hi) if abs(lo - midline_x) > abs(hi - midline_x) else (hi, lo)
    return float(outer + target * (inner - outer) - pupil_x)


def eye_shifts(rig, neutral: np.ndarray, rounds: int = 2) -> list[tuple[np.ndarray, float]]:
    """For each eyeball of ``rig`` (its ``rigid_sets`` drawn as the ``eye`` part), its vertices and
    the sideways move (along x) that centres it in its opening in the shape ``neutral``
    (:func:`visible_span`, :func:`centring_shift`; ``rounds`` times, the opening seen around the
    moved ball). Empty for a rig without eyeballs or skin."""
    from stimulus_engine.parts.eyes import fit_sphere

    if "eye" not in rig.part_names or "skin" not in rig.part_names:
        return []
    v = np.array(neutral, np.float64)
    cover = rig.faces[rig.face_part == rig.part_names.index("skin")]
    eye_faces = rig.faces[rig.face_part == rig.part_names.index("eye")]
    midline = float(np.median(v[np.unique(cover), 0]))
    out = []
    for ball in rig.rigid_sets:
        ball = np.asarray(ball)
        faces = eye_faces[np.isin(eye_faces, ball).all(axis=1)]
        if not len(faces):
            continue
        total = 0.0
        for _ in range(rounds):
            centre, radius = fit_sphere(v[ball])
            span = visible_span(v, faces, cover, centre, radius)
            if span is None:
                break
            dx = centring_shift(span, float(centre[0]), midline)
            v[ball, 0] += dx
            total += dx
        out.append((ball, total))
    return out


def centre_eyes(vertices: np.ndarray, shifts: list[tuple[np.ndarray, float]]) -> np.ndarray:
    """A copy of ``vertices`` with each eyeball moved sideways by its :func:`eye_shifts`."""
    v = np.array(vertices, copy=True)
    for ball, dx in shifts:
        v[ball, 0] += dx
    return v
