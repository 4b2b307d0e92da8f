"""Morph-space PCA: pure maths on small arrays with exact expectations."""

from __future__ import annotations

import numpy as np
import pytest

from appeal.errors import AppealInputError
from stimulus_engine.morphpca import (
    build_model,
    caricature_vector,
    compute_flow,
    deserialise,
    fix_foldovers,
    jacobian_det,
    pca,
    render_morph,
    serialise,
)
from stimulus_engine.morphpca.faceframe import align_relative_vector, faceframe_affine, similarity_from_eyes
from stimulus_engine.morphpca.flow import grid, invert_displacement, warp_image
from stimulus_engine.morphpca.mimicry import component_correlations, mimicry_measures
from stimulus_engine.morphpca.morphvec import TEXTURE_SCALE


def test_serialise_is_columnwise_rgb_then_xy():
    h, w = 2, 3
    tex = np.arange(h * w * 3, dtype=np.float32).reshape(h, w, 3) / 100.0
    warp = np.arange(h * w * 2, dtype=np.float32).reshape(h, w, 2) + 1000
    v = serialise(tex, warp)
    assert v.shape == (h * w * 5,)
    # R channel column by column: (0,0), (1,0), (0,1), (1,1), (0,2), (1,2)
    r = tex[..., 0] * TEXTURE_SCALE
    np.testing.assert_allclose(v[:6], [r[0, 0], r[1, 0], r[0, 1], r[1, 1], r[0, 2], r[1, 2]], rtol=1e-6)
    np.testing.assert_allclose(v[12:18], tex[..., 2].T.ravel() * TEXTURE_SCALE, rtol=1e-6)  # B
    np.testing.assert_array_equal(v[18:24], warp[..., 0].T.ravel())  # x
    np.testing.assert_array_equal(v[24:], warp[..., 1].T.ravel())  # y
    t2, w2 = deserialise(v, (h, w))
    np.testing.assert_allclose(t2, tex, atol=1e-6)
    np.testing.assert_array_equal(w2, warp)
    batch = serialise(np.stack([tex, tex]), np.stack([warp, warp]))
    assert batch.shape == (2, h * w * 5) and np.array_equal(batch[1], v)


def test_pca_matches_numpy_svd():
    rng = np.random.default_rng(0)
    x = rng.standard_normal((12, 300)).astype(np.float32) @ np.diag(np.linspace(3, 0.1, 300)).astype(np.float32)
    x -= x.mean(axis=0)
    comps, var, total = pca(x, n_components=5)
    _, s, vt = np.linalg.svd(x.astype(np.float64), full_matrices=False)
    np.testing.assert_allclose(var, s[:5] ** 2 / 11, rtol=1e-4)
    np.testing.assert_allclose(np.abs(comps @ vt[:5].T), np.eye(5), atol=1e-3)
    assert total == pytest.approx(float((x.astype(np.float64) ** 2).sum() / 11), rel=1e-5)
    k_var = pca(x, variance=0.5)[0].shape[0]
    frac = np.cumsum(s**2) / np.sum(s**2)
    assert k_var == int(np.searchsorted(frac, 0.5) + 1)
    assert pca(x)[0].shape[0] == 11  # at most n - 1 components


def test_flow_recovers_known_smooth_warp():
    rng = np.random.default_rng(1)
    from scipy.ndimage import gaussian_filter

    img = gaussian_filter(rng.random((96, 80)), 2.0).astype(np.float32)
    img = (img - img.min()) / np.ptp(img)
    g = grid(96, 80)
    true = np.dstack([2.5 * np.sin(g[..., 1] / 15.0), 1.5 * np.cos(g[..., 0] / 12.0)]).astype(np.float32)
    moved = warp_image(img, g - true)  # moved(x + true) ≈ img(x) for smooth small warps
    for backend in ("dis", "farneback"):
        f = compute_flow(img, moved, backend)
        err = np.abs(f - true)[10:-10, 10:-10].mean()
        assert err < 0.35, (backend, err)


