"""stimulus_engine.geometry.mesh_ops on small meshes, and against trimesh where it has the operation."""

from __future__ import annotations

import numpy as np
import trimesh

from meshes import grid
from stimulus_engine.geometry import mesh_ops
from stimulus_engine.geometry.closest import SurfaceIndex


def test_vertex_normals_are_area_weighted():
    # vertex 0 joins a large triangle facing +z and a small one facing +x
    v = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [0, 0.5, 0], [0, 0, 0.5]], float)
    f = np.array([[0, 1, 2], [0, 3, 4]])
    n = mesh_ops.vertex_normals(v, f)
    cross = 16 * np.array([0, 0, 1.0]) + 0.25 * np.array([1.0, 0, 0])
    np.testing.assert_allclose(n[0], cross / np.linalg.norm(cross), rtol=1e-14)
    # trimesh's vertex normals weight by corner angle (here 90 degrees both): not the same
    angle_weighted = trimesh.Trimesh(v, f, process=False).vertex_normals[0]
    assert abs(angle_weighted[0] - angle_weighted[2]) < 1e-12 and abs(n[0, 0] - n[0, 2]) > 0.9


def test_face_normals_and_areas():
    v, f = grid(4, z=lambda x, y: 0.3 * x * y)
    n, area = mesh_ops.face_normals(v, f)
    m = trimesh.Trimesh(v, f, process=False)
    np.testing.assert_allclose(n, m.face_normals, atol=1e-14)
    np.testing.assert_allclose(area, m.area_faces, rtol=1e-13)
    np.testing.assert_array_equal(SurfaceIndex(v, f).face_normals, n)


def test_edge_face_counts():
    f = np.array([[0, 1, 2], [2, 1, 3], [1, 2, 4]])  # edge 1-2 shared by three triangles
    c = mesh_ops.edge_face_counts(f)
    assert c[0, 0] == c[1, 2] == c[2, 2] == 3  # the edge 1-2, opposite corners 0, 2, 2
    assert (np.sort(c.ravel()) == [1, 1, 1, 1, 1, 1, 3, 3, 3]).all()
    assert (mesh_ops.boundary_edge_mask(f) == (c == 1)).all()


def test_boundary_half_edges_on_messy_faces():
    """Flipped faces, a duplicated face and a non-manifold fan: a half-edge is on the boundary
    exactly when no face runs its reverse (the definition, by set membership)."""
    rng = np.random.default_rng(2)
    _, f = grid(6)
    f = f.copy()
    flip = rng.random(len(f)) < 0.2
    f[flip] = f[flip][:, ::-1]
    f = np.concatenate([f, f[:3], [[0, 1, 40], [1, 0, 41]]])
    he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    have = {(int(a), int(b)) for a, b in he}
    want = np.array([(a, b) not in have for b, a in he])  # reverse (b, a) missing
    np.testing.assert_array_equal(mesh_ops.boundary_half_edges(f), he[want])
    keys = rng.integers(0, 1 << 40, 1000)  # beyond 32 bits: the comparison sort
    np.testing.assert_array_equal(mesh_ops.argsort_keys(keys), np.argsort(keys, kind="stable"))
    small = rng.integers(0, 1 << 31, 5000)
    np.testing.assert_array_equal(mesh_ops.argsort_keys(small), np.argsort(small, kind="stable"))


def test_boundary_loop_follows_the_faces():
    v, f = grid(4)  # faces face +z: the outline runs counter-clockwise seen from +z
    (loop,) = mesh_ops.boundary_loops(f)
    assert len(loop) == 12 and set(loop) == set(np.flatnonzero(mesh_ops.boundary_vertex_mask(f, 16)))
    p = v[loop, :2] - v[loop, :2].mean(axis=0)
    assert np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]) > 0  # signed area
    b, prv, nxt = mesh_ops.boundary_neighbours(f, 16)
    after = dict(zip(loop, np.roll(loop, -1)))
    assert set(b) == set(loop) and all(after[i] == j for i, j in zip(b, nxt))
    assert all(after[i] == j for i, j in zip(prv, b))
    assert mesh_ops.boundary_loops(trimesh.creation.icosphere(1).faces) == []


def test_inconsistently_oriented_edge_is_boundary_on_both_sides():
    f = np.array([[0, 1, 2], [1, 2, 3]])  # both use the half-edge 1 -> 2
    he = {tuple(e) for e in mesh_ops.boundary_half_edges(f).tolist()}
    assert (1, 2) in he and len(he) == 5  # trimesh's edges used once would leave 1-2 out


def test_adjacency_and_vertex_faces_match_trimesh():
    m = trimesh.creation.icosphere(2)
    n = len(m.vertices)
    adj = mesh_ops.vertex_adjacency(m.faces, n)
    want = np.zeros((n, n))
    want[m.edges_unique[:, 0], m.edges_unique[:, 1]] = want[m.edges_unique[:, 1], m.edges_unique[:, 0]] = 1
    np.testing.assert_array_equal(adj.toarray(), want)
    np.testing.assert_array_equal(np.sort(mesh_ops.vertex_faces(m.faces, n), axis=1),
                                  np.sort(m.vertex_faces, axis=1))
