"""Eyeballs centred in their lids' openings (stimulus_engine.characters.eye_openings, the ICT rig)."""

from __future__ import annotations

import numpy as np
import trimesh

from stimulus_engine.characters.eye_openings import centring_shift, front_depth, visible_span


def _plate_with_hole(hole: tuple[float, float], z: float = 2.0) -> trimesh.Trimesh:
    """A flat plate at depth ``z`` over x, y in [-3, 3], with a square hole spanning ``hole`` in x
    and [-0.5, 0.5] in y."""
    xs = np.array([-3.0, hole[0], hole[1], 3.0])
    ys = np.array([-3.0, -0.5, 0.5, 3.0])
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    v = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)])
    faces = []
    for i in range(3):
        for j in range(3):
            if i == 1 and j == 1:
                continue  # the hole
            a, b, c, d = i * 4 + j, (i + 1) * 4 + j, (i + 1) * 4 + j + 1, i * 4 + j + 1
            faces += [(a, b, c), (a, c, d)]
    return trimesh.Trimesh(v, np.array(faces), process=False)


def test_front_depth_is_the_nearest_surface_along_the_line():
    plate = _plate_with_hole((-1.0, 0.5))
    xs = np.array([-2.0, 0.0, 2.0])
    z = front_depth(plate.vertices, plate.faces, 0.0, xs)
    assert z[0] == 2.0 and z[2] == 2.0 and z[1] == -np.inf  # the hole shows nothing of the plate


def test_the_ball_is_seen_through_the_hole_only():
    plate = _plate_with_hole((-1.0, 0.5))
    ball = trimesh.creation.icosphere(subdivisions=4, radius=1.5)
    v = np.vstack([plate.vertices, ball.vertices])
    ball_faces = ball.faces + len(plate.vertices)
    lo, hi = visible_span(v, ball_faces, plate.faces, np.zeros(3), 1.5)
    assert abs(lo + 1.0) < 0.02 and abs(hi - 0.5) < 0.02


def test_the_shift_puts_the_pupil_midway_from_the_outer_end():
    # a right eye (x < 0, the face's middle at x = 0): outer end -4, inner -2
    assert np.isclose(centring_shift((-4.0, -2.0), -2.6, 0.0), -0.4)
    # a left eye mirrored
    assert np.isclose(centring_shift((2.0, 4.0), 2.6, 0.0), 0.4)
    assert np.isclose(centring_shift((2.0, 4.0), 2.6, 0.0, target=0.3), 2.0 + 0.7 * 2.0 - 2.6)


def test_ict_eyes_look_ahead_from_the_middle_of_their_openings(shared_data):
    """The ICT rig's eyeballs, looking straight ahead, sit 0.53-0.60 of the way across their
    openings from the outer end (aimed at the lens they looked crossed); moved by their
    ``eye_shifts`` they sit midway, sideways only, the lids where they were."""
    from stimulus_engine.characters.eye_openings import centre_eyes, eye_shifts
    from stimulus_engine.characters.ict import load_ict_rig
    from stimulus_engine.parts.eyes import fit_sphere

    rig = load_ict_rig(shared_data / "meshes" / "ict-facekit", "identity001", shapes=[])
    shifts = eye_shifts(rig, rig.vertices)
    assert len(shifts) == 2 and all(0.1 < abs(dx) < 0.25 for _, dx in shifts)  # 1-2.5 mm
    moved = centre_eyes(rig.vertices, shifts)
    changed = np.flatnonzero(np.any(moved != rig.vertices, axis=1))
    assert set(changed) <= set(np.concatenate([b for b, _ in shifts]))
    assert np.array_equal(moved[:, 1:], rig.vertices[:, 1:])  # sideways only
    skin = rig.faces[rig.face_part == rig.part_names.index("skin")]
    eye = rig.faces[rig.face_part == rig.part_names.index("eye")]
    for v, lo_frac, hi_frac in ((rig.vertices, 0.53, 0.6), (moved, 0.48, 0.52)):
        for ball, _ in shifts:
            c, r = fit_sphere(v[ball])
            lo, hi = visible_span(v, eye[np.isin(eye, ball).all(axis=1)], skin, c, r)
            outer, inner = (lo, hi) if abs(lo) > abs(hi) else (hi, lo)
            assert lo_frac < (c[0] - outer) / (inner - outer) < hi_frac
