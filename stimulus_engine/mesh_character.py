"""Any face mesh as a grid character: the rig is corresponded onto it with ElastiFace (issue 4).

A user's mesh (a scan, an artist's stylised head, the MediaPipe face ...) has its own
tessellation and UV layout and no expressions. :func:`correspond_rig` deforms a rig's skin
region (ICT Face Model or the procedural head) onto it with
:func:`stimulus_engine.correspond` from a few landmark pairs (thesis §3.2), so the character
becomes a :class:`~stimulus_engine.expressions.FaceRig` *in the rig's topology*:

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
from stimulus_engine.expressions import FaceRig

__all__ = ["MeshCharacter", "correspond_rig", "front_region", "rig_skin_mesh", "source_landmark_names"]


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
    """

    rig: FaceRig
    region: np.ndarray
    metrics: dict = field(default_factory=dict)
    transferred: np.ndarray | None = None


def source_landmark_names(rig: FaceRig) -> list[str]:
    """Rig landmarks usable as correspondence points (skin landmarks of at most 3 vertices)."""
    skin = set(np.asarray(rig.skin).tolist())
    return [k for k, idx in rig.landmarks.items() if len(idx) <= 3 and all(int(i) in skin for i in idx)]


def rig_skin_mesh(rig: FaceRig, region: np.ndarray | None = None) -> tuple[trimesh.Trimesh, np.ndarray]:
    """The rig's skin triangles inside ``region`` (default: all skin) as a mesh with the rig's UVs.

    Returns the mesh and the rig vertex index of each of its vertices.
    """
    from stimulus_engine.mesh_io import select_region

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


