"""Any face mesh as a grid character: the rig is corresponded onto it with ElastiFace (issue 4).

A user's mesh (a scan, an artist's stylised head, the MediaPipe face ...) has its own
tessellation and UV layout and no expressions. :func:`correspond_rig` deforms a rig's skin
region (ICT Face Model or the procedural head) onto it with
:func:`stimulus_engine.correspond` from a few landmark pairs (thesis §3.2), so the character
becomes a :class:`~stimulus_engine.characters.rig.FaceRig` *in the rig's topology*:

* its neutral is the user's shape (in the rig's frame and scale: the correspondence's
  similarity alignment is undone, so cameras, lights and landmarks work as for the rig);
* expressions are carried onto it from the rig by deformation transfer (thesis ch. 4);
* its albedo is the user's texture re-laid into the rig's UV layout with
  :func:`stimulus_engine.transfer_texture` (thesis §3.3), so materials can be swapped with
  every other character in that layout ("material from another character" across layouts);
* parts outside the corresponded region (eyeballs, teeth, mouth, the rest of the head) follow
  the region by interpolated displacements; eyeballs move rigidly and scale with the eye width.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from appeal.errors import AppealInputError
from appeal.logs import logger
from stimulus_engine.characters.lashes import seat_lashes
from stimulus_engine.characters.rig import FaceRig
from stimulus_engine.characters.scan_regions import skin_texels

__all__ = ["MeshCharacter", "auto_landmark_points", "correspond_rig", "front_region", "rig_skin_mesh", "source_landmark_names"]


def front_region(rig: FaceRig) -> np.ndarray:
    """Skin vertices in front of the ears (from 10 % of the face width behind the ``face_left``/
    ``face_right`` landmarks): what a face-only mesh (a mask like MediaPipe's, a frontal scan) covers."""
    lm = rig.landmark_points()
    z = (lm["face_left"][2] + lm["face_right"][2]) / 2 - 0.1 * float(np.linalg.norm(lm["face_left"] - lm["face_right"]))
    skin = np.asarray(rig.skin, np.int64)
    return skin[rig.vertices[skin, 2] > z]


@dataclass
class MeshCharacter:
    """The result of :func:`correspond_rig`.

    Attributes
    ----------
    rig : FaceRig
        The corresponded character (rig topology, the user's shape, the transferred albedo as
        ``texture`` when the mesh had one).
    region : (n,) int array
        Rig vertices that were corresponded onto the mesh.
    metrics : dict
        The correspondence's fit metrics (distances relative to the mesh's bbox diagonal).
    transferred : (H, W) bool array or None
        Texels of ``rig.texture`` that came from the user's texture (the rest is painted).
    left_out : tuple of str
        Landmark pairs not used because their rig point is also another landmark's aimed
        elsewhere (a coarse rig's landmarks can share a vertex).
    alignment : Similarity or None
        The similarity that took the rig into the mesh's frame (its inverse brings the mesh
        into the rig's frame, where the character lives).
    """

    rig: FaceRig
    region: np.ndarray
    metrics: dict = field(default_factory=dict)
    transferred: np.ndarray | None = None
    left_out: tuple[str, ...] = ()
    alignment: object = None


def source_landmark_names(rig: FaceRig) -> list[str]:
    """Rig landmarks usable as correspondence points (skin landmarks of at most 3 vertices)."""
    skin = set(np.asarray(rig.skin).tolist())
    return [k for k, idx in rig.landmarks.items() if len(idx) <= 3 and all(int(i) in skin for i in idx)]


def rig_skin_mesh(rig: FaceRig, region: np.ndarray | None = None) -> tuple[trimesh.Trimesh, np.ndarray]:
    """The rig's skin triangles inside ``region`` (default: all skin) as a mesh with the rig's UVs.

    Returns the mesh and the rig vertex index of each of its vertices.
    """
    from stimulus_engine.geometry.mesh_io import select_region

    ids = np.asarray(rig.skin if region is None else region, np.int64)
    inside = np.zeros(len(rig.vertices), bool)
    inside[ids] = True
    faces = np.flatnonzero((rig.face_part == rig.part_names.index("skin")) & inside[rig.faces].all(axis=1))
    whole = trimesh.Trimesh(rig.vertices, rig.faces, process=False)
    if rig.uv is not None and rig.face_uv is not None:
        whole.metadata["uv_coords"] = rig.uv
        whole.metadata["face_uv"] = rig.face_uv
    sub, vid = select_region(whole, np.unique(rig.faces[faces]), faces=faces)
    return sub, vid


def _affine_fit(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Least-squares affine map (4 × 3, homogeneous rows) with ``[src 1] @ A ≈ dst``."""
    h = np.column_stack([src, np.ones(len(src))])
    return np.linalg.lstsq(h, dst, rcond=None)[0]


def _apply_affine(A: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.column_stack([p, np.ones(len(p))]) @ A


def _carry_along(v0: np.ndarray, known: np.ndarray, new_known: np.ndarray, falloff: float, k: int = 12) -> np.ndarray:
    """Positions of all vertices when ``known`` move to ``new_known``.

    Every other vertex follows the least-squares affine map of the known vertices, plus the
    residual of its nearest known vertices (inverse-distance weights), faded out with a Gaussian
    of width ``falloff`` in distance from them: the rest of a head follows a corresponded face
    smoothly without inheriting its local detail far away (no cone where a forehead ends).
    """
    A = _affine_fit(v0[known], new_known)
    resid = new_known - _apply_affine(A, v0[known])
    out = _apply_affine(A, v0)
    out[known] = new_known
    rest = np.setdiff1d(np.arange(len(v0)), known)
    if rest.size:
        d, j = cKDTree(v0[known]).query(v0[rest], k=min(k, len(known)))
        d, j = d.reshape(len(rest), -1), j.reshape(len(rest), -1)
        w = 1.0 / np.maximum(d, 1e-9) ** 2
        r = (w[..., None] * resid[j]).sum(axis=1) / w.sum(axis=1, keepdims=True)
        out[rest] += r * np.exp(-((d[:, 0] / falloff) ** 2))[:, None]
    return out


def _shared_points(sv: np.ndarray, sw: np.ndarray, target_pos: np.ndarray, tol: float) -> tuple[np.ndarray, list[int]]:
    """Pairs to keep, and pairs to drop because their rig point is also another landmark's.

    A coarse rig can put two landmarks on one vertex (the procedural head at low resolution:
    both inner eye corners on the nose ridge, the top and bottom of the mouth on one lip
    vertex). One point cannot sit on two places, and pulling it towards both (or their mean)
    crumples the face, so such pairs are left out; pairs with the same point *and* the same
    target (within ``tol``) are kept once.
    """
    groups: dict[tuple, list[int]] = {}
    for k in range(len(sv)):
        groups.setdefault(tuple(sorted(zip(sv[k].tolist(), np.round(sw[k], 9).tolist()))), []).append(k)
    keep, drop = [], []
    for g in groups.values():
        if np.linalg.norm(target_pos[g] - target_pos[g].mean(axis=0), axis=1).max() <= tol:
            keep.append(g[0])
        else:
            drop += g
    return np.array(sorted(keep), np.int64), sorted(drop)


def _landmark_warp(rig_points: np.ndarray, mesh_points: np.ndarray):
    """Thin-plate spline from rig landmarks to their mesh points (a callable on (n, 3) arrays):
    every landmark lands on its point, the face between them follows smoothly."""
    from scipy.interpolate import RBFInterpolator

    return RBFInterpolator(rig_points, mesh_points, kernel="thin_plate_spline")


def mask_crop(rig: FaceRig, region: np.ndarray, mesh: trimesh.Trimesh, to_mesh) -> np.ndarray:
    """The part of ``region`` that corresponds to an open mesh (a face mask such as MediaPipe's).

    Region vertices are moved into the mesh's frame with ``to_mesh`` (a callable on (n, 3)
    arrays, e.g. the landmark thin-plate spline) and kept where their closest point on the mesh
    lies inside it, not on its border (or within 0.1 % of its diagonal of the mesh: a landmark
    on the outline); the kept set is closed and opened by one vertex ring, holes are filled, and
    the largest piece is kept, so the result is one disk whose border loop follows the mesh's
    outline.

    Returns the kept rig vertex ids (a subset of ``region``).
    """
    from scipy.sparse.csgraph import connected_components

    from stimulus_engine.geometry.closest import SurfaceIndex
    from stimulus_engine.geometry.mesh_ops import boundary_loops, grow_rings, vertex_adjacency

    sub, vid = rig_skin_mesh(rig, np.asarray(region, np.int64))
    f = np.asarray(sub.faces, np.int64)
    n = len(vid)
    mv = np.asarray(mesh.vertices, float)
    cp = SurfaceIndex(mv, np.asarray(mesh.faces, np.int64)).query(to_mesh(np.asarray(sub.vertices, float)))
    on = np.asarray(cp.distance) < 1e-3 * float(np.linalg.norm(np.ptp(mv, axis=0)))
    inside = ~np.asarray(cp.on_boundary, bool) | on
    adj = vertex_adjacency(f, n)
    keep = ~grow_rings(~grow_rings(inside, adj), adj) & (inside | ~on)  # closing: fill one-ring notches
    keep = grow_rings(~grow_rings(~keep, adj), adj) | (keep & on)  # opening: drop one-ring spikes (not the landmarks)
    # holes: pieces of the dropped part that do not reach the region's own border
    border = np.zeros(n, bool)
    for loop in boundary_loops(f):
        border[loop] = True
    drop = np.flatnonzero(~keep)
    if drop.size:
        _, lab = connected_components(adj[drop][:, drop], directed=False)
        outside = np.unique(lab[border[drop]])
        keep[drop[~np.isin(lab, outside)]] = True
    # the largest piece (by faces)
    fk = keep[f].all(axis=1)
    _, lab = connected_components(vertex_adjacency(f[fk], n), directed=False)
    used = np.unique(f[fk])
    big = np.bincount(lab[used]).argmax()
    keep = np.zeros(n, bool)
    keep[used[lab[used] == big]] = True
    return vid[keep]


def _outline_pairs(source: trimesh.Trimesh, mesh: trimesh.Trimesh, to_mesh, up: np.ndarray,
                   anchor_targets: np.ndarray):
    """Boundary correspondences (thesis Fig. 3.5) tying the source's outer border loop to the
    mesh's outer border loop by relative arc length between anchors: the mesh loop vertices
    at the landmarks' targets that lie on it (``anchor_targets``, mesh frame) plus the loop's
    top end (along ``up``, unless an anchor is near it), each paired with the source loop
    vertex whose ``to_mesh`` image is nearest."""
    from stimulus_engine.correspondence import boundary_correspondences
    from stimulus_engine.geometry.mesh_ops import boundary_loops

    s_loop = boundary_loops(np.asarray(source.faces))[0]
    t_loop = boundary_loops(np.asarray(mesh.faces))[0]
    tp = np.asarray(mesh.vertices, float)[t_loop]
    size = float(np.linalg.norm(np.ptp(tp, axis=0)))
    on = [int(np.argmin(np.linalg.norm(tp - a, axis=1))) for a in anchor_targets]
    on = [k for k, a in zip(on, anchor_targets) if np.linalg.norm(tp[k] - a) < 1e-3 * size]
    top = int(np.argmax(tp @ up))
    ends = sorted(set(on) | ({top} if all(np.linalg.norm(tp[k] - tp[top]) > 0.2 * size for k in on) else set()))
    if len(ends) < 3:  # too few on the outline: its four ends
        side = np.cross(up, tp.mean(axis=0) - np.asarray(mesh.vertices, float).mean(axis=0))
        ends = sorted({top, int(np.argmin(tp @ up)), int(np.argmin(tp @ side)), int(np.argmax(tp @ side))})
    s_img = to_mesh(np.asarray(source.vertices, float)[s_loop])
    anchors = [(int(s_loop[np.argmin(np.linalg.norm(s_img - tp[e], axis=1))]), int(t_loop[e])) for e in ends]
    return boundary_correspondences(np.asarray(source.vertices), np.asarray(source.faces),
                                    np.asarray(mesh.vertices), np.asarray(mesh.faces), anchors)


#: Skin closer to an eyeball's centre than this many ball radii lines its socket and moves with
#: it, landmark vertices excepted (ICT's socket lining lies within 0.48-0.93 radii, its lid margins
#: further out; a procedural head's outer eye corner lies at 0.84).
SOCKET_DEPTH = 0.97


def _socket_similarity(v0: np.ndarray, new_v: np.ndarray, ball: np.ndarray, skin: np.ndarray,
                       rotation: np.ndarray):
    """Similarity of the skin around an eyeball (the skin vertices within 1.6 ball radii of its
    centre, from their old to their new places) with the head's ``rotation``: the best uniform
    scale and translation only. Each socket's own rotation turned the eyes of a scan with
    closed lids 13-21 degrees apart (a squint, the iris sunk behind the sclera)."""
    from stimulus_engine.correspondence import Similarity

    c = v0[ball].mean(axis=0)
    r = float(np.linalg.norm(v0[ball] - c, axis=1).max())
    d = np.linalg.norm(v0[skin] - c, axis=1)
    near = skin[d < 1.6 * r]
    if len(near) < 6:
        near = skin[np.argsort(d)[:12]]
    x, y = v0[near], new_v[near]
    xc, yc = x - x.mean(axis=0), y - y.mean(axis=0)
    rx = xc @ rotation.T
    scale = float(np.sum(yc * rx) / max(np.sum(rx * rx), 1e-12))
    return Similarity(scale, rotation, y.mean(axis=0) - scale * rotation @ x.mean(axis=0))


def auto_landmark_points(rig: FaceRig, mesh: trimesh.Trimesh, region: np.ndarray | None = None, *,
                         name: str = "mesh", min_confidence: float = 0.4,
                         found: object | None = None) -> dict[str, tuple[float, float, float]]:
    """Rig landmarks found on ``mesh`` automatically (``landmarks: auto``).

    The mesh's 68 iBUG points come from
    :func:`stimulus_engine.correspondence.auto_landmarks.detect_mesh_landmarks`; each usable rig
    landmark inside ``region`` (default: all skin) with an iBUG counterpart
    (:data:`stimulus_engine.characters.rig.IBUG_LANDMARKS`) gets the mean of its points, unless their mean
    confidence is below ``min_confidence`` (the jaw line, a silhouette for the detector, often is).
    ``found``: a detection already made on ``mesh`` (a ``MeshLandmarks``) to use instead.
    """
    from stimulus_engine.correspondence.auto_landmarks import detect_mesh_landmarks
    from stimulus_engine.characters.rig import IBUG_LANDMARKS

    found = detect_mesh_landmarks(mesh, name=name) if found is None else found
    usable = set(source_landmark_names(rig))
    region = np.asarray(rig.skin if region is None else region, np.int64)
    out = {}
    for landmark, idx in IBUG_LANDMARKS.items():
        ids = list(idx)
        if landmark in usable and np.isin(rig.landmarks[landmark], region).all() \
                and found.confidence[ids].mean() >= min_confidence:
            out[landmark] = tuple(float(x) for x in found.points[ids].mean(axis=0))
    logger.info("%s: automatic landmarks (front %s, %d views): %s", name, found.front, found.views, ", ".join(out))
    return out


def _painted_fill(rig: FaceRig, size: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The rig's painted albedo and region masks at ``size``, painted at half of it (at most
    1024) and enlarged: it only fills what the mesh's texture does not cover, and painting is
    the slowest step of a rig character's texture (1.7 s at 1024 px)."""
    from PIL import Image

    from stimulus_engine.characters.skin_maps import rig_albedo

    half = min(max(size // 2, 64), 1024)
    if half >= size:
        return rig_albedo(rig, size=size)
    painted, masks = rig_albedo(rig, size=half)
    up = np.asarray(Image.fromarray(np.asarray(painted, np.uint8)).resize((size, size), Image.BICUBIC), np.float64)
    return up, {k: np.asarray(Image.fromarray(np.asarray(m, np.float32)).resize((size, size), Image.BILINEAR))
                for k, m in masks.items()}


#: The inside of the lips (their faces turned away from the mesh's surface they lie on, within
#: this share of the mouth's width of its centre; cosine below :data:`INNER_LIP_COS`) ...
INNER_LIP_REACH, INNER_LIP_COS = 0.6, 0.3
#: ... is drawn in the lips' mean colour times this (wet mucosa in the lips' shade): a closed-lipped
#: scan gives the rig's inner lips the texels of its lip line, and a rig's neutral lips, parted a
#: little, showed a pale band between them (Lee Perry-Smith).
MUCOSA_SHADE = 0.6


def _inner_lip_faces(deformed: trimesh.Trimesh, mesh: trimesh.Trimesh, mouth_left: np.ndarray,
                     mouth_right: np.ndarray) -> np.ndarray:
    """(F,) bool over ``deformed``'s faces (the rig region on the mesh): the inside of the lips,
    faces near the mouth turned away from the mesh's surface at their closest point there (a
    lip's inner face looks down or up into the mouth where the closed scan looks forward)."""
    from stimulus_engine.geometry.closest import SurfaceIndex

    centres = np.asarray(deformed.triangles_center)
    mouth, width = (mouth_left + mouth_right) / 2, float(np.linalg.norm(mouth_left - mouth_right))
    near = np.linalg.norm(centres - mouth, axis=1) < INNER_LIP_REACH * width
    out = np.zeros(len(centres), bool)
    if near.any():
        hit = SurfaceIndex(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces)).query(centres[near])
        facing = np.einsum("fd,fd->f", np.asarray(deformed.face_normals)[near], np.asarray(mesh.face_normals)[hit.face])
        out[near] = facing < INNER_LIP_COS
    return out


def _teeth_behind_lips(rig: FaceRig, v: np.ndarray, lips: np.ndarray, gap: float) -> None:
    """Move the teeth and tongue back (-z, in place) until no tooth comes through the skin around
    the mouth: the rig's mouth inside, moved with the lips, fits the rig's lips, and a thinner or
    flatter mouth would otherwise show teeth through closed lips."""
    from stimulus_engine.geometry.polyline2d import push_behind

    names = [p for p in ("teeth", "tongue") if p in rig.part_names]
    if "teeth" not in names:
        return
    teeth = np.unique(rig.faces[rig.face_part == rig.part_names.index("teeth")])
    moved = np.unique(rig.faces[np.isin(rig.face_part, [rig.part_names.index(p) for p in names])])
    shift = push_behind(v[teeth], v[lips], gap)[0] - v[teeth[0]]
    v[moved] += shift


def correspond_rig(rig: FaceRig, mesh: trimesh.Trimesh, landmarks: Mapping[str, object], *,
                   region: np.ndarray | None = None, texture: np.ndarray | None = None,
                   texture_size: int = 1024, params: object | None = None, name: str | None = None,
                   where: str = "mesh", maps: Mapping[str, np.ndarray] | None = None,
                   relay_texture: bool = True) -> MeshCharacter:
    """Correspond ``rig`` onto a user mesh and return the mesh as a character in the rig's topology.

    Parameters
    ----------
    rig : FaceRig
        The rig supplying topology, parts, landmarks and expressions (ICT or procedural).
    mesh : trimesh.Trimesh
        The user's face mesh (any tessellation and UV layout; see
        :func:`stimulus_engine.load_mesh`).
    landmarks : mapping of str to point
        Rig landmark name (see :func:`source_landmark_names`, e.g. ``nose_tip``,
        ``eye_right_outer``, ``mouth_left``, ``chin``) → the corresponding point on ``mesh``: a
        vertex index or ``[x, y, z]`` (snapped to the surface). At least 6 pairs; 12–16 spread
        over eyes, nose, mouth and face outline work best (thesis §3.2.1).
    region : int array, optional
        Rig vertices to correspond (default: its skin). For a face-only mesh give the face
        region (e.g. ICT ``narrow_face``) so the back of the head is not pulled onto it.
    texture : (H, W, 3) uint8 array, optional
        The mesh's albedo in *its* UV layout (default: the mesh's own texture, if any).
    texture_size : int
        Size of the albedo re-laid into the rig's layout.
    params : CorrespondParams, optional
        ElastiFace weights (default: the thesis's).
    name : str, optional
        Name of the new rig.
    where : str
        Prefix of error messages (e.g. ``grid.yaml: characters.toon.mesh``).
    maps : mapping, optional
        ``normal`` (H, W, 3) tangent-space and/or ``specular`` (H, W) uint8 maps in the mesh's
        UV layout; re-laid into the rig's layout like the texture (``rig.texture_maps``; flat
        normal and mid-grey specular where the mesh does not cover the rig). A tangent-space
        normal map stays right only where both layouts orient u and v alike on the surface
        (u to the subject's left, v up, not mirrored); see docs/stimuli.md.
    relay_texture : bool
        False: leave texture and maps out (the mesh is drawn as itself and keeps its own).

    Raises
    ------
    AppealInputError
        Unknown landmark names, too few pairs, points off the mesh, texture without UVs.
    """
    from stimulus_engine.correspondence import (
        CorrespondParams,
        Correspondences,
        SurfacePoints,
        correspond,
        parse_points,
        umeyama,
    )
    from stimulus_engine.geometry.mesh_ops import boundary_loops
    from stimulus_engine.characters.skin_maps import FLAT_NORMAL
    from stimulus_engine.geometry.mesh_io import mesh_uv_layout, texture_image
    from stimulus_engine.correspondence.texture_transfer import transfer_texture

    usable = source_landmark_names(rig)
    bad = [k for k in landmarks if k not in usable]
    if bad:
        raise AppealInputError(f"{where}: landmarks: unknown or unusable rig landmark '{bad[0]}' "
                               f"(expected one of: {', '.join(usable)})")
    if len(landmarks) < 6:
        raise AppealInputError(f"{where}: landmarks: need at least 6 pairs (got {len(landmarks)})")
    region = np.asarray(rig.skin if region is None else region, np.int64)
    names = list(landmarks)
    outside = [n for n in names if not np.isin(rig.landmarks[n], region).all()]
    if outside:
        raise AppealInputError(f"{where}: landmarks: '{outside[0]}' is outside the corresponded region of the rig")
    target_pts = parse_points([landmarks[n] for n in names], mesh, f"{where}: landmarks")
    sv = np.zeros((len(names), 3), np.int64)
    sw = np.zeros((len(names), 3))
    for k, n in enumerate(names):
        idx = np.asarray(rig.landmarks[n], np.int64)
        sv[k, :len(idx)] = idx
        sv[k, len(idx):] = idx[0]
        sw[k, :len(idx)] = 1.0 / len(idx)
    mesh_v, mesh_f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    aim = target_pts.positions(mesh_v)
    keep, drop = _shared_points(sv, sw, aim, 1e-3 * float(np.linalg.norm(np.ptp(mesh_v, axis=0))))
    if drop:
        logger.warning("%s: landmarks %s share their rig point with another landmark aimed elsewhere: left out",
                       where, ", ".join(names[k] for k in drop))
    if len(keep) < 6:
        raise AppealInputError(f"{where}: landmarks: need at least 6 pairs on distinct rig points (got {len(keep)})")
    left_out = tuple(names[k] for k in drop)
    names = [names[k] for k in keep]
    sv, sw, aim, target_pts = sv[keep], sw[keep], aim[keep], target_pts.subset(keep)
    rig_pts = np.einsum("mk,mkd->md", sw, rig.vertices[sv])
    open_mesh = bool(boundary_loops(mesh_f))
    if open_mesh:  # a mask: only the part of the rig region it covers, its border tied to the mesh's
        to_mesh = _landmark_warp(rig_pts, aim)
        region = mask_crop(rig, region, mesh, to_mesh)
        missing = [n for n, pts in zip(names, sv) if not np.isin(pts, region).all()]
        if missing:
            raise AppealInputError(f"{where}: landmarks: '{missing[0]}' does not lie on the mesh once the rig is "
                                   "warped onto it by the landmarks (expected points on the mesh's face)")
    source, vid = rig_skin_mesh(rig, region)
    local = np.full(len(rig.vertices), -1)
    local[vid] = np.arange(len(vid))
    corr = Correspondences(SurfacePoints(local[sv], sw), target_pts)
    if open_mesh and boundary_loops(np.asarray(source.faces)):
        sim = umeyama(rig_pts, aim)
        up = sim.apply(np.array([[0.0, 1.0, 0.0]]))[0] - sim.apply(np.zeros((1, 3)))[0]
        corr = corr.concat(_outline_pairs(source, mesh, to_mesh, up / np.linalg.norm(up), aim))
    params = params or CorrespondParams()
    if open_mesh:
        # the mask is the region's whole counterpart (its border vertices are tied), so it is
        # not cut down to the source's neighbourhood (the cut can lose tied border vertices)
        params = replace(params, crop_target=None)
    try:
        res = correspond(source, mesh, corr, params)
    except (RuntimeError, np.linalg.LinAlgError) as exc:  # e.g. a singular fairing system
        raise AppealInputError(f"{where}: the correspondence failed ({exc}); try a smaller rig region "
                               "(e.g. region: narrow_face for ICT) or more landmarks") from None
    inv = res.alignment.inverse()
    region_new = inv.apply(res.vertices)  # back into the rig's frame
    v0 = rig.vertices
    lm_old = rig.landmark_points()
    width = float(np.linalg.norm(lm_old["face_left"] - lm_old["face_right"]))
    # vertices without a closest-point match (beyond the mesh's border, e.g. the forehead above
    # a scan's cut) only follow the smoothness term: they are carried along like the rest;
    # the correspondence points (landmarks, the border tied to the mesh's) are placed
    ok = np.asarray(res.valid, bool)
    placed = ok.copy()
    placed[np.unique(corr.source.vertices)] = True
    new_v = _carry_along(v0, vid[placed], region_new[placed], falloff=0.35 * width)
    # the mouth's inside (teeth, gums, tongue, socket) moves rigidly with the lips around it
    inner = np.isin(rig.face_part, [rig.part_names.index(p) for p in ("teeth", "mouth", "tongue")
                                    if p in rig.part_names])
    inner_v = np.unique(rig.faces[inner])
    if inner_v.size:
        mouth = (lm_old["mouth_left"] + lm_old["mouth_right"]) / 2
        half = float(np.linalg.norm(lm_old["mouth_left"] - lm_old["mouth_right"]))
        near = vid[np.linalg.norm(v0[vid] - mouth, axis=1) < 1.2 * half]
        if len(near) >= 4:
            new_v[inner_v] = umeyama(v0[near], new_v[near]).apply(v0[inner_v])
            _teeth_behind_lips(rig, new_v, near, 0.02 * half)
    # eyeballs: rigid, turned with the whole head, moved and scaled with the skin of their socket
    skin = np.asarray(rig.skin, np.int64)
    # with the skin lining the socket (deep inside the eyeball's sphere): fitted to a scan
    # with closed lids it came out in front of the eyeball, a skin-coloured film over the eye
    head = umeyama(v0[vid[placed]], region_new[placed]).rotation
    marked = np.zeros(len(v0), bool)  # landmark vertices keep their fitted places
    marked[np.concatenate([np.asarray(x) for x in rig.landmarks.values()])] = True
    for ball in rig.rigid_sets:
        ball = np.asarray(ball)
        sim = _socket_similarity(v0, new_v, ball, skin, head)
        c = v0[ball].mean(axis=0)
        r = float(np.linalg.norm(v0[ball] - c, axis=1).max())
        lining = skin[(np.linalg.norm(v0[skin] - c, axis=1) < SOCKET_DEPTH * r) & ~marked[skin]]
        both = np.concatenate([ball, lining])
        new_v[both] = sim.apply(v0[both])
    new_v = seat_lashes(rig, v0, new_v)
    out = rig.with_vertices(new_v, name=name or f"{rig.name}_on_mesh")
    transferred = None
    image = texture
    if not relay_texture:  # the mesh is drawn as itself (a scan character): nothing to re-lay
        image, maps = None, {}
    elif image is None:
        own = texture_image(mesh)
        image = None if own is None else np.asarray(own.convert("RGB"))
    maps = {k: np.asarray(v, np.uint8) for k, v in (maps or {}).items()}
    if image is not None or maps:
        if mesh_uv_layout(mesh) is None:
            what = "texture" if image is not None else f"{next(iter(maps))}_map"
            raise AppealInputError(f"{where}: {what}: the mesh has no UVs, so its {what.replace('_', ' ')} cannot be "
                                   "transferred (expected a mesh with texture coordinates)")
        if rig.uv is None:
            raise AppealInputError(f"{where}: the rig has no UVs to carry a texture")
        from scipy.ndimage import gaussian_filter

        from stimulus_engine.correspondence import deformed_mesh
        from stimulus_engine.geometry.uv_raster import rasterize_uv

        deformed = deformed_mesh(source, res.vertices)
        # only texels on triangles that matched the mesh (the rest of the region was smeared
        # over the mesh's border); a soft edge of a few texels
        uv_s, fuv_s = mesh_uv_layout(source)
        rows, cols, fid, _ = rasterize_uv(uv_s, fuv_s, texture_size, texture_size)
        good = np.zeros((texture_size, texture_size))
        good[rows, cols] = ok[np.asarray(source.faces)[fid]].all(axis=1)
        good = gaussian_filter(good, sigma=texture_size / 512)
        inner_lips = np.zeros((texture_size, texture_size))
        lm_new = out.landmark_points()  # the corresponded mouth corners, in the mesh's frame
        corners = res.alignment.apply(np.stack([lm_new["mouth_left"], lm_new["mouth_right"]]))
        inner_lips[rows, cols] = _inner_lip_faces(deformed, mesh, *corners)[fid]
        inner_lips = gaussian_filter(inner_lips, sigma=texture_size / 512)

        def relay(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """``img`` (mesh layout) in the rig's layout, and the weight of the transferred texels."""
            img = np.asarray(img, np.uint8)
            img = np.repeat(img[..., None], 3, axis=2) if img.ndim == 2 else img[..., :3]
            rgba = np.concatenate([img, np.full(img.shape[:2] + (1,), 255, np.uint8)], axis=2)
            moved = np.asarray(transfer_texture(deformed, mesh, rgba, size=(texture_size, texture_size),
                                                background=(0, 0, 0, 0)))
            return moved, moved[..., 3:4].astype(np.float64) / 255.0 * good[..., None]

        defaults = {"normal": np.array(FLAT_NORMAL, np.float64), "specular": np.full(3, 128.0)}
        relaid = {}
        for kind, img in maps.items():
            moved, w = relay(img)
            m = np.clip(np.rint(defaults[kind] * (1 - w) + moved[..., :3] * w), 0, 255).astype(np.uint8)
            relaid[kind] = m if kind == "normal" else m[..., 0].copy()
        out = replace(out, texture_maps=relaid)
    if image is not None:
        moved, a = relay(image)
        # the painted albedo of the new shape fills what the region does not cover
        base = out.with_vertices(new_v)
        base.texture = None
        painted, masks = _painted_fill(base, texture_size)
        # tone-match the painted rest of the head to the user's skin (per-channel gain over
        # the transferred texels, lips and brows left out)
        skin_w = a[..., 0] * skin_texels(masks, a.shape)
        if skin_w.sum() > 0:
            gain = ((moved[..., :3] * skin_w[..., None]).sum(axis=(0, 1))
                    / np.maximum((painted * skin_w[..., None]).sum(axis=(0, 1)), 1e-9))
            painted = np.clip(painted * gain, 0, 255)
        albedo = painted * (1 - a) + moved[..., :3] * a
        lips = np.clip(masks.get("lips", np.zeros(a.shape[:2])), 0, 1) * a[..., 0] * (1 - inner_lips)
        if lips.sum() > 0:  # the lips' inside: their own red, darker (wet mucosa in the lips' shade)
            red = (moved[..., :3] * lips[..., None]).sum(axis=(0, 1)) / lips.sum() * MUCOSA_SHADE
            albedo = albedo * (1 - inner_lips[..., None]) + red * inner_lips[..., None]
        albedo = np.clip(np.rint(albedo), 0, 255).astype(np.uint8)
        out = replace(out, texture=albedo, texture_masks=dict(masks))
        transferred = a[..., 0] > 0.5
    return MeshCharacter(rig=out, region=vid, metrics=dict(res.metrics), transferred=transferred,
                         left_out=left_out, alignment=res.alignment)
