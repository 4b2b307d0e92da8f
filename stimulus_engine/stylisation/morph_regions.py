"""Facial regions for part-based morphs (thesis §3.4, Fig. 3.1): which mesh gives the eyes, the
nose or the mouth, as per-vertex weights for :func:`stimulus_engine.stylisation.morph.partial_blend`.

A region is one or more blobs around iBUG-68 landmark groups of the base mesh (found in renders
by :func:`stimulus_engine.correspondence.auto_landmarks.detect_mesh_landmarks`, or given): full
weight within the blob (its landmarks' largest distance from their centre, × :data:`CORE`),
fading smoothly to nothing :data:`FALLOFF` blob radii further out.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.geometry.ramps import smoothstep

__all__ = ["CORE", "FALLOFF", "REGIONS", "parse_regions", "part_morph_sheet", "read_ibug", "region_weights"]

#: Region name -> iBUG-68 point groups (0-based), one blob per group.
REGIONS: dict[str, tuple[tuple[int, ...], ...]] = {
    "eyes": (tuple(range(36, 42)), tuple(range(42, 48))),
    "brows": (tuple(range(17, 22)), tuple(range(22, 27))),
    "nose": (tuple(range(27, 36)),),
    "mouth": (tuple(range(48, 68)),),
}
#: Full weight out to this many times the blob's landmark spread.
CORE = 1.3
#: The weight falls to zero over this many core radii beyond the core.
FALLOFF = 0.6


def parse_regions(text: str, n_meshes: int, where: str = "--regions") -> dict[str, int]:
    """``"eyes=1,mouth=2"`` -> ``{"eyes": 1, "mouth": 2}`` (mesh indices from 0; 0 is the base)."""
    out: dict[str, int] = {}
    for item in [x.strip() for x in str(text).split(",") if x.strip()]:
        name, sep, idx = item.partition("=")
        name = name.strip()
        if name not in REGIONS:
            raise AppealInputError(f"{where}: unknown region '{name}' (expected one of: {', '.join(REGIONS)})")
        if not sep:
            if n_meshes != 2:
                raise AppealInputError(f"{where}: '{name}': say which mesh gives it, e.g. {name}=1 (meshes 1..{n_meshes - 1})")
            idx = "1"
        try:
            k = int(idx)
        except ValueError:
            raise AppealInputError(f"{where}: '{item}': expected REGION=MESH with MESH a number (got '{idx}')") from None
        if not 1 <= k < n_meshes:
            raise AppealInputError(f"{where}: '{item}': mesh {k} does not exist (meshes 1..{n_meshes - 1} give "
                                   "regions; 0 is the base)")
        if name in out:
            raise AppealInputError(f"{where}: region '{name}' named twice")
        out[name] = k
    if not out:
        raise AppealInputError(f"{where}: expected REGION=MESH[,REGION=MESH...] (regions: {', '.join(REGIONS)})")
    return out


def region_weights(vertices: np.ndarray, ibug: np.ndarray, regions: Mapping[str, int], n_meshes: int,
                   core: float = CORE, falloff: float = FALLOFF) -> np.ndarray:
    """Per-vertex blend weights: each named region from its mesh, the rest from mesh 0.

    Parameters
    ----------
    vertices : (N, 3) array
        The base mesh (its landmarks ``ibug`` lie on it).
    ibug : (68, 3) array
    regions : mapping of str to int
        Region name (:data:`REGIONS`) -> the mesh that gives it.
    n_meshes : int

    Returns
    -------
    (N, n_meshes) array
        Rows sum to 1; regions that overlap share their vertices in proportion.
    """
    v = np.asarray(vertices, np.float64)
    p = np.asarray(ibug, np.float64)
    if p.shape != (68, 3):
        raise AppealInputError(f"landmarks: expected 68 iBUG points (got an array of shape {p.shape})")
    w = np.zeros((len(v), n_meshes))
    for name, k in regions.items():
        blob = np.zeros(len(v))
        for group in REGIONS[name]:
            pts = p[list(group)]
            c = pts.mean(axis=0)
            r = core * float(np.linalg.norm(pts - c, axis=1).max())
            d = np.linalg.norm(v - c, axis=1)
            blob = np.maximum(blob, 1.0 - smoothstep((d - r) / (falloff * r)))
        w[:, k] += blob
    total = w.sum(axis=1)
    over = total > 1
    w[over] /= total[over, None]
    w[:, 0] += 1.0 - w.sum(axis=1)
    return w


def read_ibug(path, mesh=None, name: str = "mesh") -> np.ndarray:
    """68 iBUG points for a part morph's base: ``auto`` (found in renders of ``mesh``), a menpo
    ``.ljson`` file, or a JSON list of 68 [x, y, z] points in iBUG order."""
    import json
    from pathlib import Path

    if str(path) == "auto":
        from stimulus_engine.correspondence.auto_landmarks import detect_mesh_landmarks

        return detect_mesh_landmarks(mesh, name=name).points
    path = Path(path)
    if path.suffix.lower() == ".ljson":
        from stimulus_engine.correspondence.landmark_sets import read_ljson, reorder_landmarks

        pts, order = read_ljson(path)
        return np.asarray(reorder_landmarks(pts, order), np.float64)
    try:
        pts = np.asarray(json.loads(path.read_text()), np.float64)
    except (OSError, ValueError) as exc:
        raise AppealInputError(f"{path}: --landmarks: cannot read 68 [x, y, z] points ({exc})") from None
    if pts.shape != (68, 3):
        raise AppealInputError(f"{path}: --landmarks: expected 68 [x, y, z] points in iBUG order (got shape {pts.shape})")
    return pts


def part_morph_sheet(meshes, result, ibug: np.ndarray, labels, path, width: int = 360) -> None:
    """A sheet of the base, the donors and the part morph, rendered alike (front view, framed on
    the base's eyes and chin)."""
    from PIL import Image

    from stimulus_engine.render import contact_sheet, face_camera, render_mesh

    eyes = np.asarray(ibug)[36:48].mean(axis=0)
    cam = face_camera(eyes, 1.3 * float(np.linalg.norm(eyes - np.asarray(ibug)[8])))
    shots = [render_mesh(m, width=width, height=width, camera=cam, lighting="gi_soft") for m in [*meshes, result]]
    Image.fromarray(contact_sheet(shots, len(shots), thumb_width=width, labels=list(labels))).save(path)
