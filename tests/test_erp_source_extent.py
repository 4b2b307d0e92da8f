"""Source statistics comparable across grids: the cluster extent as a volume and Gaussian
smoothing of the maps (thesis §7.3: 25 voxels of 2 mm; SPM's 8 mm FWHM)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.erp.source import HeadModel, contrast_clusters, smooth_on_grid


def _grid_head(spacing_m: float, half: int = 6) -> HeadModel:
    """A cubic volume grid (metres) with an identity MNI transform (mm = 1000 m)."""

    class _Src(list):
        pass

    g = np.arange(-half, half + 1) * spacing_m
    rr = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    src = _Src([{"rr": rr, "vertno": np.arange(len(rr))}])
    to_mni = np.eye(4)
    to_mni[:3, :3] *= 1e3
    return HeadModel(bem=None, src=src, trans=None, to_mni=to_mni, kind="sphere")


def test_smoothing_has_the_asked_fwhm_and_keeps_a_constant():
    head = _grid_head(0.002, half=12)  # 2 mm grid
    pos = head.positions
    spike = np.zeros(len(pos))
    centre = int(np.argmin(np.linalg.norm(pos, axis=1)))
    spike[centre] = 1.0
    out = smooth_on_grid(spike[None], pos, 0.008)[0]
    on_x = np.abs(pos[:, 1]) + np.abs(pos[:, 2]) < 1e-9
    x, y = pos[on_x, 0], out[on_x]
    half_max = y.max() / 2
    # the full width at half maximum of the profile through the spike, linearly interpolated
    right = np.sort(x[(x >= 0) & (y < half_max)])[0]
    inside = x[(x >= 0) & (y >= half_max)].max()
    yr, yi = np.interp(right, x[np.argsort(x)], y[np.argsort(x)]), np.interp(inside, x[np.argsort(x)], y[np.argsort(x)])
    fwhm = 2 * (inside + (yi - half_max) / (yi - yr) * (right - inside))
    assert fwhm == pytest.approx(0.008, rel=0.1)
    inner = np.all(np.abs(pos) < 0.012, axis=1)  # away from the grid's edge
    np.testing.assert_allclose(smooth_on_grid(np.ones((1, len(pos))), pos, 0.008)[0][inner], 1.0)
    np.testing.assert_array_equal(smooth_on_grid(spike[None], pos, 0.0)[0], spike)


def test_cluster_extent_as_a_volume_means_the_same_on_any_grid():
    rng = np.random.default_rng(3)
    results = {}
    for spacing in (0.004, 0.007):
        head = _grid_head(spacing)
        pos = head.positions
        blob = np.linalg.norm(pos - [0.0, 0.0, 0.0], axis=1) < 0.0105  # a 21 mm wide effect
        diff = rng.normal(0, 1, (12, len(pos))) + 3.0 * blob
        by_volume = {}
        for mm3 in (200.0, 30000.0):
            _, table = contrast_clusters(diff, head, p_threshold=0.005, min_volume_mm3=mm3, n_permutations=50)
            by_volume[mm3] = table
        results[spacing] = by_volume
        voxel = (spacing * 1e3) ** 3
        t = by_volume[200.0]
        assert len(t) >= 1 and t["volume_mm3"].iloc[0] == pytest.approx(t["n_voxels"].iloc[0] * voxel)
        assert (t["volume_mm3"] >= 200.0).all()
    # the effect (about 4.8 cm³) passes 200 mm³ on both grids and fails 30 cm³ on both
    for spacing, by_volume in results.items():
        assert len(by_volume[200.0]) >= 1 and len(by_volume[30000.0]) == 0, spacing
