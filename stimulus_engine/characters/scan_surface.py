"""A scan drawn as itself: its own surface and photographic texture, posed through a rig.

A mesh character (:mod:`stimulus_engine.characters.mesh_character`) puts a rig's topology onto a scan; with
``topology: scan`` the grid then draws the *scan* rather than the rig: its own vertices, faces,
UVs and texture (hair and all), so the realistic level is the scan as photographed. The scan is
bound to the corresponded rig's skin — each scan vertex to its closest point there (triangle and
barycentric weights) — and every pose of the rig (an expression, a stylised shape) moves each
scan vertex by the rig's displacement at its bound point. Where the rig region does not reach
(the back of the head, hair, the neck) the nearest skin point's displacement carries the scan.

With eyes (:mod:`stimulus_engine.characters.scan_eyes`), the drawn surface is the scan with its eye openings
cut, plus two eyeballs and their sockets: each eyeball follows the rig's eyeball by the similarity
(rotation, scale, shift) that best maps the rig's eyeball from its neutral onto its pose, so a
stylised shape's larger eyes and the lids' opening and closing move it as on the rig.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stimulus_engine.parts.eyelashes import ROWS as LASH_ROWS
from stimulus_engine.parts.eyelashes import lash_texture
from stimulus_engine.characters.rig import FaceRig
from stimulus_engine.characters.scan_eyes import EyeGeometry

__all__ = ["ScanSurface", "bind_scan", "wear_rig_hair"]


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
    follow : tuple of (drawn vertex indices, rig vertex indices)
        Drawn vertices that are rig vertices (the mouth's inside), posed as on the rig.
    """

    topology: FaceRig
    neutral: np.ndarray
    rig_neutral: np.ndarray
    corners: np.ndarray
    bary: np.ndarray
    rigid: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    follow: tuple[tuple[np.ndarray, np.ndarray], ...] = ()

    def pose(self, rig_vertices: np.ndarray) -> np.ndarray:
        """Scan vertices for a pose of the rig (same topology as :attr:`rig_neutral`)."""
        from stimulus_engine.correspondence.alignment import umeyama

        rv = np.asarray(rig_vertices, np.float64)
        out = self.neutral + np.einsum("sk,skd->sd", self.bary, (rv - self.rig_neutral)[self.corners])
        for drawn, rig_set in self.rigid:
            out[drawn] = umeyama(self.rig_neutral[rig_set], rv[rig_set]).apply(self.neutral[drawn])
        for drawn, rig_vertices_of in self.follow:
            out[drawn] = rv[rig_vertices_of]
        return out


def wear_rig_hair(scan: ScanSurface, hair) -> ScanSurface:
    """``scan`` drawn with ``hair`` fitted to its rig (:func:`stimulus_engine.parts.hair.fit_hair`
    on the corresponded rig, laid over the scan's own surface): the rig vertices the hair is bound
    to are appended to the drawn topology as vertices of no face that follow the rig (like the
    mouth's inside), and the hair is re-bound to them, so every pose of the rig moves the hair
    as it moves the rig's whole head (a scan's own surface may not reach the back of the head)."""
    from dataclasses import replace

    used, inv = np.unique(hair.corners, return_inverse=True)
    n = len(scan.neutral)
    drawn = np.arange(n, n + len(used))
    rig_at = scan.rig_neutral[used]
    topology = replace(scan.topology, vertices=np.vstack([scan.topology.vertices, rig_at]),
                       hair=replace(hair, corners=drawn[inv.reshape(-1, 3)]))
    return replace(scan, topology=topology, neutral=np.vstack([scan.neutral, rig_at]),
                   corners=np.vstack([scan.corners, np.repeat(used[:, None], 3, axis=1)]),
                   bary=np.vstack([scan.bary, np.tile([1.0, 0.0, 0.0], (len(used), 1))]),
                   follow=(*scan.follow, (drawn, used)))


def _eye_pieces(eyes: EyeGeometry) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, int]]:
    """The eyeballs (part 1), sockets (part 2) and lashes (part 3) as (vertices, faces, uv, part) pieces."""
    return ([(b, bf, buv, 1) for b, bf, buv in zip(eyes.balls, eyes.ball_faces, eyes.ball_uv)]
            + [(sv, sf, np.zeros((len(sv), 2)), 2) for sv, sf in eyes.sockets]
            + [(lv, lf, luv, 3) for lv, lf, luv in eyes.lashes])


