"""Correspondence maths on small meshes: Laplacian, areas, Umeyama, closest points, landmarks."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import trimesh

from appeal.errors import AppealInputError
from meshes import grid
from stimulus_engine.correspondence import (
    Correspondences,
    SurfacePoints,
    boundary_correspondences,
    parse_pairs,
    parse_points,
    reorder_landmarks,
    umeyama,
)
from stimulus_engine.geometry.closest import SurfaceIndex, closest_point_on_triangles
from stimulus_engine.correspondence.landmark_sets import landmark_orderings
from stimulus_engine.correspondence.laplacian import (
    bilaplacian,
    cotangent_laplacian,
    fairing_operator,
    voronoi_areas,
)
from stimulus_engine.correspondence.solve import ReusableSolver, available_backends
from stimulus_engine.geometry.mesh_ops import boundary_loops


def test_cotangent_laplacian_right_triangle():
    # right isosceles triangle: angles 90 (cot 0), 45, 45 (cot 1)
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    L = cotangent_laplacian(v, np.array([[0, 1, 2]])).toarray()
    # edge (1,2) is opposite the right angle: weight 0; edges (0,1), (0,2) opposite 45 deg: 1/2
    np.testing.assert_allclose(L, [[-1, 0.5, 0.5], [0.5, -0.5, 0], [0.5, 0, -0.5]], atol=1e-12)


def test_laplacian_of_linear_function_vanishes_inside():
    v, f = grid(7)
    L = cotangent_laplacian(v, f)
    lin = 2 * v[:, 0] - 3 * v[:, 1] + 1
    interior = (v[:, 0] > 0) & (v[:, 0] < 1) & (v[:, 1] > 0) & (v[:, 1] < 1)
    np.testing.assert_allclose((L @ lin)[interior], 0, atol=1e-12)
    # fairing operator: a flat grid (straight boundary sides) has zero energy except at corners
    op = fairing_operator(v, f)
    r = op @ v
    corners = [0, 6, 42, 48]
    mask = np.ones(len(v), bool)
    mask[corners] = False
    np.testing.assert_allclose(r[mask], 0, atol=1e-12)


def test_voronoi_areas_sum_to_total_area():
    v, f = grid(6, z=lambda x, y: 0.3 * np.sin(3 * x) * y)
    m = trimesh.Trimesh(v, f, process=False)
    np.testing.assert_allclose(voronoi_areas(v, f).sum(), m.area, rtol=1e-12)


def test_bilaplacian_is_symmetric_psd():
    v, f = grid(5, z=lambda x, y: x * y)
    q = bilaplacian(fairing_operator(v, f), voronoi_areas(v, f))
    assert abs(q - q.T).max() < 1e-9
    assert np.linalg.eigvalsh(q.toarray()).min() > -1e-8


def test_umeyama_recovers_similarity():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(20, 3))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    y = 2.5 * x @ q.T + [1, -2, 3]
    s = umeyama(x, y)
    assert s.scale == pytest.approx(2.5)
    np.testing.assert_allclose(s.rotation, q, atol=1e-10)
    np.testing.assert_allclose(s.apply(x), y, atol=1e-10)
    np.testing.assert_allclose(s.inverse().apply(y), x, atol=1e-10)


def test_umeyama_errors():
    with pytest.raises(AppealInputError, match="at least 3"):
        umeyama(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(AppealInputError, match="collinear"):
        umeyama(np.outer(np.arange(4), [1, 0, 0]), np.outer(np.arange(4), [0, 1, 0]))


def test_closest_point_on_triangle_regions():
    a, b, c = np.array([[0, 0, 0.0]]), np.array([[1, 0, 0.0]]), np.array([[0, 1, 0.0]])
    pts = np.array([[0.2, 0.2, 1.0], [-1, -1, 0], [2, -0.5, 0], [1, 1, 0], [0.5, -1, 0]])
    bary = closest_point_on_triangles(pts, *(np.repeat(t, len(pts), 0) for t in (a, b, c)))
    want = np.array([[0.6, 0.2, 0.2], [1, 0, 0], [0, 1, 0], [0, 0.5, 0.5], [0.5, 0.5, 0]])
    np.testing.assert_allclose(bary, want, atol=1e-12)


def test_projection_kernel_matches_trimesh_on_random_triangles():
    from stimulus_engine.geometry.closest import project_to_triangles

    rng = np.random.default_rng(3)
    tri = rng.normal(size=(2000, 3, 3))
    tri[:5, 2] = tri[:5, 1]  # a few degenerate (collinear) triangles
    p = rng.normal(size=(2000, 3)) * 2
    want = trimesh.triangles.closest_point(tri, p)
    ab, ac = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    dots = [np.einsum("ij,ij->i", x, y) for x, y in ((ab, ab), (ab, ac), (ac, ac))]
    v, w, d2 = project_to_triangles(p - tri[:, 0], ab, ac, *dots)
    got = tri[:, 0] + v[:, None] * ab + w[:, None] * ac
    ok = slice(5, None)  # trimesh's answer on degenerate triangles is not defined the same way
    np.testing.assert_allclose(got[ok], want[ok], atol=1e-9)
    np.testing.assert_allclose(np.sqrt(d2), np.linalg.norm(got - p, axis=1), atol=1e-7)
    assert ((v >= -1e-12) & (w >= -1e-12) & (v + w <= 1 + 1e-12)).all()


def test_surface_index_matches_trimesh():
    m = trimesh.creation.icosphere(3)
    rng = np.random.default_rng(0)
    q = rng.normal(size=(300, 3)) * 1.3
    res = SurfaceIndex(m.vertices, m.faces).query(q)
    _, d, _ = trimesh.proximity.closest_point(m, q)
    np.testing.assert_allclose(res.distance, d, atol=1e-9)


def test_compiled_hierarchy_is_exact():
    """The compiled BVH finds the exact closest point (trimesh's brute force) on a sphere, for
    points near, inside and far away, and on a soup of random and degenerate triangles; the
    NumPy candidate path agrees near the surface."""
    from stimulus_engine.geometry import triangle_bvh

    if not triangle_bvh.compiled:
        pytest.skip("numba is not installed (the 'fast' extra)")
    rng = np.random.default_rng(5)
    m = trimesh.creation.icosphere(4)
    q = np.concatenate([m.vertices * rng.uniform(0.95, 1.05, (len(m.vertices), 1)),
                        rng.normal(size=(2000, 3)) * 0.3, rng.normal(size=(2000, 3)) * 20])
    got = SurfaceIndex(m.vertices, m.faces).query(q)
    assert SurfaceIndex(m.vertices, m.faces).compiled
    _, d, _ = trimesh.proximity.closest_point(m, q)
    # trimesh's own answer misses the closest triangle by up to 5e-7 on some points
    np.testing.assert_allclose(got.distance, d, atol=1e-6)
    assert (got.distance <= d + 1e-12).all()
    # a hint (any triangle, near or not) changes where the search starts, not what it finds
    hinted = SurfaceIndex(m.vertices, m.faces).query(q, hint=rng.integers(-1, len(m.faces), len(q)))
    np.testing.assert_array_equal(hinted.face, got.face)
    pick = rng.choice(len(q), 400, replace=False)
    np.testing.assert_allclose(got.distance[pick], _brute_distance(m.vertices[m.faces], q[pick]), atol=1e-12)
    near = slice(0, len(m.vertices))
    numpy_path = SurfaceIndex(m.vertices, m.faces, compiled=False).query(q[near])
    np.testing.assert_allclose(numpy_path.distance, got.distance[near], atol=1e-12)
    # a soup: overlapping random triangles, some collinear or collapsed to a point
    tri = rng.normal(size=(500, 3, 3))
    tri[:20, 2] = tri[:20, 1]
    tri[20:30, 1:] = tri[20:30, :1]
    soup = trimesh.Trimesh(tri.reshape(-1, 3), np.arange(1500).reshape(-1, 3), process=False)
    p = rng.normal(size=(3000, 3)) * 2
    res = SurfaceIndex(soup.vertices, soup.faces).query(p)
    np.testing.assert_allclose(res.distance, _brute_distance(tri, p), atol=1e-9)


def _brute_distance(tri: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Distance of each point to the nearest of all triangles (F, 3, 3), one triangle at a time."""
    best = np.full(len(p), np.inf)
    for t in tri:
        bary = closest_point_on_triangles(p, *np.repeat(t[None], len(p), axis=0).transpose(1, 0, 2))
        best = np.minimum(best, np.linalg.norm(bary @ t - p, axis=1))
    return best


def test_boundary_flag():
    v, f = grid(5)
    res = SurfaceIndex(v, f).query(np.array([[-0.5, 0.5, 0.0], [0.5, 0.5, 0.3]]))
    assert res.on_boundary.tolist() == [True, False]


def test_parse_points_kinds_and_errors():
    v, f = grid(4)
    m = trimesh.Trimesh(v, f, process=False)
    sp_ = parse_points([3, [0.5, 0.5, 0.001], {"face": 2, "bary": [0.2, 0.3, 0.5]}], m)
    np.testing.assert_allclose(sp_.positions(v)[0], v[3])
    np.testing.assert_allclose(sp_.positions(v)[1], [0.5, 0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(sp_.positions(v)[2], 0.2 * v[f[2, 0]] + 0.3 * v[f[2, 1]] + 0.5 * v[f[2, 2]])
    C = sp_.matrix(len(v))
    np.testing.assert_allclose(C @ v, sp_.positions(v))
    with pytest.raises(AppealInputError, match=r"landmarks\[0\]: vertex index 99 is out of range"):
        parse_points([99], m)
    with pytest.raises(AppealInputError, match=r"off the surface"):
        parse_points([[0.5, 0.5, 3.0]], m)
    with pytest.raises(AppealInputError, match="bary: expected 3 non-negative weights summing to 1"):
        parse_points([{"face": 0, "bary": [0.5, 0.6, 0.1]}], m)
    with pytest.raises(AppealInputError, match="same number of points"):
        parse_pairs({"source": [0, 1, 2], "target": [0, 1]}, m, m)
    with pytest.raises(AppealInputError, match="keys 'source' and 'target'"):
        parse_pairs({"src": [0]}, m, m)


def test_boundary_correspondences_by_arc_length():
    # a square ring of 4x4 source vertices against a 7x7 target of the same square
    vs, fs = grid(4)
    vt, ft = grid(7)
    loops = boundary_loops(fs)
    assert len(loops) == 1 and len(loops[0]) == 12
    corr = boundary_correspondences(vs, fs, vt, ft, [(0, 0)])
    # equal relative arc length on equal squares: every source boundary vertex lands on itself
    np.testing.assert_allclose(corr.target.positions(vt), corr.source.positions(vs), atol=1e-12)
    with pytest.raises(AppealInputError, match="not on a boundary loop"):
        boundary_correspondences(vs, fs, vt, ft, [(5, 0)])


def test_landmark_orderings_round_trip():
    pts = np.arange(68 * 3, dtype=float).reshape(68, 3)
    ib = reorder_landmarks(pts, "menpo_ljson", "ibug68")
    # menpo's 'leye' (points 17-22) are iBUG 36-41; its 'leyebrow' (29-33) are iBUG 17-21
    np.testing.assert_array_equal(ib[36], pts[17])
    np.testing.assert_array_equal(ib[17], pts[29])
    np.testing.assert_array_equal(reorder_landmarks(ib, "ibug68", "menpo_ljson"), pts)
    assert sorted(landmark_orderings()["menpo_ljson"]["to_ibug"]) == list(range(68))
    with pytest.raises(AppealInputError, match="expected 68 points"):
        reorder_landmarks(pts[:10], "ibug68")
    with pytest.raises(AppealInputError, match="unknown"):
        reorder_landmarks(pts, "dlib5")


def test_reusable_solver_counts():
    s = ReusableSolver()
    h = sp.diags([2.0, 3.0, 4.0]).tocsc()
    k = s.make_key(1.0, np.array([True, False]))
    x1 = s.solve(k, lambda: h, np.ones((3, 1)))
    x2 = s.solve(k, lambda: h, 2 * np.ones((3, 1)))
    np.testing.assert_allclose(x2, 2 * x1)
    s.solve(s.make_key(2.0), lambda: 2 * h, np.ones((3, 1)))
    assert (s.factorizations, s.reuses) == (2, 1)


def test_correspondences_length_check():
    with pytest.raises(AppealInputError, match="same number"):
        Correspondences(SurfacePoints.from_vertices([0, 1]), SurfacePoints.from_vertices([0]))


def _spd_grid_system(n=12):
    from stimulus_engine.correspondence.laplacian import bilaplacian, cotangent_laplacian, voronoi_areas

    v, f = grid(n, z=lambda x, y: 0.1 * np.sin(3 * x) * np.cos(2 * y))
    lap = cotangent_laplacian(v, f)
    h = (bilaplacian(lap, voronoi_areas(v, f)) + sp.identity(len(v))).tocsr()
    return v, f, h


def test_nested_dissection_is_a_permutation_and_solves_the_same():
    from stimulus_engine.correspondence.ordering import nested_dissection
    from stimulus_engine.correspondence.solve import factorize

    v, _, h = _spd_grid_system()
    order = nested_dissection(h, v, leaf=8)
    np.testing.assert_array_equal(np.sort(order), np.arange(len(v)))
    b = np.random.default_rng(0).normal(size=(len(v), 3))
    x_nd = factorize(h, order).solve(b)
    x_mmd = factorize(h).solve(b)
    np.testing.assert_allclose(h @ x_nd, b, atol=1e-9)
    np.testing.assert_allclose(x_nd, x_mmd, atol=1e-9)
    # a factor's ordering can be handed to the next factorisation of the same pattern
    f1 = factorize(h)
    np.testing.assert_allclose(factorize(2 * h, f1.ordering).solve(b), x_mmd / 2, atol=1e-9)


def test_coupled_ordering_puts_the_coupling_last_and_solves_the_same():
    """Two grids tied at a few vertices (the joint fairing's structure): each grid by nested
    dissection, the tied unknowns last; the solution is the same as with the default order."""
    from stimulus_engine.correspondence.ordering import coupled_ordering
    from stimulus_engine.correspondence.solve import factorize

    v, _, h = _spd_grid_system()
    n = len(v)
    tie = np.arange(0, n, 7)  # vertex i of the first grid tied to vertex i of the second
    c = sp.csr_matrix((np.ones(len(tie)), (np.arange(len(tie)), tie)), shape=(len(tie), n))
    d = sp.hstack([c, -c]).tocsr()
    big = (sp.block_diag([h, h]) + 10.0 * (d.T @ d)).tocsr()
    coords = np.vstack([v, v + [0.0, 0.0, 0.01]])
    order = coupled_ordering(big, coords, n, n + tie, leaf=8)
    np.testing.assert_array_equal(np.sort(order), np.arange(2 * n))
    np.testing.assert_array_equal(np.sort(order[-len(tie):]), n + tie)
    np.testing.assert_array_equal(np.sort(order[:n]), np.arange(n))  # the first block first, whole
    b = np.random.default_rng(1).normal(size=(2 * n, 3))
    for backend in available_backends():
        x = factorize(big, order, backend=backend).solve(b)
        np.testing.assert_allclose(x, factorize(big, backend=backend).solve(b), atol=1e-9)


def test_pcg_on_a_nearby_factorisation():
    from stimulus_engine.correspondence.solve import factorize, pcg

    v, _, h = _spd_grid_system()
    near = (h + sp.diags(np.linspace(0.0, 0.05, len(v)))).tocsr()  # a slightly different matrix
    b = np.random.default_rng(1).normal(size=(len(v), 3))
    x, it, ok = pcg(near, b, factorize(h).solve, rtol=1e-12, maxiter=50)
    assert ok and 0 < it < 20
    np.testing.assert_allclose(near @ x, b, atol=1e-9)
    # far from the preconditioner: gives up early instead of iterating to maxiter
    _, it_far, ok_far = pcg((h + 50 * sp.identity(len(v))).tocsr(), b, factorize(h).solve, rtol=1e-14, maxiter=6)
    assert not ok_far and it_far <= 6
    s = ReusableSolver(backend="superlu")
    s.solve(s.make_key(0), lambda: h, b)
    x2 = s.solve(s.make_key(1), lambda: near, b, near=True)
    assert (s.factorizations, s.pcg_solves) == (1, 1)
    np.testing.assert_allclose(near @ x2, b, atol=1e-7)


@pytest.mark.parametrize("backend", available_backends())
def test_direct_solvers_agree_and_refactorise(backend):
    from stimulus_engine.correspondence.solve import factorize

    v, _, h = _spd_grid_system()
    b = np.random.default_rng(2).normal(size=(len(v), 3))
    f = factorize(h, backend=backend)
    assert f.backend == backend
    x = f.solve(b)
    np.testing.assert_allclose(h @ x, b, atol=1e-9)
    np.testing.assert_allclose(f.solve(b[:, 0]), x[:, 0], atol=1e-12)  # one right-hand side
    # columns solved together (CHOLMOD: its sparse-right-hand-side solve), zero columns too
    b0 = b.copy()
    b0[:, 1] = 0.0
    np.testing.assert_allclose(f.solve(b0), np.stack([f.solve(c) for c in b0.T], axis=1), atol=1e-12)
    assert (f.solve(np.zeros_like(b)) == 0).all()
    # same pattern, new values: refactorised (CHOLMOD: numerically, in place)
    h2 = (h + sp.diags(np.linspace(1.0, 2.0, len(v)))).tocsr()
    f2 = f.refactor(h2)
    np.testing.assert_allclose(h2 @ f2.solve(b), b, atol=1e-9)
    # another pattern: a new factor
    h3 = (h + sp.diags(np.ones(len(v) - 1), 1) + sp.diags(np.ones(len(v) - 1), -1)).tocsr()
    np.testing.assert_allclose(h3 @ f2.refactor(h3).solve(b), b, atol=1e-9)
    # the solver that reuses factorisations refactorises a near matrix exactly with CHOLMOD
    s = ReusableSolver(backend=backend)
    s.solve(s.make_key(0), lambda: h, b)
    x2 = s.solve(s.make_key(1), lambda: h2, b, near=True)
    np.testing.assert_allclose(h2 @ x2, b, atol=1e-7)
    assert s.factorizations + s.pcg_solves == 2


def test_sparse_solver_choice(monkeypatch):
    from stimulus_engine.correspondence.solve import default_backend

    monkeypatch.setenv("APPEAL_SPARSE_SOLVER", "superlu")
    assert default_backend() == "superlu"
    monkeypatch.setenv("APPEAL_SPARSE_SOLVER", "umfpack")
    with pytest.raises(AppealInputError, match="APPEAL_SPARSE_SOLVER: unknown sparse solver 'umfpack'; expected one of"):
        default_backend()
    monkeypatch.delenv("APPEAL_SPARSE_SOLVER")
    assert default_backend() == available_backends()[0]


def test_cholmod_not_positive_definite():
    if "cholmod" not in available_backends():
        pytest.skip("cvxopt is not installed")
    from stimulus_engine.correspondence.solve import factorize

    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        factorize(sp.diags([1.0, -1.0, 2.0]).tocsc(), backend="cholmod")


def test_untangle_removes_a_fold_on_a_plane():
    from stimulus_engine.correspondence.metrics import flipped_triangles
    from stimulus_engine.correspondence.untangle import untangle

    v, f = grid(9)
    folded = v.copy()
    folded[40, :2] += [0.2, 0.17]  # the centre vertex pulled across its 1-ring
    assert flipped_triangles(folded, f, v).sum() > 0
    res = untangle(folded, f, v, lambda p: p * [1.0, 1.0, 0.0])
    assert res.folds_before > 0 and res.folds_after == 0
    assert flipped_triangles(res.vertices, f, v).sum() == 0
    np.testing.assert_allclose(res.vertices[:, 2], 0.0, atol=1e-12)
    # only the patch around the fold moved
    np.testing.assert_array_equal(res.vertices[~res.moved], folded[~res.moved])
    assert res.moved.sum() < len(v) / 2
    # nothing to do on an unfolded mesh
    same = untangle(v, f, v, lambda p: p)
    assert same.rounds == 0 and not same.moved.any()


def test_untangle_membrane_where_the_target_lacks_the_geometry():
    """A patch the target squeezes onto a line (as james's closed lips squeeze ICT's inner
    lips). With the on-surface rounds switched off (max_rounds=0; on this small plane they can
    slide the vertices out of the disc), the membrane fallback alone leaves only vertices of
    the squeezed disc off the surface, everything else on it, and no bad triangle."""
    from stimulus_engine.correspondence.metrics import degenerate_triangles, flipped_triangles
    from stimulus_engine.correspondence.untangle import untangle

    v, f = grid(13)

    def project(p):
        q = p * [1.0, 1.0, 0.0]
        inside = np.linalg.norm(q[:, :2] - 0.5, axis=1) < 0.2
        q[inside, 1] = 0.5  # the disc has no surface of its own: only its middle line
        return q

    squeezed = project(v)
    bad = lambda x: flipped_triangles(x, f, v) | degenerate_triangles(x, f, v)  # noqa: E731
    assert bad(squeezed).sum() > 0
    res = untangle(squeezed, f, v, project, max_rounds=0)
    assert res.rounds > 0 and res.folds_after == 0 and not bad(res.vertices).any()
    off = np.zeros(len(v), dtype=bool)
    off[res.off_surface] = True
    # some vertices stay off, all of them relaxed ones around the disc, fewer than were relaxed
    assert off.any() and (off <= res.moved).all() and off.sum() < res.moved.sum()
    assert np.linalg.norm(v[off, :2] - 0.5, axis=1).max() < 0.4
    np.testing.assert_allclose(project(res.vertices[~off]), res.vertices[~off], atol=1e-12)
    # without the fallback the squeeze stays
    stuck = untangle(squeezed, f, v, project, max_rounds=0, membrane_rounds=0)
    assert bad(stuck.vertices).any() and len(stuck.off_surface) == 0


@pytest.mark.parametrize("backend", available_backends())
def test_bilaplacian_map_on_a_fixed_pattern(backend):
    from stimulus_engine.correspondence.laplacian import bilaplacian, bilaplacian_map, fairing_operator, voronoi_areas
    from stimulus_engine.correspondence.solve import factorize

    v, f = grid(10, z=lambda x, y: 0.1 * np.sin(3 * x) * np.cos(2 * y))
    op = fairing_operator(v, f)
    extra = sp.coo_matrix(([0.5, 0.5, 1.0, 1.0], ([0, 99, 0, 99], [99, 0, 0, 99])), shape=(100, 100)).tocsr()
    pattern, m = bilaplacian_map(op, extra)
    areas = voronoi_areas(v, f)
    pos, val = pattern.positions(extra)
    # the positions recorded while the pattern was built are those a lookup finds
    np.testing.assert_array_equal(pattern.matrix_positions[0][0], pos)
    np.testing.assert_array_equal(pattern.matrix_positions[0][1], val)
    values = m @ (1.0 / areas)
    values[pos] += val
    values[pattern.diagonal] += 1e-3
    h = pattern.matrix(values)
    expected = bilaplacian(op, areas) + extra + 1e-3 * sp.identity(100)
    assert abs(h.full() - expected).max() < 1e-12 * abs(expected).max()
    b = np.random.default_rng(3).normal(size=(100, 3))
    fac = factorize(h, backend=backend)
    np.testing.assert_allclose(expected @ fac.solve(b), b, atol=1e-8)
    # new values on the same pattern: a numeric refactorisation
    np.testing.assert_allclose(2 * (expected @ fac.refactor(pattern.matrix(2 * values)).solve(b)), b, atol=1e-8)