def test_invert_displacement_roundtrip():
    g = grid(40, 50)
    d = np.dstack([3 * np.sin(g[..., 1] / 8), 2 * np.cos(g[..., 0] / 9)]).astype(np.float32)
    e = invert_displacement(d, 20)
    from stimulus_engine.morphpca.flow import sample_field

    back = e + sample_field(d, g + e)  # p + e(p) + d(p + e(p)) == p
    assert np.abs(back)[5:-5, 5:-5].max() < 0.02


def test_fix_foldovers_makes_warp_one_to_one():
    g = grid(60, 60)
    bump = np.exp(-((g[..., 0] - 30) ** 2 + (g[..., 1] - 30) ** 2) / (2 * 4.0**2))
    d = np.dstack([25 * bump, np.zeros_like(bump)]).astype(np.float32)  # a fold: slope >> 1
    assert jacobian_det(d).min() < 0
    fixed = fix_foldovers(d)
    assert jacobian_det(fixed).min() >= 0.1
    untouched = fix_foldovers(0.1 * d)  # already fold-free: unchanged
    np.testing.assert_array_equal(untouched, (0.1 * d).astype(np.float32))


def test_render_morph_has_no_holes_and_identity_warp_is_exact():
    rng = np.random.default_rng(2)
    tex = rng.random((30, 40, 3)).astype(np.float32)
    g = grid(30, 40)
    np.testing.assert_allclose(render_morph(tex, g), tex, atol=1e-6)
    # a strong expansion (and a fold) still fills every pixel with texture values
    bump = np.exp(-((g[..., 0] - 20) ** 2 + (g[..., 1] - 15) ** 2) / 30.0)
    warp = g + np.dstack([30 * bump, 10 * bump]).astype(np.float32)
    out = render_morph(tex, warp)
    assert np.isfinite(out).all() and out.min() >= 0 and out.max() <= 1
    assert out.shape == tex.shape


def test_faceframe_affine_maps_points_and_rel_vector_moves():
    src = np.array([[10.0, 10], [30, 10], [20, 30]])
    dst = np.array([[12.0, 14], [34, 14], [23, 36]])
    a = faceframe_affine(src, dst)
    np.testing.assert_allclose(np.c_[src, np.ones(3)] @ a.T, dst, atol=1e-5)
    with pytest.raises(AppealInputError, match="collinear"):
        faceframe_affine([[0, 0], [1, 1], [2, 2]], dst)
    m = similarity_from_eyes([[0, 0], [10, 0]], [[5, 5], [5, 25]])  # rotate 90°, scale 2
    np.testing.assert_allclose(m, [[0, -2, 5], [2, 0, 5]], atol=1e-12)
    # a uniform relative displacement (1, 0) scaled by 1.1 in x becomes (1.1, 0) everywhere inside
    size = (40, 40)
    tex = np.zeros(size + (3,), np.float32)
    disp = np.zeros(size + (2,), np.float32)
    disp[..., 0] = 1.0
    moved = align_relative_vector(serialise(tex, disp), size, src, size, dst)
    _, d2 = deserialise(moved, size)
    assert d2[20, 20, 0] == pytest.approx(1.1, abs=1e-4) and d2[20, 20, 1] == pytest.approx(0.0, abs=1e-4)


def test_caricature_scales_only_the_warp():
    size = (2, 2)
    v = np.arange(20, dtype=np.float32)
    c = caricature_vector(v, size, warp_factor=2.0, texture_factor=1.0)[0]
    np.testing.assert_array_equal(c[:12], v[:12])
    np.testing.assert_array_equal(c[12:], 2 * v[12:])


def test_mimicry_measures_exact():
    a = np.array([[1.0, 0.0, 2.0], [0.0, 1.0, 0.0]])
    b = np.array([[1.0, 2.0, 2.0], [0.0, 1.0, 0.0]])
    df = mimicry_measures(a, b, variances=np.array([1.0, 4.0, 1.0]))
    assert df["euclidean"].tolist() == [2.0, 0.0]
    assert df["normalised"].tolist() == [1.0, 0.0]
    assert df["correlation"][1] == pytest.approx(1.0)
    cc = component_correlations(np.array([[1.0, 2], [2, 4], [3, 5]]), np.array([[2.0, 0], [4, 1], [6, 3]]))
    assert cc["correlation"][0] == pytest.approx(1.0)
    with pytest.raises(AppealInputError, match="differ in shape"):
        mimicry_measures(a, b[:1])


