"""Part-based morphs (thesis §3.4): Laplacian slerp + Poisson, facial regions, gradient-domain
texture blending, and ``appeal stimuli morph --regions``."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from appeal.errors import AppealInputError
from meshes import grid
from stimulus_engine.stylisation.gradient_blend import gradient_blend
from stimulus_engine.stylisation.morph import partial_blend, slerp_vectors
from stimulus_engine.stylisation.morph_regions import REGIONS, parse_regions, region_weights


def test_slerp_vectors_is_slerp_for_two_and_keeps_one_hot_vectors():
    a, b = np.array([[2.0, 0, 0]]), np.array([[0, 4.0, 0]])
    for t in (0.0, 0.3, 0.5, 1.0):
        got = slerp_vectors(np.stack([a, b]), np.array([[1 - t, t]]))[0]
        ang = t * np.pi / 2
        np.testing.assert_allclose(got, (2 + 2 * t) * np.array([np.cos(ang), np.sin(ang), 0]), atol=1e-12)
    rng = np.random.default_rng(0)
    v = rng.normal(size=(3, 50, 3))
    w = np.zeros((50, 3))
    w[:, 2] = 1
    np.testing.assert_allclose(slerp_vectors(v, w), v[2], atol=1e-12)
    # three vectors, equal weights, symmetric about z: the mean direction is z
    s = np.array([[[1.0, 0, 1]], [[-0.5, 0.866025403784, 1]], [[-0.5, -0.866025403784, 1]]])
    got = slerp_vectors(s, np.full((1, 3), 1 / 3))[0]
    np.testing.assert_allclose(got / np.linalg.norm(got), [0, 0, 1], atol=1e-9)
    assert np.linalg.norm(got) == pytest.approx(np.sqrt(2))
    zero = slerp_vectors(np.stack([np.zeros((1, 3)), b]), np.array([[0.5, 0.5]]))
    np.testing.assert_allclose(zero, 0.5 * b)  # no direction to turn: linear


def test_slerp_and_linear_agree_on_identical_meshes_and_differ_on_a_turned_one():
    s = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    w = np.full((len(v), 2), 0.5)
    anchor = int(np.argmin(v[:, 2]))
    w[anchor] = (1.0, 0.0)
    for method in ("slerp", "linear"):
        np.testing.assert_allclose(partial_blend([v, v], f, w, interpolation=method), v, atol=1e-6)
    turned = v @ trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0])[:3, :3].T
    radius = {}
    for method in ("slerp", "linear"):
        out = partial_blend([v, turned], f, w, interpolation=method)
        radius[method] = np.linalg.norm(out - out.mean(axis=0), axis=1).mean()
    # halfway to a copy turned 90 degrees: slerp keeps the Laplacians' lengths and so the size
    # (measured 1.06); averaging vectors 90 degrees apart shortens them, the shape shrinks (0.88)
    assert radius["slerp"] == pytest.approx(1.0, abs=0.1)
    assert radius["linear"] < 0.9 * radius["slerp"]
    with pytest.raises(AppealInputError, match="interpolation"):
        partial_blend([v, v], f, w, interpolation="cubic")


def _face_points() -> np.ndarray:
    """68 iBUG-like points on the plane z = 0: eyes at (+-1, 1), nose at (0, 0), mouth at (0, -1)."""
    p = np.zeros((68, 3))
    p[:17] = np.column_stack([np.linspace(-2, 2, 17), -1.5 + 0.2 * np.linspace(-2, 2, 17) ** 2, np.zeros(17)])
    for i, cx in ((36, -1.0), (42, 1.0)):
        ang = np.linspace(0, 2 * np.pi, 7)[:6]
        p[i:i + 6] = np.column_stack([cx + 0.3 * np.cos(ang), 1 + 0.15 * np.sin(ang), np.zeros(6)])
    p[17:27] = np.column_stack([np.r_[np.linspace(-1.4, -0.6, 5), np.linspace(0.6, 1.4, 5)], np.full(10, 1.5), np.zeros(10)])
    p[27:36] = np.column_stack([np.r_[np.zeros(4), np.linspace(-0.3, 0.3, 5)], np.r_[np.linspace(0.6, 0, 4), np.full(5, -0.1)], np.zeros(9)])
    ang = np.linspace(0, 2 * np.pi, 21)[:20]
    p[48:68] = np.column_stack([0.5 * np.cos(ang), -1 + 0.2 * np.sin(ang), np.zeros(20)])
    return p


def test_region_weights_cover_the_named_parts_only():
    v, _ = grid(81, lo=-2.5, hi=2.5)
    p = _face_points()
    w = region_weights(v, p, {"eyes": 1, "mouth": 2}, 3)
    assert w.shape == (len(v), 3) and np.allclose(w.sum(axis=1), 1)
    at = lambda x, y: w[np.argmin(np.linalg.norm(v[:, :2] - [x, y], axis=1))]  # noqa: E731
    np.testing.assert_allclose(at(-1, 1), [0, 1, 0]), np.testing.assert_allclose(at(1, 1), [0, 1, 0])
    np.testing.assert_allclose(at(0, -1), [0, 0, 1])
    np.testing.assert_allclose(at(0, 0.2), [1, 0, 0]), np.testing.assert_allclose(at(-2.3, -2.3), [1, 0, 0])
    edge = at(-1.48, 1.0)  # beyond the core, within the falloff
    assert 0 < edge[1] < 1
    with pytest.raises(AppealInputError, match="expected 68 iBUG points"):
        region_weights(v, p[:10], {"eyes": 1}, 2)


def test_parse_regions_says_what_is_wrong_in_one_line():
    assert parse_regions("eyes=1, mouth=2", 3) == {"eyes": 1, "mouth": 2}
    assert parse_regions("nose", 2) == {"nose": 1}
    for text, n, msg in [("ears=1", 2, "unknown region 'ears'"), ("eyes=3", 3, "mesh 3 does not exist"),
                         ("eyes=0", 2, "mesh 0 does not exist"), ("eyes=x", 2, "MESH a number"),
                         ("eyes=1,eyes=1", 2, "named twice"), ("nose", 3, "say which mesh"), ("", 2, "expected REGION")]:
        with pytest.raises(AppealInputError, match=msg) as exc:
            parse_regions(text, n)
        assert "\n" not in str(exc.value)
    assert set(REGIONS) == {"eyes", "brows", "nose", "mouth"}


def test_gradient_blend_brings_the_details_in_the_bases_tone_without_a_seam():
    h = w = 64
    yy, xx = np.mgrid[0:h, 0:w]
    base = np.full((h, w, 3), 100.0)
    donor = 160 + 20 * np.sin(xx / 2.0)[..., None] * np.ones(3)
    r = np.hypot(yy - 32, xx - 32)
    wd = np.clip((14 - r) / 4, 0, 1)  # the donor inside a disc, soft edge
    out = gradient_blend([base.astype(np.uint8), donor.astype(np.uint8)], np.stack([1 - wd, wd])).astype(float)
    core = r < 8
    assert abs(out[core].mean() - 100) < 12  # the base's tone, not the donor's 160
    assert out[core, 0].std() > 0.7 * donor[core, 0].std()  # the donor's stripes
    ring = (r > 13) & (r < 16)
    assert np.abs(out[ring] - 100).max() < 12  # no seam where the disc meets the base (a paste jumps by 60)
    np.testing.assert_array_equal(out[r > 18], base[r > 18])


@pytest.mark.render
def test_morph_regions_cli_on_the_james_scan(shared_data, tmp_path, capsys):
    """A donor with james's eye regions enlarged: the morph takes its eyes and keeps the mouth."""
    from appeal_cli import main
    from stimulus_engine.correspondence.pipeline import deformed_mesh
    from stimulus_engine.geometry.mesh_io import load_mesh, save_mesh
    from stimulus_engine.stylisation.morph_regions import read_ibug

    d = shared_data / "meshes" / "menpo3d-james"
    james = load_mesh(d / "james.obj")
    ib = read_ibug(d / "james.ljson")
    v = np.asarray(james.vertices, float)
    big = v.copy()
    for group in REGIONS["eyes"]:
        c = ib[list(group)].mean(axis=0)
        near = np.linalg.norm(v - c, axis=1) < 25.0
        big[near] = c + 1.4 * (v[near] - c)
    save_mesh(deformed_mesh(james, big), tmp_path / "big.obj")
    out = tmp_path / "eyes.obj"
    assert main(["stimuli", "morph", str(d / "james.obj"), str(tmp_path / "big.obj"), "--regions", "eyes=1",
                 "--landmarks", str(d / "james.ljson"), "--out", str(out), "--sheet", str(tmp_path / "s.png")]) == 0
    res = np.asarray(load_mesh(out).vertices)
    right = ib[36:42].mean(axis=0)
    ring = np.linalg.norm(v - right, axis=1) < 20
    assert np.linalg.norm(res[ring] - right, axis=1).mean() > 1.2 * np.linalg.norm(v[ring] - right, axis=1).mean()
    mouth = np.linalg.norm(v - ib[48:68].mean(axis=0), axis=1) < 20
    np.testing.assert_allclose(res[mouth], v[mouth], atol=1e-6)
    assert (tmp_path / "s.png").is_file() and (tmp_path / "eyes.png").is_file()  # the sheet, the texture
    capsys.readouterr()
    for argv, msg in [(["--regions", "ears=1"], "unknown region 'ears'"), ([], "either --weights"),
                      (["--regions", "eyes=1", "--weights", "0.5,0.5"], "either --weights")]:
        rc = main(["stimuli", "morph", str(d / "james.obj"), str(tmp_path / "big.obj"), *argv, "--out",
                   str(tmp_path / "x.obj")])
        err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
        assert rc == 2 and len(err) == 1 and msg in err[0]
    other = shared_data / "meshes" / "mediapipe-canonical" / "canonical_face_model.obj"
    rc = main(["stimuli", "morph", str(d / "james.obj"), str(other), "--regions", "eyes=1", "--landmarks",
               str(d / "james.ljson"), "--out", str(tmp_path / "y.obj")])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1 and "not in correspondence" in err[0]
