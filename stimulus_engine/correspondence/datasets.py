"""The real-data pair of the issue: the ICT face region onto the menpo3d james scan."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from stimulus_engine.correspondence.landmarks import (
    LANDMARK_SUBSET_16,
    Correspondences,
    SurfacePoints,
    parse_points,
    read_ljson,
    reorder_landmarks,
)
from stimulus_engine.mesh_io import ict_regions, load_mesh, select_region

__all__ = ["ict_james_pair"]


def ict_james_pair(
    data_dir: str | Path, region: str = "narrow_face", subset: np.ndarray = LANDMARK_SUBSET_16
) -> tuple[trimesh.Trimesh, trimesh.Trimesh, Correspondences, tuple[np.ndarray, np.ndarray]]:
    """ICT neutral face ``region`` (source) and james (target) with landmark correspondences.

    Parameters
    ----------
    data_dir : path-like
        The ``shared/data`` folder (with ``meshes/ict-facekit`` and ``meshes/menpo3d-james``).
    region : str
        An :func:`ict_regions` name.
    subset : array of int
        iBUG indices used as correspondences; the other landmarks are held out.

    Returns
    -------
    source, target, corr, (held_source_vertices, held_target_points)
        The held-out landmarks: source vertex indices and james's 3D points (iBUG order).
    """
    m = Path(data_dir) / "meshes"
    ict = load_mesh(m / "ict-facekit" / "generic_neutral_mesh.obj.gz")
    regions = ict_regions(m / "ict-facekit" / "vertex_indices.json")
    src, ids = select_region(ict, regions[region])
    remap = np.full(len(ict.vertices), -1)
    remap[ids] = np.arange(len(ids))
    lm_src = remap[regions["landmarks"]]
    james = load_mesh(m / "menpo3d-james" / "james.obj")
    pts, order = read_ljson(m / "menpo3d-james" / "james.ljson")
    lm_t = reorder_landmarks(pts, order)
    corr = Correspondences(SurfacePoints.from_vertices(lm_src[subset]), parse_points(lm_t[subset], james))
    held = np.setdiff1d(np.arange(68), subset)
    return src, james, corr, (lm_src[held], lm_t[held])