def test_build_model_input_errors():
    img = np.zeros((20, 16, 3), np.float32)
    with pytest.raises(AppealInputError, match=r"at least 2 images \(got 1\)"):
        build_model([img])
    with pytest.raises(AppealInputError, match=r"images\[1\]: image shape \(20, 18, 3\) differs"):
        build_model([img, np.zeros((20, 18, 3), np.float32)])
    with pytest.raises(AppealInputError, match=r"images\[1\]: image shape \(20, 16\) differs"):
        build_model([img, np.zeros((20, 16), np.float32)])
    with pytest.raises(AppealInputError, match="keypoints: expected 3 points"):
        build_model([img, img], faceframes=np.zeros((1, 3, 2)))


def test_gram_and_pca_loadings_match_plain_products():
    from stimulus_engine.morphpca.pca import gram, pca_with_loadings

    rng = np.random.default_rng(3)
    x = rng.standard_normal((9, 500)).astype(np.float32)
    x -= x.mean(axis=0)
    np.testing.assert_allclose(gram(x), x.astype(np.float64) @ x.T.astype(np.float64), rtol=1e-5, atol=1e-3)
    comps, var, _, lo = pca_with_loadings(x, n_components=4)
    np.testing.assert_allclose(lo, x @ comps.T, atol=1e-4)  # loadings from the eigenvectors = projections
    np.testing.assert_allclose(lo.var(axis=0, ddof=1), var, rtol=1e-4)
    assert all(abs(r.max()) >= abs(r.min()) for r in comps)  # sign rule: largest |value| positive


def test_jacobian_det_equals_numpy_gradient_and_inversion_buffers():
    rng = np.random.default_rng(4)
    d = rng.standard_normal((13, 17, 2)).astype(np.float32)
    dxdy, dxdx = np.gradient(d[..., 0])
    dydy, dydx = np.gradient(d[..., 1])
    np.testing.assert_allclose(jacobian_det(d), (1 + dxdx) * (1 + dydy) - dxdy * dydx, rtol=1e-6, atol=1e-6)
    g = grid(13, 17)
    smooth = 0.3 * np.dstack([np.sin(g[..., 1] / 4), np.cos(g[..., 0] / 5)]).astype(np.float32)
    bufs = tuple(np.full((13, 17, 2), np.nan, np.float32) for _ in range(3))
    np.testing.assert_array_equal(invert_displacement(smooth, 7, buffers=bufs), invert_displacement(smooth, 7))


def test_half_resolution_render_matches_full_resolution_inversion():
    from stimulus_engine.morphpca.flow import sample_field

    rng = np.random.default_rng(5)
    from scipy.ndimage import gaussian_filter

    tex = gaussian_filter(rng.random((64, 48, 3)), (1.5, 1.5, 0)).astype(np.float32)
    g = grid(64, 48)
    d = np.dstack([2.0 * np.sin(g[..., 1] / 9), 1.5 * np.cos(g[..., 0] / 7)]).astype(np.float32)
    np.testing.assert_allclose(render_morph(tex, g), tex, atol=1e-6)  # identity stays exact at half resolution
    e = -d
    for _ in range(20):  # full-resolution fixed point, by hand
        e = -sample_field(d, g + e)
    ref = np.clip(warp_image(tex, g + e), 0, 1)
    assert np.abs(render_morph(tex, g + d) - ref)[4:-4, 4:-4].max() < 0.02


def test_faceframe_on_mean_inverts_at_the_points():
    from stimulus_engine.morphpca.flow import sample_field
    from stimulus_engine.morphpca.pca import faceframe_on_mean

    g = grid(50, 40)
    d = np.dstack([1.5 * np.sin(g[..., 1] / 8), np.cos(g[..., 0] / 6)]).astype(np.float32)
    frames = np.array([[[12.0, 20], [28, 20], [20, 35]]] * 2)
    pts = faceframe_on_mean(np.stack([g + d, g + d]), frames)
    # each point q on the mean shape moves to the image keypoint: q + d(q) = p
    moved = pts + sample_field(d, pts.astype(np.float32).reshape(1, -1, 2)).reshape(-1, 2)
    np.testing.assert_allclose(moved, frames[0], atol=1e-3)
