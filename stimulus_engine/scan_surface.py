"""A scan drawn as itself: its own surface and photographic texture, posed through a rig.

A mesh character (:mod:`stimulus_engine.mesh_character`) puts a rig's topology onto a scan; with
``topology: scan`` the grid then draws the *scan* rather than the rig: its own vertices, faces,
UVs and texture (hair and all), so the realistic level is the scan as photographed. The scan is
bound to the corresponded rig's skin — each scan vertex to its closest point there (triangle and
barycentric weights) — and every pose of the rig (an expression, a stylised shape) moves each
scan vertex by the rig's displacement at its bound point. Where the rig region does not reach
(the back of the head, hair, the neck) the nearest skin point's displacement carries the scan.

With eyes (:mod:`stimulus_engine.scan_eyes`), the drawn surface is the scan with its eye openings
cut, plus two eyeballs and their sockets: each eyeball follows the rig's eyeball by the similarity
(rotation, scale, shift) that best maps the rig's eyeball from its neutral onto its pose, so a
stylised shape's larger eyes and the lids' opening and closing move it as on the rig.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stimulus_engine.rig import FaceRig
from stimulus_engine.scan_eyes import EyeGeometry

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
    rigid : tuple of (drawn vertex indices, rig vertex indices)
        Drawn vertices (eyeballs) that move with a rig vertex set by its best similarity.
    """

    topology: FaceRig
    neutral: np.ndarray
    rig_neutral: np.ndarray
    corners: np.ndarray
    bary: np.ndarray
    rigid: tuple[tuple[np.ndarray, np.ndarray], ...] = ()

    def pose(self, rig_vertices: np.ndarray) -> np.ndarray:
        """Scan vertices for a pose of the rig (same topology as :attr:`rig_neutral`)."""
        from stimulus_engine.correspondence.alignment import umeyama

        rv = np.asarray(rig_vertices, np.float64)
        out = self.neutral + np.einsum("sk,skd->sd", self.bary, (rv - self.rig_neutral)[self.corners])
        for drawn, rig_set in self.rigid:
            out[drawn] = umeyama(self.rig_neutral[rig_set], rv[rig_set]).apply(self.neutral[drawn])
        return out


def _with_eyes(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray, face_uv: np.ndarray,
               eyes: EyeGeometry) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, list]:
    """The scan with its openings cut, then the eyeballs and the sockets, as one indexed mesh:
    vertices, faces, uv, face_uv, face part (0 skin, 1 eye, 2 socket) and each ball's vertices."""
    v, f, t, ft, part = [eyes.vertices], [faces[eyes.keep]], [uv], [face_uv[eyes.keep]], [np.zeros(int(eyes.keep.sum()))]
    n, nt, balls = len(vertices), len(uv), []
    pieces = [(b, bf, buv, 1) for b, bf, buv in zip(eyes.balls, eyes.ball_faces, eyes.ball_uv)]
    pieces += [(sv, sf, np.zeros((len(sv), 2)), 2) for sv, sf in eyes.sockets]
    for pv, pf, puv, k in pieces:
        if k == 1:
            balls.append(np.arange(n, n + len(pv)))
        v.append(pv), f.append(pf + n), t.append(puv), ft.append(pf + nt), part.append(np.full(len(pf), k))
        n, nt = n + len(pv), nt + len(puv)
    return (np.vstack(v), np.vstack(f).astype(np.int64), np.vstack(t), np.vstack(ft).astype(np.int64),
            np.concatenate(part).astype(np.int64), balls)


def bind_scan(rig: FaceRig, vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray, face_uv: np.ndarray,
              name: str = "scan", eyes: EyeGeometry | None = None) -> ScanSurface:
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
    eyes : EyeGeometry, optional
        Eye openings, eyeballs and sockets for the scan (:func:`stimulus_engine.scan_eyes.eye_geometry`);
        the eyeballs follow the rig's eyeballs (``rig.rigid_sets``, the nearest to each).
    """
    from stimulus_engine.correspondence.closest import SurfaceIndex

    v, f = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    t, ft = np.asarray(uv, np.float64), np.asarray(face_uv, np.int64)
    part, names, textures, rigid = np.zeros(len(f), np.int64), ("skin",), {}, ()
    if eyes is not None:
        v, f, t, ft, part, balls = _with_eyes(v, f, t, ft, eyes)
        names, textures = ("skin", "eye", "socket"), {"eye": eyes.texture}
        centres = np.array([rig.vertices[s].mean(axis=0) for s in rig.rigid_sets])
        if len(centres):
            rigid = tuple((b, rig.rigid_sets[int(np.argmin(np.linalg.norm(centres - v[b].mean(axis=0), axis=1)))])
                          for b in balls)
    skin_faces = rig.faces[rig.face_part == rig.part_names.index("skin")]
    hit = SurfaceIndex(rig.vertices, skin_faces).query(v)
    topology = FaceRig(name=name, vertices=v, faces=f, uv=t, face_uv=ft, face_part=part, part_names=names,
                       landmarks={}, skin=np.flatnonzero(np.isin(np.arange(len(v)), f[part == 0])),
                       part_textures=textures)
    return ScanSurface(topology, v, np.asarray(rig.vertices, np.float64).copy(), skin_faces[hit.face], hit.bary,
                       rigid)
