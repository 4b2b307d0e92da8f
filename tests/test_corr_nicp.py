"""Ours vs trimesh's Amberg NICP on stylised pairs: where NICP folds and ours does not (thesis
Fig. 3.12), plus the hooked-nose stylisation that makes a target with an overhang.

NICP is called exactly as ``benchmarks/correspond.py`` calls it (same similarity alignment,
same landmarks as (triangle, barycentric) pairs), with the schedule of trimesh's own example
(examples/nricp.py: stiffness 0.02 -> 0.007 -> 0.002, landmark weight 3 throughout, distance
threshold 0.05). With trimesh's *defaults* (stiffness never below 0.01, landmarks switched off
for the last stage) NICP has not folded on any pair tried (notes/issue-4.md, follow-up 5).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from stimulus_engine.correspondence import correspond, fit_metrics
from stimulus_engine.correspondence.synthetic import synthetic_face, synthetic_pair

_BENCH = Path(__file__).resolve().parent.parent / "benchmarks" / "correspond.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_correspond", _BENCH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_nose_hook_makes_an_overhang_and_keeps_the_plain_faces():
    plain = synthetic_face(600, 1.6, 1.6, "jitter", 1, 16)
    zero = synthetic_face(600, 1.6, 1.6, "jitter", 1, 16, nose_hook=0.0)
    hooked = synthetic_face(600, 1.6, 1.6, "jitter", 1, 16, nose_hook=1.0)
    np.testing.assert_array_equal(plain.vertices, zero.vertices)
    np.testing.assert_array_equal(plain.faces, hooked.faces)
    # a height field over (x, y) has every triangle facing +z; the hooked nose's underside
    # faces downwards and away from the viewer
    assert (plain.face_normals[:, 2] > 0).all()
    under = hooked.face_normals[:, 2] < -0.3
    assert under.sum() >= 3
    assert (hooked.face_normals[under, 1] < 0).all()  # they face down (-y): an overhang
    # only the nose moved (x unchanged everywhere; y only where the ridge is)
    np.testing.assert_array_equal(plain.vertices[:, 0], hooked.vertices[:, 0])
    moved = np.abs(plain.vertices[:, 1] - hooked.vertices[:, 1]) > 1e-3
    assert np.abs(plain.vertices[moved, 0]).max() < 0.4


@pytest.mark.parametrize(
    "stylisation",
    [
        # the pair: eyes x1.6, nose x0.6, grid source vs jittered target
        {},
        # a hooked cartoon nose (x1.6) whose underside overhangs the upper lip
        {"nose": 1.6, "nose_hook": 1.0},
    ],
    ids=["eyes1.6_nose0.6", "hooked_nose"],
)
def test_nicp_folds_where_ours_does_not(bench, stylisation):
    src, tgt, corr = synthetic_pair(600, 500, texture_size=16, **stylisation)
    res = correspond(src, tgt, corr)
    assert res.metrics["flipped_triangles"] == 0
    assert res.metrics["degenerate_triangles"] == 0
    assert res.metrics["median_dist_rel"] < 0.001

    _, v, aligned = bench.run_nicp(src, tgt, corr, 1, "example")
    m = fit_metrics(v, src.faces, tgt.vertices, tgt.faces, aligned)
    # Why NICP folds here: its stiffness term only asks neighbouring vertices' affine maps to
    # agree (Amberg eq. 10); at the example's stiffness 0.007 -> 0.002 with the landmark term
    # still on, a landmark whose target lies several edges away (the stylised eye corners and
    # nose wings) is pulled through its one-ring before its neighbours follow, and the
    # closest-point term then presses the crumpled ring onto the target. Measured with these
    # settings (600/500, seeds 0-2): 19-23 fold-overs on the issue pair, 35-40 on the hooked
    # pair (0 with trimesh's defaults), all within ~3 edges of a feature point. With the
    # defaults' first stages and only the last (landmark-free) stiffness lowered to 0.002 the
    # issue pair does not fold, the hooked pair does (2-3, at the overhang: closest points on
    # the underside of the nose, thesis Fig. 3.2). Ours fairs both meshes together first (no
    # closest points until both are smooth and alike): none on the issue pair; on the hooked
    # pair its registration leaves 2 at the overhang (3319 -> 1328, untangle=False), which the
    # default untangling step relaxes away on the target surface (0 off-surface vertices).
    assert m["flipped_triangles"] > 0
    # the folds are on the surface, not a diverged fit: half of NICP's vertices are as close
    # to the target as ours
    assert m["median_dist_rel"] < 0.001
