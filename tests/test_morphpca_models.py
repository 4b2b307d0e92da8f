"""Morph-space PCA models end to end on synthetic faces with exact ground truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from appeal.errors import AppealInputError
from stimulus_engine.morphpca import (
    Reconstructor,
    build_avatar,
    build_model,
    load_model,
    naive_transfer,
    project_expression,
    psnr,
    random_identity,
    render_synthetic_face,
    save_model,
    ssim,
    synthetic_set,
)
from stimulus_engine.morphpca.synthetic import draw_weights


@pytest.fixture(scope="module")
def two_models():
    a, b = random_identity(11), random_identity(12)
    ia, _, ka = synthetic_set(a, 24, 0)
    ib, _, kb = synthetic_set(b, 24, 1)
    return a, b, build_model(ia, faceframes=ka), build_model(ib, faceframes=kb)


def test_heldout_reconstruction_and_faceframe(two_models):
    a, _, ma, _ = two_models
    test, _, _ = synthetic_set(a, 4, 7, include_neutral=False)
    rec = ma.reconstruct(ma.project(ma.encode(test)))
    values = [psnr(x, y) for x, y in zip(test, rec)]
    assert np.mean(values) > 30.0, values
    # the faceframe on the mean image is where the generator put the eyes and philtrum (neutral)
    _, kp = render_synthetic_face(a)
    assert np.abs(ma.faceframe - kp).max() < 3.0
    # training loadings reproduce the training reconstruction exactly
    np.testing.assert_allclose(ma.project(ma.vectors(ma.loadings[:3])), ma.loadings[:3], atol=1e-2)


def test_projection_beats_naive_transfer(two_models):
    a, b, ma, mb = two_models
    w = draw_weights(4, 5)
    w[:, 1] = np.maximum(w[:, 1], 0.5)  # visible mouth movement in every test face
    src = np.stack([render_synthetic_face(a, x)[0] for x in w])
    truth = np.stack([render_synthetic_face(b, x)[0] for x in w])
    proj = project_expression(src, ma, mb)  # warp-weighted (the default texture weight)
    base = naive_transfer(src, ma, mb)
    s_proj = np.mean([ssim(x, y) for x, y in zip(proj.images, truth)])
    s_naive = np.mean([ssim(x, y) for x, y in zip(base.images, truth)])
    assert s_proj > s_naive + 0.005
    # the paper's plain inner product (texture_weight 1) gives other, valid loadings
    paper = project_expression(src, ma, mb, texture_weight=1.0)
    assert not np.allclose(paper.loadings, proj.loadings)


def test_save_load_roundtrip_and_versions(two_models, tmp_path):
    _, _, ma, _ = two_models
    path = save_model(ma, tmp_path / "m.npz")
    meta = json.loads((tmp_path / "m.json").read_text())
    assert meta["format"] == "appeal-morphpca" and meta["format_version"] == 1 and meta["size"] == [240, 200]
    back = load_model(path)
    np.testing.assert_array_equal(back.components, ma.components)
    np.testing.assert_allclose(back.faceframe, ma.faceframe)
    lo = ma.loadings[:2]
    assert np.abs(Reconstructor(back)(lo).astype(int) - Reconstructor(ma)(lo).astype(int)).max() <= 1
    # a version-0 file without loadings/faceframe still loads
    z = dict(np.load(path))
    meta0 = {k: v for k, v in json.loads(str(z["metadata_json"])).items() if k != "format_version"}
    z["metadata_json"] = np.array(json.dumps(meta0))
    del z["loadings"], z["faceframe"]
    np.savez(tmp_path / "old.npz", **z)
    old = load_model(tmp_path / "old.npz")
    assert old.faceframe is None and old.loadings.shape == (0, ma.n_components)
    meta0["format_version"] = 99
    z["metadata_json"] = np.array(json.dumps(meta0))
    np.savez(tmp_path / "new.npz", **z)
    with pytest.raises(AppealInputError, match="format_version: 99 is newer"):
        load_model(tmp_path / "new.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(AppealInputError, match="junk.npz: not a morph-space PCA model"):
        load_model(tmp_path / "junk.npz")


def test_reconstructor_batch_equals_single(two_models):
    _, _, ma, _ = two_models
    rec = Reconstructor(ma)
    batch = rec(ma.loadings[:3])
    assert batch.shape == (3, 240, 200, 3) and batch.dtype == np.uint8
    np.testing.assert_array_equal(batch[1], rec(ma.loadings[1]))
    with pytest.raises(ValueError, match="at most"):
        rec(np.zeros(ma.n_components + 1))


def test_avatar_blends_identities(two_models):
    a, b, ma, mb = two_models
    small_a = build_model(synthetic_set(a, 5, 3)[0], faceframes=synthetic_set(a, 5, 3)[2])
    small_b = build_model(synthetic_set(b, 5, 4)[0], faceframes=synthetic_set(b, 5, 4)[2])
    av = build_avatar([small_a, small_b])
    assert av.frames.shape == (10, 240, 200, 3) and av.model.n_components == 9
    # the blended neutral face is nearer to the average of both identities' skin than to either
    ska, skb = np.array(a.skin), np.array(b.skin)
    cheek = av.frames[0][150:160, 60:70].reshape(-1, 3).mean(axis=0)
    mid = (ska + skb) / 2
    assert np.linalg.norm(cheek / cheek.sum() - mid / mid.sum()) < max(
        np.linalg.norm(cheek / cheek.sum() - ska / ska.sum()), np.linalg.norm(cheek / cheek.sum() - skb / skb.sum()))
    with pytest.raises(AppealInputError, match="at least 2 identity models"):
        build_avatar([small_a])
    with pytest.raises(AppealInputError, match="summing to 1"):
        build_avatar([small_a, small_b], weights=[0.5, 0.6])


def test_reconstructor_chunks_and_float_mode_agree(two_models, monkeypatch):
    import stimulus_engine.morphpca.reconstruct as rc

    _, _, ma, _ = two_models
    lo = ma.loadings[:5]
    whole = Reconstructor(ma)(lo)
    monkeypatch.setattr(rc, "MAX_BUFFER_BYTES", 2 * 4 * (240 * 200 * 3 + 120 * 100 * 2))  # 2 rows per product
    chunked = Reconstructor(ma)(lo)  # products of 2, 2 and 1 rows: the same faces (BLAS rounding aside)
    assert np.abs(chunked.astype(int) - whole).max() <= 1
    as_float = ma.reconstruct(lo)
    assert as_float.dtype == np.float32 and 0 <= as_float.min() and as_float.max() <= 1
    assert np.abs(np.round(as_float * 255) - whole).max() <= 1
    assert Reconstructor(ma)(np.zeros((0, ma.n_components))).shape == (0, 240, 200, 3)
