"""Hair strands for the path tracer (stimulus_engine.render.hair_strands): grown over the hair
mesh where its texture has hair, combed towards the hairline, the same on every pose."""

from __future__ import annotations

import numpy as np
import pytest

from stimulus_engine.geometry.closest import SurfaceIndex
from stimulus_engine.render.hair_strands import StrandSpec, combing_directions, grow_strands

MM = 10.0  # millimetres per unit: a 100 mm dome


def _dome(n: int = 24):
    """An open hemisphere of radius 5 (its rim at y = 0 is the hairline), UVs from (x, z), with
    the render mesh's seam: one column of vertices repeated."""
    th, ph = np.meshgrid(np.linspace(np.pi / 2 / n, np.pi / 2, n), np.linspace(0, 2 * np.pi, 2 * n + 1))
    v = 5 * np.stack([np.sin(th) * np.cos(ph), np.cos(th), np.sin(th) * np.sin(ph)], -1).reshape(-1, 3)
    idx = np.arange(v.shape[0]).reshape(2 * n + 1, n)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    pole = len(v)
    v = np.vstack([v, [[0.0, 5.0, 0.0]]])
    cap = np.stack([np.full(2 * n, pole), idx[1:, 0], idx[:-1, 0]], -1)
    f = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3), cap])
    uv = (v[:, [0, 2]] / 10.0) + 0.5
    return v, f, uv


def test_strands_comb_towards_the_hairline_and_stay_on_the_hair():
    v, f, uv = _dome()
    alpha = np.ones((64, 64), bool)
    spec = StrandSpec(count=3000, length_mm=(20.0, 30.0), layer_mm=1.0)
    pts, sizes, radius = grow_strands(v, f, uv, alpha, MM, spec)
    assert len(sizes) > 2500 and sizes.sum() == len(pts) == len(radius) and sizes.min() >= 2
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    # every strand runs down the dome, towards its rim
    drop = np.array([pts[s + n - 1, 1] - pts[s, 1] for s, n in zip(starts, sizes)])
    assert (drop < 0).mean() > 0.98
    # each segment about length / segments long (along the surface), none longer
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    inner = np.ones(len(pts) - 1, bool)
    inner[np.cumsum(sizes)[:-1] - 1] = False
    assert seg[inner].max() < 1.2 * 30.0 / MM / spec.segments
    # on the hair mesh, up to the layer's thickness above it
    d = SurfaceIndex(v, f).distance(pts.astype(float))
    assert d.max() <= spec.layer_mm / MM + 1e-3
    # the radius tapers from root to tip
    assert np.all(radius[starts] == pytest.approx(spec.radius_mm / MM))
    assert np.all(radius[starts + sizes - 1] == pytest.approx(spec.tip_ratio * spec.radius_mm / MM))


def test_strands_grow_only_where_the_texture_has_hair():
    v, f, uv = _dome()
    alpha = np.ones((64, 64), bool)
    alpha[:, 32:] = False  # u > 0.5: x > 0 is bare
    pts, sizes, _ = grow_strands(v, f, uv, alpha, MM, StrandSpec(count=3000, layer_mm=0.0))
    assert len(sizes) < 1800  # about half the roots dropped
    assert pts[:, 0].max() < 0.2  # no strand point on the bare half (a texel's width of slack)


def test_the_same_seed_gives_the_same_strands_on_every_pose():
    v, f, uv = _dome()
    alpha = np.ones((64, 64), bool)
    spec = StrandSpec(count=2000)
    a = grow_strands(v, f, uv, alpha, MM, spec)
    b = grow_strands(v, f, uv, alpha, MM, spec)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    moved = grow_strands(v + [1.0, 2.0, 3.0], f, uv, alpha, MM, spec)
    starts = np.concatenate([[0], np.cumsum(a[1])[:-1]])
    assert len(moved[1]) == len(a[1])
    np.testing.assert_allclose(moved[0][starts], a[0][starts] + np.float32([1.0, 2.0, 3.0]), atol=1e-4)  # roots
    # the paths too, but for the odd strand that passes the crown, where the combing has no
    # direction and rounding picks the way down
    assert (np.abs(moved[0] - a[0] - np.float32([1.0, 2.0, 3.0])).max(axis=1) < 1e-4).mean() > 0.99
    other = grow_strands(v, f, uv, alpha, MM, StrandSpec(count=2000, seed=1))
    assert not np.array_equal(a[0][:100], other[0][:100])


def test_combing_needs_a_hairline():
    v, f, _ = _dome()
    comb, dist = combing_directions(v, f)
    rim = np.abs(v[:, 1]) < 0.2
    assert dist[rim].max() < 0.2 and np.allclose(np.linalg.norm(comb[~rim & (dist > 0.5)], axis=1), 1)
    closed = np.concatenate([f, f[:, ::-1] + 0])  # every edge used twice: no border
    with pytest.raises(ValueError, match="no open border"):
        combing_directions(v, closed)


def test_strand_tangents_are_the_combing_direction_on_every_render_vertex():
    """The render mesh repeats vertices along UV seams: each copy gets its position's direction,
    unit length, in the surface; at the crown (no combing direction) a direction in the surface."""
    from stimulus_engine.geometry.mesh_ops import vertex_normals
    from stimulus_engine.render.hair_strands import strand_tangents

    v, f, _ = _dome()
    t = strand_tangents(v, f)
    assert t.shape == v.shape and np.allclose(np.linalg.norm(t, axis=1), 1)
    assert np.abs(np.einsum("ij,ij->i", t, vertex_normals(v, f))).max() < 0.2
    # the seam's copies (first and last column of the dome) agree
    n = 24
    idx = np.arange(len(v) - 1).reshape(2 * n + 1, n)
    assert np.allclose(t[idx[0]], t[idx[-1]])
    # away from the pole they point down the dome, towards the hairline
    body = (v[:, 1] < 4.0) & (v[:, 1] > 0.5)
    assert (t[body, 1] < 0).all()
