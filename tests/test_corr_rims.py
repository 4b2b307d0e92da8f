"""Rim correspondences: a source boundary loop mapped onto a closed curve on a target surface
without the hole (ICT's eye/mouth openings onto james's eyelid and lip landmark lines)."""

from __future__ import annotations

import numpy as np
import pytest

from appeal.errors import AppealInputError
from meshes import grid
from stimulus_engine.correspondence.datasets import _rim_anchors
from stimulus_engine.correspondence.boundary import rim_to_curve_correspondences
from stimulus_engine.correspondence.curves import surface_polyline
from stimulus_engine.geometry.mesh_ops import boundary_loops


def holed_plane(n: int = 16, a: float = 1.0, b: float = 1.0, rings: int = 3, width: float = 0.5):
    """A flat (z = 0) annulus: ``n`` vertices per ring, the hole an ellipse with half-axes a, b,
    vertex ``k`` of the hole at angle 2πk/n. Faces oriented with +z normals."""
    th = 2 * np.pi * np.arange(n) / n
    v = np.concatenate([np.column_stack([(a + r * width) * np.cos(th), (b + r * width) * np.sin(th), np.zeros(n)])
                        for r in range(rings + 1)])
    f = []
    for r in range(rings):
        for k in range(n):
            i, j = r * n + k, r * n + (k + 1) % n
            f += [[i, j, j + n], [i, j + n, i + n]]
    return v, np.asarray(f)


def flat_grid(half: float = 3.0, n: int = 13):
    return grid(n, lo=-half, hi=half)


SQUARE = np.array([[2.0, 0, 0], [0, 2.0, 0], [-2.0, 0, 0], [0, -2.0, 0]])  # a diamond, CCW


def test_surface_polyline_snaps_and_measures():
    v, f = flat_grid()
    # knots 1 above the plane: the curve is the diamond on the plane
    curve, arc = surface_polyline(v, f, SQUARE + [0, 0, 1.0], samples=4)
    assert curve.shape == (16, 3) and arc.shape == (16,)
    np.testing.assert_allclose(curve[:, 2], 0.0, atol=1e-12)
    np.testing.assert_allclose(curve[::4], SQUARE, atol=1e-12)
    np.testing.assert_allclose(curve[1], [1.5, 0.5, 0.0], atol=1e-12)  # a quarter along the first chord
    side = np.sqrt(8.0)
    np.testing.assert_allclose(arc[::4], side * np.arange(4), atol=1e-12)
    open_curve, open_arc = surface_polyline(v, f, SQUARE, samples=2, closed=False)
    assert open_curve.shape == (7, 3)
    np.testing.assert_allclose(open_arc[-1], 3 * side, atol=1e-12)


def test_surface_polyline_smooth_spline_and_corners():
    v, f = flat_grid()
    curve, _ = surface_polyline(v, f, SQUARE, samples=2, smooth=True)
    np.testing.assert_allclose(curve[::2], SQUARE, atol=1e-12)  # through the knots
    # uniform Catmull-Rom mid-segment: -p0/16 + 9 p1/16 + 9 p2/16 - p3/16 (worked by hand)
    np.testing.assert_allclose(curve[1], [1.25, 1.25, 0.0], atol=1e-12)
    # a corner at every knot: each piece stays on its chord (x + y = 2 on the first)
    sharp, _ = surface_polyline(v, f, SQUARE, samples=4, smooth=True, corners=range(4))
    np.testing.assert_allclose(sharp[:4, 0] + sharp[:4, 1], 2.0, atol=1e-12)
    assert not np.allclose(sharp[1], [1.5, 0.5, 0.0])  # but not evenly spaced like the chords


def test_surface_polyline_rejects_bad_input():
    v, f = flat_grid()
    with pytest.raises(AppealInputError, match="at least 2 points"):
        surface_polyline(v, f, SQUARE[:1])
    with pytest.raises(AppealInputError, match="samples: expected an integer >= 1"):
        surface_polyline(v, f, SQUARE, samples=0)