def correspond_rig(rig: FaceRig, mesh: trimesh.Trimesh, landmarks: Mapping[str, object], *,
                   region: np.ndarray | None = None, texture: np.ndarray | None = None,
                   texture_size: int = 1024, params: object | None = None, name: str | None = None,
                   where: str = "mesh", maps: Mapping[str, np.ndarray] | None = None) -> MeshCharacter:
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

    Raises
    ------
    AppealInputError
        Unknown landmark names, too few pairs, points off the mesh, texture without UVs.
    """
    from stimulus_engine.correspondence import CorrespondParams, Correspondences, SurfacePoints, correspond
    from stimulus_engine.correspondence.landmarks import parse_points
    from stimulus_engine.materials import FLAT_NORMAL, rig_albedo
    from stimulus_engine.mesh_io import mesh_uv_layout, texture_image
    from stimulus_engine.texture_transfer import transfer_texture

    usable = source_landmark_names(rig)
    bad = [k for k in landmarks if k not in usable]
    if bad:
        raise AppealInputError(f"{where}: landmarks: unknown or unusable rig landmark '{bad[0]}' "
                               f"(expected one of: {', '.join(usable)})")
    if len(landmarks) < 6:
        raise AppealInputError(f"{where}: landmarks: need at least 6 pairs (got {len(landmarks)})")
    source, vid = rig_skin_mesh(rig, region)
    local = np.full(len(rig.vertices), -1)
    local[vid] = np.arange(len(vid))
    names = list(landmarks)
    sv = np.zeros((len(names), 3), np.int64)
    sw = np.zeros((len(names), 3))
    for k, n in enumerate(names):
        idx = local[rig.landmarks[n]]
        if (idx < 0).any():
            raise AppealInputError(f"{where}: landmarks: '{n}' is outside the corresponded region of the rig")
        sv[k, :len(idx)] = idx
        sv[k, len(idx):] = idx[0]
        sw[k, :len(idx)] = 1.0 / len(idx)
    target_pts = parse_points([landmarks[n] for n in names], mesh, f"{where}: landmarks")
    corr = Correspondences(SurfacePoints(sv, sw), target_pts)
    try:
        res = correspond(source, mesh, corr, params or CorrespondParams())
    except (RuntimeError, np.linalg.LinAlgError) as exc:  # e.g. a singular fairing system
        raise AppealInputError(f"{where}: the correspondence failed ({exc}); try a smaller rig region "
                               "(e.g. region: narrow_face for ICT) or more landmarks") from None
    inv = res.alignment.inverse()
    region_new = inv.apply(res.vertices)  # back into the rig's frame
    v0 = rig.vertices
    lm_old = rig.landmark_points()
    width = float(np.linalg.norm(lm_old["face_left"] - lm_old["face_right"]))
    # vertices without a closest-point match (beyond the mesh's border, e.g. the forehead above
    # a scan's cut) only follow the smoothness term: they are carried along like the rest
    ok = np.asarray(res.valid, bool)
    new_v = _carry_along(v0, vid[ok], region_new[ok], falloff=0.35 * width)
    # the mouth's inside (teeth, gums, tongue, socket) moves rigidly with the lips around it
    inner = np.isin(rig.face_part, [rig.part_names.index(p) for p in ("teeth", "mouth", "tongue")
                                    if p in rig.part_names])
    inner_v = np.unique(rig.faces[inner])
    if inner_v.size:
        from stimulus_engine.correspondence import umeyama

        mouth = (lm_old["mouth_left"] + lm_old["mouth_right"]) / 2
        half = float(np.linalg.norm(lm_old["mouth_left"] - lm_old["mouth_right"]))
        near = vid[np.linalg.norm(v0[vid] - mouth, axis=1) < 1.2 * half]
        if len(near) >= 4:
            new_v[inner_v] = umeyama(v0[near], new_v[near]).apply(v0[inner_v])
    # eyeballs: rigid, translated with their surroundings and scaled with the eye width
    lm_new = rig.landmark_points(new_v)
    for ball, side in zip(rig.rigid_sets, ("left", "right")):
        c_old = v0[ball].mean(axis=0)
        c_new = new_v[ball].mean(axis=0)
        s = 1.0
        outer, inner = f"eye_{side}_outer", f"eye_{side}_inner"
        if outer in lm_old and inner in lm_old:
            s = float(np.linalg.norm(lm_new[outer] - lm_new[inner]) / np.linalg.norm(lm_old[outer] - lm_old[inner]))
        new_v[ball] = c_new + s * (v0[ball] - c_old)
    out = rig.with_vertices(new_v, name=name or f"{rig.name}_on_mesh")
    transferred = None
    image = texture
    if image is None:
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
        from stimulus_engine.texture_transfer import rasterize_uv

        deformed = deformed_mesh(source, res.vertices)
        # only texels on triangles that matched the mesh (the rest of the region was smeared
        # over the mesh's border); a soft edge of a few texels
        uv_s, fuv_s = mesh_uv_layout(source)
        rows, cols, fid, _ = rasterize_uv(uv_s, fuv_s, texture_size, texture_size)
        good = np.zeros((texture_size, texture_size))
        good[rows, cols] = ok[np.asarray(source.faces)[fid]].all(axis=1)
        good = gaussian_filter(good, sigma=texture_size / 512)

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
        painted, masks = rig_albedo(base, size=texture_size)
        # tone-match the painted rest of the head to the user's skin (per-channel gain over
        # the transferred texels, lips and brows left out)
        skin_w = a[..., 0] * (1 - sum((np.clip(m, 0, 1) for m in masks.values()), np.zeros(a.shape[:2])).clip(0, 1))
        if skin_w.sum() > 0:
            gain = ((moved[..., :3] * skin_w[..., None]).sum(axis=(0, 1))
                    / np.maximum((painted * skin_w[..., None]).sum(axis=(0, 1)), 1e-9))
            painted = np.clip(painted * gain, 0, 255)
        albedo = np.clip(np.rint(painted * (1 - a) + moved[..., :3] * a), 0, 255).astype(np.uint8)
        out = replace(out, texture=albedo, texture_masks=dict(masks))
        transferred = a[..., 0] > 0.5
    return MeshCharacter(rig=out, region=vid, metrics=dict(res.metrics), transferred=transferred)
