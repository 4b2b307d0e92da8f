"""Region masks found in a scan's photographic texture (for the flat and blurred materials)."""

from __future__ import annotations

import numpy as np

from stimulus_engine.stylisation.materials import stylise_albedo
from stimulus_engine.geometry.mesh_io import load_mesh, mesh_uv_layout, texture_image
from stimulus_engine.characters.scan_regions import scan_masks


def test_james_texture_splits_into_skin_hair_lips_and_shirt(shared_data):
    """On the real scan with menpo's own 68 points: the lips mask lies under the lip points, hair
    is darker than skin, the shirt brighter, and the flat material paints each its own colour."""
    from stimulus_engine.correspondence.landmark_sets import read_ljson, reorder_landmarks

    d = shared_data / "meshes" / "menpo3d-james"
    mesh = load_mesh(d / "james.obj")
    pts, order = read_ljson(d / "james.ljson")
    ibug = reorder_landmarks(pts, order, "ibug68")
    v = np.asarray(mesh.vertices, np.float64)
    # the masks look along +z: turn the scan so its face does (nose tip in front of the eye corners)
    if ibug[30, 2] < ibug[[36, 45], 2].mean():
        v, ibug = v * [-1, 1, -1], ibug * [-1, 1, -1]
    uv, face_uv = mesh_uv_layout(mesh)
    tex = np.asarray(texture_image(mesh).convert("RGB"))
    masks = scan_masks(tex, v, np.asarray(mesh.faces), uv, face_uv, ibug)
    assert set(masks) == {"lips", "hair", "other", "unused"}
    h, w = tex.shape[:2]
    assert all(m.shape == (h, w) and 0 <= m.min() and m.max() <= 1 for m in masks.values())
    lum = tex @ [0.2126, 0.7152, 0.0722]
    skin = 1 - sum(masks.values())
    assert skin.mean() > 0.05
    mean = {k: np.average(lum, weights=m) for k, m in {**masks, "skin": np.clip(skin, 0, 1)}.items()}
    assert mean["hair"] < mean["skin"] - 30 < mean["other"] - 30  # dark hair, white shirt
    red = tex[..., 0] / np.maximum(tex[..., 1:].mean(axis=-1), 1)
    assert np.average(red, weights=masks["lips"]) > np.average(red, weights=np.clip(skin, 0, 1)) + 0.1
    assert 0.0005 < masks["lips"].mean() < 0.02
    flat = stylise_albedo(tex, "flat", masks)
    colours = {k: flat[m > 0.99].reshape(-1, 3) for k, m in masks.items() if k != "unused"}
    for k, c in colours.items():
        assert len(c) and np.ptp(c, axis=0).max() <= 2, k  # one colour per region
    assert len({tuple(np.median(c, axis=0).astype(int)) for c in colours.values()}) == 3


def test_too_little_skin_gives_no_masks():
    tex = np.zeros((64, 64, 3), np.uint8)
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    ibug = np.full((68, 3), 5.0)  # landmarks nowhere near the surface
    assert scan_masks(tex, v, np.array([[0, 1, 2]]), np.array([[0, 0], [1, 0], [0, 1.0]]),
                      np.array([[0, 1, 2]]), ibug) == {}