def _eye_landmarks(vertices: np.ndarray, balls: list[np.ndarray]) -> dict[str, np.ndarray]:
    """The drawn eyeballs (right first) and their pupil rings: each template looks along +z
    (:func:`stimulus_engine.parts.eyes.eyeball_asset`), so its gaze axis is +z in the neutral."""
    from stimulus_engine.characters.gaze import SIDES, pupil_ring
    from stimulus_engine.parts.eyes import fit_sphere

    out = {}
    for side, ball in zip(SIDES, balls):
        out[f"eye_{side}"] = ball
        out[f"pupil_{side}"] = pupil_ring(vertices, ball, fit_sphere(vertices[ball])[0], np.array([0.0, 0.0, 1.0]))
    return out


def _rig_pieces(rig: FaceRig, parts: tuple[str, ...], first: int) -> tuple[list, list[np.ndarray]]:
    """The rig's ``parts`` as pieces (part numbers from ``first``) and each piece's rig vertices."""
    pieces, verts = [], []
    for k, name in enumerate(parts):
        sel = rig.face_part == rig.part_names.index(name)
        used, inv = np.unique(rig.faces[sel], return_inverse=True)
        pieces.append((rig.vertices[used], inv.reshape(-1, 3), np.zeros((len(used), 2)), first + k))
        verts.append(used)
    return pieces, verts


def _with_pieces(v: np.ndarray, f: np.ndarray, t: np.ndarray, ft: np.ndarray, part: np.ndarray,
                 pieces: list) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
    """The mesh with ``pieces`` (vertices, faces, uv, part) appended, and each piece's new vertex indices."""
    vs, fs, ts, fts, ps, where = [v], [f], [t], [ft], [part], []
    n, nt = len(v), len(t)
    for pv, pf, puv, k in pieces:
        where.append(np.arange(n, n + len(pv)))
        vs.append(pv), fs.append(pf + n), ts.append(puv), fts.append(pf + nt), ps.append(np.full(len(pf), k))
        n, nt = n + len(pv), nt + len(puv)
    return (np.vstack(vs), np.vstack(fs).astype(np.int64), np.vstack(ts), np.vstack(fts).astype(np.int64),
            np.concatenate(ps).astype(np.int64), where)


def _moving_faces(rig: FaceRig, skin_faces: np.ndarray, shapes: tuple[str, ...]) -> np.ndarray:
    """The skin triangles the rig's ``shapes`` carry: most of their vertices move at least half as
    far as the farthest under one of them."""
    out = np.zeros(len(skin_faces), bool)
    for name in shapes:
        if name in rig.blendshapes:
            d = np.linalg.norm(rig.blendshapes[name], axis=1)
            out |= (d[skin_faces] > 0.5 * d.max()).mean(axis=1) >= 0.5
    return out


#: How each kind of cut splits a scan's binding: the rig shapes that move one side, and which
#: side (+1 above the line, -1 below) they move.
SPLITS: dict[str, tuple[tuple[str, ...], int]] = {
    "lips": (("jawOpen",), -1),
}


