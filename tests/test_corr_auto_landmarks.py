"""``landmarks: auto``: the 68 iBUG landmarks of a mesh found in renders (dlib) and lifted onto
the surface, checked against hand-placed ground truth on a real scan and on the ICT rig."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from appeal.errors import AppealInputError
from stimulus_engine.correspondence.auto_landmarks import combine_views, detect_mesh_landmarks, merge_landmarks
from stimulus_engine.correspondence.landmark_sets import read_ljson, reorder_landmarks
from stimulus_engine.geometry.ict_topology import ict_regions
from stimulus_engine.geometry.mesh_io import load_mesh

INNER = np.arange(17, 68)  # brows, nose, eyes, mouth (the jaw, 0-16, is a silhouette for the detector)


def _error_pct(found: np.ndarray, truth: np.ndarray, mesh) -> np.ndarray:
    v = np.asarray(mesh.vertices)
    return np.linalg.norm(found - truth, axis=1) / np.linalg.norm(v.max(0) - v.min(0)) * 100


@pytest.fixture(scope="module")
def james(shared_data):
    d = shared_data / "meshes" / "menpo3d-james"
    mesh = load_mesh(d / "james.obj")
    pts, order = read_ljson(d / "james.ljson")
    return mesh, reorder_landmarks(pts, order), detect_mesh_landmarks(mesh, name="james")


@pytest.mark.render
@pytest.mark.slow
def test_james_scan_within_measured_error(james):
    """benchmarks/auto_landmarks.py measured a mean inner error of 0.73 % of the diagonal."""
    mesh, truth, lm = james
    err = _error_pct(lm.points, truth, mesh)
    assert lm.front == "+z" and lm.views >= 4 and "front" in lm.scores and len(lm.scores) == lm.views
    assert err[INNER].mean() < 1.2 and np.median(err) < 2.0
    assert lm.confidence.shape == (68,) and ((0 <= lm.confidence) & (lm.confidence <= 1)).all()
    assert lm.confidence[INNER].mean() > lm.confidence[:17].mean()  # the jaw line is less certain
    np.testing.assert_allclose(lm.surface.positions(mesh.vertices), lm.points)


@pytest.mark.render
@pytest.mark.slow
def test_untextured_ict_rig_lying_on_its_side(shared_data):
    """Shaded grey (no texture), its face turned to +x and its top to +z (none of the six first
    views shows it upright); measured mean inner error 1.15 % of the diagonal."""
    d = shared_data / "meshes" / "ict-facekit"
    mesh = load_mesh(d / "generic_neutral_mesh.obj.gz")
    mesh.vertices = np.asarray(mesh.vertices)[:, [2, 0, 1]]  # (x, y, z) -> (z, x, y): a rotation
    truth = np.asarray(mesh.vertices)[np.asarray(ict_regions(d / "vertex_indices.json")["landmarks"])]
    lm = detect_mesh_landmarks(mesh, name="ict")
    assert lm.front == "+x/up+z"
    assert _error_pct(lm.points, truth, mesh)[INNER].mean() < 2.0


@pytest.mark.render
@pytest.mark.parametrize("shape", [trimesh.creation.box(extents=(1, 1.3, 0.8)), trimesh.creation.icosphere(3)],
                         ids=["box", "sphere"])
def test_a_mesh_without_a_face_is_one_line(shape):
    with pytest.raises(AppealInputError) as err:
        detect_mesh_landmarks(shape, name="shape.obj", size=320)
    message = str(err.value)
    assert message.startswith("shape.obj: landmarks: auto: no face found") and "\n" not in message
    assert "give the landmarks by hand" in message


def test_views_combine_without_their_outliers():
    """A view whose point slipped (10 % of the diagonal away) is dropped; an unseen point lowers confidence."""
    rng = np.random.default_rng(0)
    truth = rng.normal(size=(68, 3))
    stack = truth[None] + rng.normal(scale=1e-3, size=(5, 68, 3))
    stack[2, 10] += [1.0, 0.0, 0.0]  # diag 10: the slip is 10 %, the noise 0.01 %
    stack[4, 20] = np.nan
    points, confidence = combine_views(stack, diag=10.0)
    assert np.linalg.norm(points - truth, axis=1).max() < 5e-3  # the mean of all 5 would be 0.2 off at 10
    assert confidence[10] == pytest.approx(0.8, abs=0.03) and confidence[20] == pytest.approx(0.8, abs=0.03)
    others = np.setdiff1d(np.arange(68), [10, 20])
    assert (confidence[others] > 0.95).all() and (confidence <= 1).all()


@pytest.mark.render
@pytest.mark.slow
def test_given_points_override_single_auto_points(james):
    mesh, truth, lm = james
    merged = merge_landmarks(lm, {30: truth[30], 8: truth[8]}, mesh)
    err = _error_pct(merged.points, truth, mesh)
    assert err[30] < 0.1 and err[8] < 0.1 < _error_pct(lm.points, truth, mesh)[8]  # on the given point, snapped
    assert merged.confidence[30] == 1 and merged.confidence[8] == 1
    np.testing.assert_array_equal(merged.points[:8], lm.points[:8])
    with pytest.raises(AppealInputError, match="iBUG indices 0-67"):
        merge_landmarks(lm, {68: truth[0]}, mesh)
