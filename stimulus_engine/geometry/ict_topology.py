"""The ICT Face Model's topology: named vertex sets, the same for every ICT mesh.

:data:`ICT_GEOMETRY_RANGES` (the ICT-FaceKit README's tables) and :func:`ict_regions` (those plus
the lists of ``vertex_indices.json``) select regions by vertex set: the face for a
correspondence, the landmark vertices, the teeth or eyeballs of a rig
(:func:`stimulus_engine.characters.ict.load_ict_rig`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.geometry.mesh_io import read_json

__all__ = ["ICT_GEOMETRY_RANGES", "ict_regions"]

#: Vertex index ranges (inclusive) of the ICT Face Model topology, from the tables in the
#: ICT-FaceKit README ("Face Model Topology" and "Face Area Details"). Same for every ICT mesh
#: (neutral, identities, expressions), so they select regions by vertex set.
ICT_GEOMETRY_RANGES: dict[str, tuple[int, int]] = {
    "face": (0, 9408),
    "narrow_face": (0, 6705),
    "head_and_neck": (9409, 11247),
    "mouth_socket": (11248, 13293),
    "eye_socket_left": (13294, 13677),
    "eye_socket_right": (13678, 14061),
    "gums_and_tongue": (14062, 17038),
    "teeth": (17039, 21450),
    "eyeball_left": (21451, 23020),
    "eyeball_right": (23021, 24590),
    "lacrimal_fluid_left": (24591, 24794),
    "lacrimal_fluid_right": (24795, 24998),
    "eye_blend_left": (24999, 25022),
    "eye_blend_right": (25023, 25046),
    "eye_occlusion_left": (25047, 25198),
    "eye_occlusion_right": (25199, 25350),
    "eyelashes_left": (25351, 26034),
    "eyelashes_right": (26035, 26718),
}


def ict_regions(vertex_indices_json: str | os.PathLike | None = None) -> dict[str, np.ndarray]:
    """Named vertex sets of the ICT Face Model.

    The README's geometry ranges (:data:`ICT_GEOMETRY_RANGES`: ``face``, ``narrow_face``,
    ``teeth``, ...) plus, when ``vertex_indices.json`` is given, its lists: ``fitting``
    (``idx_to_fitting_verts``), ``rigid``, ``lap_rigid`` and ``landmarks`` (the 68 Multi-PIE
    landmark vertices, in iBUG order).
    """
    out = {k: np.arange(a, b + 1) for k, (a, b) in ICT_GEOMETRY_RANGES.items()}
    if vertex_indices_json is None:
        return out
    p = Path(vertex_indices_json)
    d = read_json(p, "ICT vertex_indices.json")
    keys = {
        "fitting": "idx_to_fitting_verts",
        "rigid": "idx_to_rigid_verts",
        "lap_rigid": "idx_to_lap_rigid_verts",
        "landmarks": "idx_to_landmark_verts",
    }
    for name, key in keys.items():
        if key not in d:
            raise AppealInputError(f"{p}: {key}: missing (expected a list of vertex indices)")
        arr = np.asarray(d[key], dtype=np.int64)
        out[name] = arr if name == "landmarks" else np.unique(arr)
    return out
