"""A scan drawn as itself: its own surface and photographic texture, posed through a rig.

A mesh character (:mod:`stimulus_engine.mesh_character`) puts a rig's topology onto a scan; with
``topology: scan`` the grid then draws the *scan* rather than the rig: its own vertices, faces,
UVs and texture (hair and all), so the realistic level is the scan as photographed. The scan is
bound to the corresponded rig's skin — each scan vertex to its closest point there (triangle and
barycentric weights) — and every pose of the rig (an expression, a stylised shape) moves each
scan vertex by the rig's displacement at its bound point. Where the rig region does not reach
(the back of the head, hair, the neck) the nearest skin point's displacement carries the scan.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stimulus_engine.rig import FaceRig

__all__ = ["ScanSurface", "bind_scan"]


@dataclass(frozen=True)
class ScanSurface:
    """A scan bound to a rig.

    Attributes
    ----------
    topology : FaceRig
        What the renderer draws: the scan's faces and UV layout as one textured ``skin`` part
        (its vertices are :attr:`neutral`).
    neutral : (S, 3) array
        The scan's vertices in the rig's frame.
    rig_neutral : (N, 3) array
        The corresponded rig's vertices the binding was made on.
    corners : (S, 3) int array
        Rig vertices of each scan vertex's bound triangle.
    bary : (S, 3) array
        Barycentric weights in that triangle.
    """

    topology: FaceRig
    neutral: np.ndarray
    rig_neutral: np.ndarray
    corners: np.ndarray
    bary: np.ndarray

    def pose(self, rig_vertices: np.ndarray) -> np.ndarray:
        """Scan vertices for a pose of the rig (same topology as :attr:`rig_neutral`)."""
        d = np.asarray(rig_vertices, np.float64) - self.rig_neutral
        return self.neutral + np.einsum("sk,skd->sd", self.bary, d[self.corners])


def bind_scan(rig: FaceRig, vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray, face_uv: np.ndarray,
              name: str = "scan") -> ScanSurface:
    """Bind a scan (already in the rig's frame) to the skin of a rig corresponded onto it.

    Parameters
    ----------
    rig : FaceRig
        The corresponded rig (its skin lies on the scan).
    vertices : (S, 3) array
        The scan's vertices in the rig's frame.
    faces : (F, 3) int array
    uv, face_uv
        The scan's exact UV layout (per-corner indices).
    name : str
        Name of the drawn topology.
    """
    from stimulus_engine.correspondence.closest import SurfaceIndex

    v = np.asarray(vertices, np.float64)
    skin_faces = rig.faces[rig.face_part == rig.part_names.index("skin")]
    hit = SurfaceIndex(rig.vertices, skin_faces).query(v)
    topology = FaceRig(name=name, vertices=v, faces=np.asarray(faces, np.int64), uv=np.asarray(uv, np.float64),
                       face_uv=np.asarray(face_uv, np.int64), face_part=np.zeros(len(faces), np.int64),
                       part_names=("skin",), landmarks={}, skin=np.arange(len(v)))
    return ScanSurface(topology, v, np.asarray(rig.vertices, np.float64).copy(), skin_faces[hit.face], hit.bary)