def bind_scan(rig: FaceRig, vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray, face_uv: np.ndarray,
              name: str = "scan", eyes: EyeGeometry | None = None, keep: np.ndarray | None = None,
              splits: dict[str, np.ndarray] | None = None, inside_parts: tuple[str, ...] = ()) -> ScanSurface:
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
        Eye openings, eyeballs and sockets for the scan (:func:`stimulus_engine.characters.scan_eyes.eye_geometry`);
        the eyeballs follow the rig's eyeballs (``rig.rigid_sets``, the nearest to each).
    keep : (F,) bool array, optional
        The scan triangles to draw (default: all; with ``eyes``, those outside its openings).
    splits : dict of str to (S,) int array, optional
        Cut lines (a key of :data:`SPLITS`: ``lips``) and the side of each scan vertex (+1 above,
        -1 below, 0 away from it; :func:`stimulus_engine.characters.scan_cut.cut_along`): one side is bound
        only to the rig's skin the line's shapes move (the jaw, below the lips), the other only
        to the skin they do not, so the surface parts along the cut.
    inside_parts : tuple of str
        Rig parts drawn with the scan, moving as on the rig (e.g. ``mouth``, ``teeth``, ``tongue``
        behind cut lips).
    """
    from stimulus_engine.geometry.closest import SurfaceIndex

    v, f = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    t, ft = np.asarray(uv, np.float64), np.asarray(face_uv, np.int64)
    keep = (np.ones(len(f), bool) if eyes is None else eyes.keep) if keep is None else keep
    f, ft = f[keep], ft[keep]
    part, names, textures, rigid, follow, landmarks = np.zeros(len(f), np.int64), ["skin"], {}, (), (), {}
    n_scan = len(v)
    lashes: list[np.ndarray] = []
    margins: list[tuple[np.ndarray, np.ndarray]] = []  # (drawn vertices, the scan vertex each stands on)
    if eyes is not None:
        uv_of = np.zeros(n_scan, np.int64)  # a texture coordinate of each scan vertex (its last corner's)
        uv_of[f.ravel()] = ft.ravel()
        # the lids' margins stand on the rim: the wet line and caruncle (part 4, mucosa) and the
        # upper lid's shaded underside (part 2, the socket's colour); UVs for the layout only
        wet_dry = [(mv, mf[w if k == 4 else ~w], t[uv_of[roots]], k) for mv, mf, roots, w in eyes.margins
                   for k in (4, 2)]
        v, f, t, ft, part, pieces = _with_pieces(v, f, t, ft, part, _eye_pieces(eyes) + wet_dry)
        margins = list(zip(pieces[len(pieces) - len(wet_dry):], [roots for _, _, roots, _ in eyes.margins
                                                                 for _ in (4, 2)]))
        pieces = pieces[:len(pieces) - len(wet_dry)]
        balls, lashes = pieces[:len(eyes.balls)], pieces[len(eyes.balls) + len(eyes.sockets):]
        names, textures = ["skin", "eye", "socket", "lashes", "margin"], {"eye": eyes.texture, "lashes": lash_texture()}
        landmarks = _eye_landmarks(v, balls)
        centres = np.array([rig.vertices[s].mean(axis=0) for s in rig.rigid_sets])
        if len(centres):
            rigid = tuple((b, rig.rigid_sets[int(np.argmin(np.linalg.norm(centres - v[b].mean(axis=0), axis=1)))])
                          for b in balls)
    if inside_parts:
        pieces, follow = _rig_pieces(rig, inside_parts, len(names))
        v, f, t, ft, part, drawn = _with_pieces(v, f, t, ft, part, pieces)
        follow = tuple(zip(drawn, follow))
        names += list(inside_parts)
    skin_faces = rig.faces[rig.face_part == rig.part_names.index("skin")]
    corners, bary = np.zeros((len(v), 3), np.int64), np.zeros((len(v), 3))
    free = np.ones(len(v), bool)
    groups = []
    for kind, side in (splits or {}).items():
        shapes, moving_side = SPLITS[kind]
        moving = _moving_faces(rig, skin_faces, shapes)
        if not moving.any():
            continue
        side = np.concatenate([side, np.zeros(len(v) - n_scan, np.int64)])
        groups += [(np.flatnonzero(free & (side == moving_side)), skin_faces[moving]),
                   (np.flatnonzero(free & (side == -moving_side)), skin_faces[~moving])]
        free &= side == 0
    groups.append((np.flatnonzero(free), skin_faces))
    for idx, sf in groups:
        if len(idx):
            hit = SurfaceIndex(rig.vertices, sf).query(v[idx])
            corners[idx], bary[idx] = sf[hit.face], hit.bary
    for drawn, roots in margins:  # a lid's margin moves with the rim it stands on
        corners[drawn], bary[drawn] = corners[roots], bary[roots]
    for strip in lashes:  # a lash moves with the lid point at its root
        root = strip[np.arange(len(strip)) % (len(strip) // LASH_ROWS)]
        corners[strip], bary[strip] = corners[root], bary[root]
    topology = FaceRig(name=name, vertices=v, faces=f, uv=t, face_uv=ft, face_part=part, part_names=tuple(names),
                       landmarks=landmarks, skin=np.flatnonzero(np.isin(np.arange(len(v)), f[part == 0])),
                       part_textures=textures)
    return ScanSurface(topology, v, np.asarray(rig.vertices, np.float64).copy(), corners, bary, rigid, follow)
