"""End-to-end correspondence, texture transfer, morphing and the CLI on small synthetic pairs,
and one real-data test (ICT face region onto the menpo3d james scan)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from appeal_cli import main
from appeal.errors import AppealInputError
from stimulus_engine import (
    blend_images,
    blend_vertices,
    correspond,
    deformed_mesh,
    partial_blend,
    transfer_texture,
)
from stimulus_engine.correspondence import CorrespondParams, Correspondences, SurfacePoints, joint_fairing
from stimulus_engine.correspondence.datasets import ict_james_pair
from stimulus_engine.geometry.mesh_ops import boundary_loops
from stimulus_engine.correspondence.synthetic import synthetic_pair
from stimulus_engine.geometry.mesh_io import load_mesh, save_mesh


@pytest.fixture(scope="module")
def pair():
    src, tgt, corr = synthetic_pair(900, 700, texture_size=64)
    return src, tgt, corr, correspond(src, tgt, corr)


def test_stylised_pair_fits_without_foldovers(pair):
    src, tgt, corr, res = pair
    m = res.metrics
    assert m["hausdorff_rel"] < 0.01
    assert m["median_dist_rel"] < 0.002
    assert m["flipped_triangles"] == 0
    assert m["degenerate_triangles"] == 0
    assert res.vertices.shape == src.vertices.shape
    # the source's features land on the target's (eyes x1.6, nose x0.6)
    lm_s = corr.source.subset(slice(0, 16)).positions(res.vertices)
    lm_t = corr.target.subset(slice(0, 16)).positions(tgt.vertices)
    assert np.linalg.norm(lm_s - lm_t, axis=1).max() / m["target_bbox_diagonal"] < 0.01
    assert set(res.seconds) >= {"fairing", "register_base", "register_original", "total"}


def test_converged_stages_end_early(pair):
    # the default stops a stiffness stage / the fairing once no vertex moves more than 2e-4
    # of the diagonal; with the tolerance off every iteration of the schedule runs
    src, tgt, corr, res = pair
    full = correspond(src, tgt, corr, CorrespondParams(converge_tolerance=0.0))
    p = CorrespondParams()
    assert full.metrics["fairing_solves"] == p.fairing_iterations
    assert full.metrics["registration_iterations"] == sum(n for _, n in p.schedule) + p.final_iterations
    assert res.metrics["registration_iterations"] < full.metrics["registration_iterations"]
    assert res.metrics["fairing_solves"] <= p.fairing_iterations
    # and the result is the same to within a small fraction of the target's size
    d = np.linalg.norm(res.vertices - full.vertices, axis=1).max() / res.metrics["target_bbox_diagonal"]
    assert d < 2e-3
    assert abs(res.metrics["hausdorff_rel"] - full.metrics["hausdorff_rel"]) < 5e-4


# the long cartoon nose (x2.8) is not fully reached at its tip: Hausdorff 4.6 % measured
# (median 0.001 %), an open limit noted in docs/correspondence.md; the point here is no folds
@pytest.mark.parametrize("eyes, nose, max_hausdorff", [(2.4, 0.4, 0.01), (1.6, 2.8, 0.06)])
def test_extreme_stylised_pairs_fit_without_foldovers(eyes, nose, max_hausdorff):
    # more extreme than the pair (eyes x1.6, nose x0.6)
    src, tgt, corr = synthetic_pair(700, 500, eyes=eyes, nose=nose, texture_size=32)
    m = correspond(src, tgt, corr).metrics
    assert m["flipped_triangles"] == 0
    assert m["degenerate_triangles"] == 0
    assert m["hausdorff_rel"] < max_hausdorff
    assert m["median_dist_rel"] < 0.001


def test_joint_fairing_makes_meshes_smooth_and_coincident(pair):
    src, tgt, corr, res = pair
    from stimulus_engine.correspondence.laplacian import bilaplacian, fairing_operator, voronoi_areas

    def bend(v, f):
        return np.einsum("ij,ij->", v, bilaplacian(fairing_operator(v, f), voronoi_areas(v, f)) @ v)

    aligned = res.alignment.apply(src.vertices)
    assert bend(res.faired_source, src.faces) < 0.5 * bend(aligned, src.faces)
    gap0 = np.linalg.norm(corr.source.positions(aligned) - corr.target.positions(tgt.vertices), axis=1).mean()
    gap = np.linalg.norm(corr.source.positions(res.faired_source) - corr.target.positions(res.faired_target), axis=1).mean()
    assert gap < 0.1 * gap0


def test_fairing_energy_decreases_with_lambda1():
    src, tgt, corr = synthetic_pair(400, 300, texture_size=16)
    from stimulus_engine.correspondence.laplacian import bilaplacian, fairing_operator, voronoi_areas

    def bend(v, f):
        return np.einsum("ij,ij->", v, bilaplacian(fairing_operator(v, f), voronoi_areas(v, f)) @ v)

    b = [bend(joint_fairing(src.vertices, src.faces, tgt.vertices, tgt.faces, corr, lambda1=l1, iterations=1).source, src.faces)
         for l1 in (0.01, 0.1, 10.0)]
    assert b[0] > b[1] > b[2]


def test_fairing_energy_is_the_energy_of_eq_3_7():
    """The reported energy (from the solve's identity) equals eq. 3.7-3.10 evaluated directly
    on the faired meshes, with the input areas of the one solve."""
    src, tgt, corr = synthetic_pair(400, 300, texture_size=16)
    from stimulus_engine.correspondence.laplacian import fairing_operator, voronoi_areas

    xs, xt = np.asarray(src.vertices, float), np.asarray(tgt.vertices, float)
    res = joint_fairing(xs, src.faces, xt, tgt.faces, corr, iterations=1)
    a_s, a_t = voronoi_areas(xs, src.faces), voronoi_areas(xt, tgt.faces)
    m = len(corr)
    smooth = sum(np.einsum("i,ij,ij->", 1 / a, op @ v, op @ v)
                 for a, op, v in ((a_s, fairing_operator(xs, src.faces), res.source),
                                  (a_t, fairing_operator(xt, tgt.faces), res.target)))
    rs, rt = corr.source.positions(res.source), corr.target.positions(res.target)
    hat = 0.5 * (corr.source.positions(xs) + corr.target.positions(xt))
    energy = (0.1 / (a_s.sum() + a_t.sum()) * smooth + 100.0 / m * np.sum((rs - rt) ** 2)
              + 1.0 / m * np.sum((0.5 * (rs + rt) - hat) ** 2) - 1.0 / m * np.sum(hat ** 2))
    assert res.energies[0] == pytest.approx(energy, rel=1e-6)


def test_registration_on_the_fairing_map_equals_the_plain_one():
    """The registration's matrices from the fairing's bi-Laplacian map (no sparse products) are
    the ones it builds itself: the same registered vertices."""
    from stimulus_engine.geometry.closest import SurfaceIndex
    from stimulus_engine.correspondence.laplacian import fairing_operator, voronoi_areas
    from stimulus_engine.correspondence.registration import Pruning, nonrigid_register

    src, tgt, corr = synthetic_pair(400, 300, texture_size=16)
    xs, xt = np.asarray(src.vertices, float), np.asarray(tgt.vertices, float)
    ls = fairing_operator(xs, src.faces)
    fair = joint_fairing(xs, src.faces, xt, tgt.faces, corr, iterations=2, source_laplacian=ls)
    assert fair.source_bilaplacian is not None
    args = (xs, np.asarray(src.faces), ls, voronoi_areas(xs, src.faces), SurfaceIndex(xt, tgt.faces), corr.source,
            corr.target.positions(xt))
    # one solve per stiffness (later closest-point rounds amplify 1e-13 differences into
    # other pruning decisions at the thresholds)
    kw = dict(schedule=((10.0, 1),), pruning=Pruning(2.0, 60.0, True))
    plain = nonrigid_register(*args, **kw)
    mapped = nonrigid_register(*args, **kw, bilaplacian_map=fair.source_bilaplacian)
    assert mapped.solver.pattern is fair.source_bilaplacian[0]
    np.testing.assert_allclose(mapped.vertices, plain.vertices, atol=1e-10)
    kw = dict(schedule=((0.1, 1),), pruning=Pruning(2.0, 60.0, True))  # softer: the bi-Laplacian weighs less
    np.testing.assert_allclose(nonrigid_register(*args, **kw, bilaplacian_map=fair.source_bilaplacian).vertices,
                               nonrigid_register(*args, **kw).vertices, atol=1e-10)


def test_texture_transfer_carries_target_features(pair):
    src, tgt, corr, res = pair
    dm = deformed_mesh(src, res.vertices)
    img = np.asarray(transfer_texture(dm, tgt, size=(64, 64)), dtype=float)
    ref = np.asarray(tgt.visual.material.image, dtype=float)
    # UV = (x, y) on both faces: the transferred map is the target's painted features where the
    # source's feature sits, i.e. the target texture warped; check the skin colour is kept and
    # the big target eyes (white) appear in the source layout around the source eye position
    assert np.allclose(img[0, 0], 0)  # outside the outline: no triangle, stays background
    assert img[int((1 - 0.61) * 64), 32].mean() > 100  # forehead is skin, not background
    assert img.shape == (64, 64, 3) and ref.shape[2] == 3


def test_texture_transfer_errors(pair):
    src, tgt, corr, res = pair
    bare = trimesh.Trimesh(src.vertices, src.faces, process=False)
    with pytest.raises(AppealInputError, match="no UV coordinates"):
        transfer_texture(bare, tgt)
    missing = tgt.copy()
    missing.metadata.update({"texture_missing": True, "texture_path": "/nowhere/t.png"})
    missing.visual.material.image = None
    with pytest.raises(AppealInputError, match="texture file /nowhere/t.png not found"):
        transfer_texture(deformed_mesh(src, res.vertices), missing)


def test_morph_blends():
    v0 = np.zeros((4, 3))
    v1 = np.ones((4, 3))
    np.testing.assert_allclose(blend_vertices([v0, v1], [0.25, 0.75]), 0.75)
    with pytest.raises(AppealInputError, match="sum to 1"):
        blend_vertices([v0, v1], [0.5, 0.6])
    with pytest.raises(AppealInputError, match="same vertex count"):
        blend_vertices([v0, np.ones((5, 3))], [0.5, 0.5])
    from PIL import Image

    a = Image.new("RGB", (4, 4), (0, 0, 0))
    b = Image.new("RGB", (4, 4), (200, 100, 50))
    assert blend_images([a, b], [0.5, 0.5]).getpixel((0, 0)) == (100, 50, 25)


def test_partial_blend_keeps_outside_and_moves_inside():
    s = trimesh.creation.icosphere(3)
    v0 = s.vertices.copy()
    v1 = v0.copy()
    bump = v0[:, 2] > 0.5
    v1[bump] *= 1.3
    w = np.zeros((len(v0), 2))
    w[bump, 1] = 1.0
    w[:, 0] = 1 - w[:, 1]
    r = partial_blend([v0, v1], s.faces, w)
    np.testing.assert_allclose(r[~bump], v0[~bump], atol=1e-6)
    assert r[bump, 2].max() > v0[bump, 2].max() + 0.02  # the region takes the other shape's bulge


def test_cli_correspond_transfer_morph(tmp_path, capsys):
    src, tgt, corr = synthetic_pair(500, 400, texture_size=32)
    save_mesh(src, tmp_path / "src.obj")
    save_mesh(tgt, tmp_path / "tgt.obj")
    # 3D points on the surfaces (snapped by the CLI; the other entry kinds are tested in test_corr_core)
    ps = corr.source.subset(slice(0, 16)).positions(src.vertices).round(6).tolist()
    pt = corr.target.subset(slice(0, 16)).positions(tgt.vertices).round(6).tolist()
    pairs = {"source": ps, "target": pt}
    (tmp_path / "pairs.json").write_text(json.dumps(pairs))
    r = main(["stimuli", "correspond", str(tmp_path / "src.obj"), str(tmp_path / "tgt.obj"),
                                 "--landmarks", str(tmp_path / "pairs.json"), "--out", str(tmp_path / "c"),
                                 "--no-sheet", "--json", str(tmp_path / "m.json")])
    assert r == 0, capsys.readouterr().err
    m = json.loads((tmp_path / "m.json").read_text())
    for k in ("seconds", "hausdorff_rel", "mean_dist_rel", "flipped_triangles", "n_source_vertices", "n_target_vertices"):
        assert k in m
    d = load_mesh(tmp_path / "c" / "deformed.obj")
    assert d.vertices.shape == src.vertices.shape
    np.testing.assert_array_equal(d.faces, src.faces)
    r = main(["stimuli", "transfer-texture", str(tmp_path / "c" / "deformed.obj"),
                                 str(tmp_path / "tgt.obj"), "--out", str(tmp_path / "tex.png")])
    assert r == 0, capsys.readouterr().err
    r = main(["stimuli", "morph", str(tmp_path / "src.obj"), str(tmp_path / "c" / "deformed.obj"),
                                 "--weights", "0.5", "0.5", "--out", str(tmp_path / "half.obj")])
    assert r == 0, capsys.readouterr().err
    half = load_mesh(tmp_path / "half.obj")
    np.testing.assert_allclose(half.vertices, 0.5 * (src.vertices + d.vertices), atol=1e-5)
    # bad input: one line, exit 2, nothing half-written
    r = main(["stimuli", "morph", str(tmp_path / "src.obj"), str(tmp_path / "tgt.obj"),
                                 "--weights", "0.5,0.5", "--out", str(tmp_path / "bad.obj")])
    assert r == 2 and "not in correspondence" in capsys.readouterr().err and not (tmp_path / "bad.obj").exists()
    r = main(["stimuli", "correspond", str(tmp_path / "src.obj"), str(tmp_path / "tgt.obj"),
                                 "--landmarks", '{"source": [0, 1, 2], "target": [0, 1]}', "--out", str(tmp_path / "c2")])
    assert r == 2 and "same number of points (got 3 and 2)" in capsys.readouterr().err
    r = main(["stimuli", "transfer-texture", str(tmp_path / "c" / "deformed.obj"),
                                 str(tmp_path / "tgt.obj"), "--out", str(tmp_path / "tex.png")])
    assert r == 2 and "exists" in capsys.readouterr().err


def test_non_manifold_rejected():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], float)
    f = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])  # edge (0,1) in three triangles
    m = trimesh.Trimesh(v, f, process=False)
    c = Correspondences(SurfacePoints.from_vertices([0, 1, 2]), SurfacePoints.from_vertices([0, 1, 2]))
    with pytest.raises(AppealInputError, match="non-manifold"):
        correspond(m, m, c)


@pytest.mark.slow
def test_ict_face_onto_james(shared_data):
    """Real data: ICT narrow face region -> james scan, thesis defaults (5 fairing solves).

    16 landmarks plus ICT's eye and mouth rims tied to james's eyelid and inner-lip landmark
    curves; the 34 landmarks used for neither (jaw, brows, nose, outer lips) are held out."""
    src, james, corr, (held_src, held_t) = ict_james_pair(shared_data)
    n_rim = sum(len(lp) for lp in boundary_loops(src.faces)[1:])  # mouth + 2 eye loops
    assert len(corr) == 16 + n_rim and len(held_src) == 34
    res = correspond(src, james, corr)
    m = res.metrics
    assert m["median_dist_rel"] <= 0.002
    assert m["hausdorff_rel"] <= 0.01
    # no fold-overs, and the rims lie on james's closed lids and lips (no membrane left off)
    assert m["flipped_triangles"] == 0 and m["degenerate_triangles"] == 0
    assert m["off_surface_vertices"] == 0
    diag = m["target_bbox_diagonal"]
    rim = slice(16, None)
    gap = np.linalg.norm(corr.source.subset(rim).positions(res.vertices) - corr.target.subset(rim).positions(james.vertices), axis=1)
    # measured (rims.py in the follow-up notes): median 0.2 %, max 2.1 % (mouth corners, moved by
    # the untangling); without the rim curves the eye openings gape (gaps of several %)
    assert np.median(gap) / diag <= 0.003 and gap.max() / diag <= 0.03
    err = np.linalg.norm(res.vertices[held_src] - held_t, axis=1) / diag
    assert err.mean() <= 0.02
    tex = transfer_texture(deformed_mesh(src, res.vertices), james, size=(128, 128))
    assert tex.size == (128, 128)