@pytest.mark.parametrize("reverse", [False, True])
def test_rim_maps_onto_curve_by_arc_length(reverse):
    vs, fs = holed_plane(16)
    vt, ft = flat_grid()
    loop = boundary_loops(fs)[0]
    assert len(loop) == 16
    anchors, knots = np.array([0, 4, 8, 12]), SQUARE
    if reverse:  # the curve given clockwise: anchors follow it the other way round the hole
        anchors, knots = anchors[[0, 3, 2, 1]], knots[[0, 3, 2, 1]]
    c = rim_to_curve_correspondences(vs, fs, vt, ft, anchors, knots)
    assert len(c) == 16
    src = c.source.vertices[:, 0]
    assert sorted(src.tolist()) == list(range(16))
    got = c.target.positions(vt)
    # hole vertex k (angle 2πk/16, equal arcs) lands k/4 of the way along the diamond: between
    # knots k//4 and k//4 + 1 at fraction (k % 4) / 4
    k = src
    expected = SQUARE[k // 4] + ((k % 4) / 4)[:, None] * (SQUARE[(k // 4 + 1) % 4] - SQUARE[k // 4])
    np.testing.assert_allclose(got, expected, atol=1e-12)


def test_rim_uneven_anchors_and_step():
    vs, fs = holed_plane(16)
    vt, ft = flat_grid()
    # anchors at hole vertices 0 and 2 and 8: vertex 1 is half-way between knots 0 and 1,
    # vertices 3..7 share the second chord evenly (6 arcs of the 16-gon)
    knots = np.array([[2.0, 0, 0], [0, 2.0, 0], [-2.0, 0, 0]])
    c = rim_to_curve_correspondences(vs, fs, vt, ft, [0, 2, 8], knots)
    pos = dict(zip(c.source.vertices[:, 0].tolist(), c.target.positions(vt)))
    np.testing.assert_allclose(pos[1], [1.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(pos[5], [0.0, 2.0, 0.0] + 0.5 * (knots[2] - knots[1]), atol=1e-12)
    # every 3rd loop vertex plus the anchors
    c3 = rim_to_curve_correspondences(vs, fs, vt, ft, [0, 2, 8], knots, step=3)
    assert set(c3.source.vertices[:, 0].tolist()) == {0, 3, 6, 9, 12, 15, 2, 8}


def test_rim_errors_are_one_line():
    vs, fs = holed_plane(16)
    vt, ft = flat_grid()
    with pytest.raises(AppealInputError, match="as many source anchors as curve points"):
        rim_to_curve_correspondences(vs, fs, vt, ft, [0, 4, 8], SQUARE)
    with pytest.raises(AppealInputError, match="at least 2 distinct"):
        rim_to_curve_correspondences(vs, fs, vt, ft, [0, 0, 4, 8], SQUARE)
    with pytest.raises(AppealInputError, match="vertex 20 is not on a boundary loop"):
        rim_to_curve_correspondences(vs, fs, vt, ft, [0, 4, 8, 20], SQUARE)
    with pytest.raises(AppealInputError, match="one boundary loop"):
        rim_to_curve_correspondences(vs, fs, vt, ft, [0, 4, 8, 48], SQUARE)  # 48: the outer rim
    with pytest.raises(AppealInputError, match="not in order along their boundary loop"):
        rim_to_curve_correspondences(vs, fs, vt, ft, [0, 8, 4, 12], SQUARE)


def test_rim_anchors_split_the_two_lids():
    # a slit-like opening (half-heights 0.05) whose "upper lid" points lie just below its middle:
    # the plain nearest boundary vertex would put both lids on the lower arc
    vs, fs = holed_plane(16, a=2.0, b=0.05)
    loop = boundary_loops(fs)[0]
    pts = np.array([[2.0, 0, 0], [1.0, -0.02, 0], [-1.0, -0.02, 0], [-2.0, 0, 0], [-1.0, -0.08, 0], [1.0, -0.08, 0]])
    got = _rim_anchors(vs, fs, pts)
    y = vs[got, 1]
    assert got[0] == 0 and got[3] == 8  # the corners: angles 0 and π
    assert (y[[1, 2]] > 0).all() and (y[[4, 5]] < 0).all()
    assert set(got) <= set(loop.tolist())
    # and the anchors are in order along the loop, so they make a valid rim correspondence
    vt, ft = flat_grid()
    rim_to_curve_correspondences(vs, fs, vt, ft, got, pts)
