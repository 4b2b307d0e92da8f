"""A character from one frontal photograph (issue 49): the ICT Face Model fitted to it, the
photograph as its material, its head and shoulders behind it.

:func:`photo_character` runs the whole path and :func:`write_photo_character` writes it out
(``appeal stimuli photo-character``):

1. **Landmarks**: dlib's 68 points (:func:`find_face`; a 68-point ``.tem`` given instead is used
   as it is). A photograph with no face, two faces, a turned head or a face under
   :data:`MIN_EYE_DISTANCE` pixels between the eyes is refused with one line naming the file.
2. **Fit** (:mod:`stimulus_engine.characters.photo_fit`): the model's 100 identity components and
   its expression shapes, with a scaled orthographic camera, to the 68 points under the model's
   prior. The photograph is laid on the fitted shape with its own expression. The character's
   neutral is the identity alone (``neutral="identity"``, the default) or that posed shape
   (``neutral="photograph"``: the realistic neutral render is the photograph, lips closed or
   parted as they were, and every expression is the rig's shapes added to it).
3. **Material** (:mod:`stimulus_engine.characters.photo_texture`): the photograph projected into
   the rig's UV layout where the face is seen, completed from the mirrored side and filled
   smoothly from the seen skin; the rig's eyeballs with the iris colour of the photograph, the
   rig's teeth and tongue behind the lips; region masks (lips, brows ...) from the rig's own.
4. **Surround** (:mod:`stimulus_engine.parts.surround`): the rest of the photograph (hair, ears,
   neck, clothes, background) on a plane behind the head at the photograph's camera, its face
   filled in; the rig's scalp and neck are not drawn, so from the photograph's viewpoint the
   character *is* the photograph and a changed face never shows the photographed one behind it.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.characters.photo_fit import PhotoFit, fit_landmarks
from stimulus_engine.characters.rig import FaceRig
from stimulus_engine.parts.surround import Surround

__all__ = [
    "MAX_TURN_DEG",
    "MIN_EYE_DISTANCE",
    "NEUTRALS",
    "PHOTO_EYE_PARTS",
    "PHOTO_VERSION",
    "PhotoCharacter",
    "dlib_vertices",
    "find_face",
    "found_template",
    "photo_character",
    "photo_eyed",
    "photo_points",
    "read_photo",
    "widens_eyes",
    "write_photo_character",
]

#: The rig's eye parts left out where a photo character shows the photograph's own eyes (the
#: surround keeps them, seen through the lids' opening): eyeballs, their lid shadow, the wet line
#: and the lash strips (the photograph has its own).
PHOTO_EYE_PARTS = ("eye", "eye_shadow", "tear", "lashes")

#: Changes whenever the fit or the photo material change (part of a grid's cache key).
PHOTO_VERSION = "photo-13"

#: What a photo character's neutral may be: the fitted shape with the photograph's own expression
#: or the fitted identity alone (the default, :func:`photo_character`'s ``neutral``).
NEUTRALS = ("photograph", "identity")

#: The smallest face a character is made from: pixels between the eye centres (below it the
#: texture is blurred and dlib's points scatter by more than the fit's noise).
MIN_EYE_DISTANCE = 80.0
#: The largest head turn (yaw or pitch, degrees) taken for a frontal photograph.
MAX_TURN_DEG = 20.0
#: A second face this large (area relative to the largest) makes the photograph ambiguous.
SECOND_FACE_AREA = 0.15
#: The landmark noise of the fit (share of the eye distance) and its expression prior.
FIT_NOISE, FIT_PRIOR_EXPRESSION = 0.05, 10.0
#: A grid's default camera (vertical field of view, eye row, face length as a share of the height).
PORTRAIT = (20.0, 0.36, 0.42)
#: The light a photograph is taken to be lit by (a portrait studio's soft frontal light): the grid's
#: default, with the ``pbr`` shading of the shipped studies.
REFERENCE_LIGHTING, REFERENCE_SHADING = "gi_soft", "pbr"
#: The grey a reference render paints the skin (sRGB) and the range the light divided out may take.
_GREY, _LIGHT_RANGE = 180, (0.25, 4.0)
#: The surround's plane lies this far (model units, cm) behind the jaw line's mean depth (iBUG
#: 0-16: where the drawn face meets the photograph around it, so the two meet at one scale under
#: a perspective camera too; the skin behind it, at the ears, is the photograph's there).
SURROUND_BEHIND = 0.5


@dataclass(frozen=True, eq=False)
class PhotoCharacter:
    """A character made by :func:`photo_character`.

    Attributes
    ----------
    rig : FaceRig
        The fitted face in the ICT topology (its neutral: :func:`photo_character`'s ``neutral``),
        wearing the photograph (``texture``), with the rig's eyeballs (iris from the photograph)
        and mouth, its scalp and neck hidden, and the photograph's surround (``surround``).
    fit : PhotoFit
        Coefficients, camera and residuals.
    points : (68, 2) array
        The photograph's landmarks the fit used.
    photo : (H, W, 3) uint8 array
    seen : (S, S) float array
        How well each texel was seen in the photograph (0-1, before the mirrored side).
    posed : (N, 3) array
        The fitted shape with the photograph's own expression (what the photograph was laid on).
    landmark_ids : (68,) int array
        The model's landmark vertices (iBUG order).
    """

    rig: FaceRig
    fit: PhotoFit
    points: np.ndarray
    photo: np.ndarray
    seen: np.ndarray
    posed: np.ndarray
    landmark_ids: np.ndarray

    @property
    def view(self) -> np.ndarray:
        """Direction from the face toward the photograph's camera (model frame)."""
        return self.fit.camera.view_direction

    @property
    def up(self) -> np.ndarray:
        """The photograph's up direction (model frame)."""
        return self.fit.camera.rotation[1].copy()


def read_photo(path: str | os.PathLike) -> np.ndarray:
    """The photograph as RGB uint8 (one-line errors for a missing or unreadable file)."""
    from stimulus_engine.faces2d.align import read_rgb

    return np.rint(read_rgb(path) * 255.0).astype(np.uint8)


def find_face(image: np.ndarray, name: str = "photo", max_side: int = 640) -> np.ndarray:
    """dlib's 68 points of the one frontal face in ``image``.

    Raises a one-line :class:`AppealInputError` naming ``name`` when no face is found (a profile
    is not found by dlib's frontal detector), when a second face is as large as
    :data:`SECOND_FACE_AREA` of the first, or when the eye centres are less than
    :data:`MIN_EYE_DISTANCE` pixels apart.
    """
    import cv2

    from stimulus_engine.morphpca.keypoints import _dlib_models

    m = _dlib_models()
    img = np.ascontiguousarray(np.asarray(image)[..., :3])
    scale = min(1.0, max_side / max(img.shape[:2]))
    small = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA) if scale < 1 else img
    rects, scores, _ = m["detector"].run(small, 1, 0.0)
    if len(rects) == 0:
        raise AppealInputError(f"{name}: no face found (expected one frontal face; a profile or a face turned "
                               f"more than about {MAX_TURN_DEG:.0f} degrees is not taken)")
    areas = np.array([r.width() * r.height() for r in rects], np.float64)
    k = int(np.argmax(areas))
    if len(rects) > 1 and np.sort(areas)[-2] >= SECOND_FACE_AREA * areas[k]:
        raise AppealInputError(f"{name}: {len(rects)} faces found (expected a photograph of one person; "
                               "crop it to the face to use)")
    r = rects[k]
    box = m["rect"](int(r.left() / scale), int(r.top() / scale), int(r.right() / scale), int(r.bottom() / scale))
    pts = np.array([[p.x, p.y] for p in m["predictor"](img, box).parts()], np.float64)
    check_eye_distance(pts, name)
    return pts


def check_eye_distance(points: np.ndarray, name: str) -> float:
    """The eye distance of 68 points; a one-line error when under :data:`MIN_EYE_DISTANCE`."""
    iod = float(np.linalg.norm(points[36:42].mean(axis=0) - points[42:48].mean(axis=0)))
    if iod < MIN_EYE_DISTANCE:
        raise AppealInputError(f"{name}: the face is {iod:.0f} px between the eyes (expected at least "
                               f"{MIN_EYE_DISTANCE:.0f} px: a larger photograph or a closer crop)")
    return iod


def photo_person(photo: str | os.PathLike) -> dict[str, object]:
    """The London set's record of the person in ``photo`` (``age``, ``gender``, ``ethnicity`` from
    ``london_info.csv``: beside the photograph's folder, or in the registered ``london-frl``
    dataset, which lists the other public people too); empty when there is none."""
    import pandas as pd

    p = Path(photo)
    places = [p.parent / "london_info.csv", p.parent.parent / "london_info.csv"]
    try:
        from appeal.datasets import resolve_reference

        places.append(Path(resolve_reference("data:london-frl", missing_ok=True)) / "london_info.csv")
    except AppealInputError:  # no registry entry: only the folders beside the photograph
        pass
    info = next((f for f in places if f.is_file()), None)
    if info is None:
        return {}
    try:
        table = pd.read_csv(info, dtype={"face_id": str})
        row = table[table["face_id"] == p.stem.split("_")[0]]
    except (ValueError, KeyError, pd.errors.ParserError):
        return {}
    if row.empty:
        return {}
    r = row.iloc[0]
    return {"age": r.get("face_age"), "gender": r.get("face_gender"), "ethnicity": r.get("face_eth")}


def found_template(photo: str | os.PathLike) -> Path | None:
    """The ``.tem`` beside a photograph (the London set's), or None."""
    t = Path(photo).with_suffix(".tem")
    return t if t.is_file() else None


@functools.lru_cache(maxsize=1)
def _frl_pairs() -> dict[int, int]:
    """iBUG point -> FRL-189 template point, where the two markups agree (scripts/frl189_to_ibug68.py)."""
    from stimulus_engine.data import DATA_DIR
    from stimulus_engine.geometry.mesh_io import read_json

    d = read_json(DATA_DIR / "faces2d" / "frl189_ibug68.json", "FRL-189 to iBUG-68 table")
    return {int(k): int(v) for k, v in d["ibug_to_frl189"].items()}


def photo_points(image: np.ndarray, name: str, template: str | os.PathLike | None = None) -> np.ndarray:
    """The photograph's 68 points: dlib's, with a template's hand-placed ones where it has them.

    A 68-point ``.tem`` (dlib's order) is used as it is; WebMorph's 189-point FRL template (the
    London set's) replaces dlib's eyes, brows, nose base and outer lips by its own points
    (:func:`_frl_pairs`: the points the two markups place alike); any other template is refused.
    """
    from stimulus_engine.faces2d.template import read_template

    if template is None:
        return find_face(image, name)
    t = read_template(template)
    if len(t.points) == 68:
        check_eye_distance(t.points, name)
        return t.points
    if len(t.points) != 189:
        raise AppealInputError(f"{template}: template: {len(t.points)} points (expected dlib's 68 in its order, or "
                               "the FRL 189-point template; leave template: out to detect them)")
    pts = find_face(image, name)
    for i, j in _frl_pairs().items():
        pts[i] = t.points[j]
    return pts


@functools.lru_cache(maxsize=2)
def _model(ict_dir: str, identity_model: str | None) -> tuple[FaceRig, np.ndarray, np.ndarray, list[str]]:
    """The ICT mean face as a rig, its identity components, landmark vertices and expression names."""
    from stimulus_engine.characters.ict import ict_identity_basis, load_ict_rig

    rig = load_ict_rig(ict_dir, "generic_neutral_mesh")
    basis = ict_identity_basis(*[d for d in (ict_dir, identity_model) if d])
    return rig, basis, dlib_vertices(), sorted(rig.blendshapes)


@functools.lru_cache(maxsize=1)
def dlib_vertices() -> np.ndarray:
    """The ICT face vertices where dlib puts its 68 points (``scripts/ict_dlib_landmarks.py``: on
    renders of the model, 3.5 % of the eye distance from dlib's points on average, where the kit's
    own 68 landmark vertices lie 6.6 % away — its jaw line inside the silhouette dlib follows)."""
    from stimulus_engine.data import DATA_DIR
    from stimulus_engine.geometry.mesh_io import read_json

    return np.asarray(read_json(DATA_DIR / "faces2d" / "ict_dlib68.json", "ICT-dlib landmark table")["vertices"], np.int64)


def _hide_scalp(rig: FaceRig, ict_dir: str) -> FaceRig:
    """The rig with its scalp, back of the head and neck (ICT ``head_and_neck``) not drawn."""
    from stimulus_engine.geometry.ict_topology import ict_regions

    back = np.zeros(len(rig.vertices), bool)
    back[ict_regions()["head_and_neck"]] = True
    part = rig.face_part.copy()
    part[back[rig.faces].any(axis=1) & (rig.face_part == rig.part_names.index("skin"))] = rig.part_names.index("hidden")
    return replace(rig, face_part=part)


#: Skin turned further than this from the photograph's camera (cosine), reached from the drawn
#: face's border through such skin only, is left to the photograph behind (the forehead's rim under
#: the hair, the sides of the cheeks, the ears): the photograph saw it too obliquely to texture it.
RIM_COS = 0.35


def _not_skin(photo: np.ndarray, points: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Which image positions ``xy`` show something other than the face's skin (hair, an ear's
    shadow, the background): their colour more than :data:`SKIN_SIGMA` (Mahalanobis, in Lab) from
    the skin between the eyes and the mouth, and outside the hull of the jaw line and brows."""
    import cv2

    h, w = photo.shape[:2]
    lab = cv2.cvtColor(np.ascontiguousarray(photo[..., :3]), cv2.COLOR_RGB2LAB).astype(np.float64)
    cheeks = np.zeros((h, w), np.uint8)
    cv2.fillConvexPoly(cheeks, cv2.convexHull(np.rint(points[[1, 2, 3, 4, 12, 13, 14, 15, 28]]).astype(np.int32)), 1)
    for poly in (points[36:42], points[42:48], points[48:60], points[31:36]):
        cv2.fillConvexPoly(cheeks, cv2.convexHull(np.rint(poly).astype(np.int32)), 0)
    px = lab[cheeks > 0]
    mu, cov = px.mean(axis=0), np.cov(px.T) + np.eye(3)
    hull = np.zeros((h, w), np.uint8)
    cv2.fillConvexPoly(hull, cv2.convexHull(np.rint(points[:27]).astype(np.int32)), 1)
    r = np.clip(np.rint(xy[:, 1]).astype(int), 0, h - 1)
    c = np.clip(np.rint(xy[:, 0]).astype(int), 0, w - 1)
    d = lab[r, c] - mu
    m2 = np.einsum("ij,jk,ik->i", d, np.linalg.inv(cov), d)
    return (m2 > SKIN_SIGMA ** 2) & (hull[r, c] == 0)


def _below_jaw(points: np.ndarray, xy: np.ndarray, margin: float = 0.04) -> np.ndarray:
    """Which image positions lie under the jaw line (iBUG 0-16, continued level beyond its ends)
    by more than ``margin`` of the eye distance: the neck, which the photograph shows itself."""
    jaw = points[:17]
    order = np.argsort(jaw[:, 0])
    iod = float(np.linalg.norm(points[36:42].mean(axis=0) - points[42:48].mean(axis=0)))
    line = np.interp(xy[:, 0], jaw[order, 0], jaw[order, 1])
    return xy[:, 1] > line + margin * iod


#: Skin colour this many standard deviations from the cheeks' (Mahalanobis, Lab) is not skin.
SKIN_SIGMA = 4.0


def _hide_rim(rig: FaceRig, vertices: np.ndarray, camera, zbuf: np.ndarray, photo: np.ndarray,
              points: np.ndarray, step: int = 2) -> FaceRig:
    """The rig with its rim not drawn: skin reached from the drawn face's border through skin that
    is oblique (:data:`RIM_COS`), hidden, or covered in the photograph (hair over the forehead:
    :func:`_not_skin`), and the neck under the jaw line (:func:`_below_jaw`): the photograph
    behind shows them as they were."""
    import trimesh
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    skin = np.flatnonzero(rig.face_part == rig.part_names.index("skin"))
    mesh = trimesh.Trimesh(vertices, rig.faces[skin], process=False)
    cos = mesh.vertex_normals @ camera.view_direction
    xy = camera.project(vertices) / step
    r = np.clip(xy[:, 1].astype(int), 0, zbuf.shape[0] - 1)
    c = np.clip(xy[:, 0].astype(int), 0, zbuf.shape[1] - 1)
    hidden = camera.depth(vertices) < zbuf[r, c] - 0.25
    low = ((cos < RIM_COS) | hidden | _not_skin(photo, points, xy * step))[mesh.faces].any(axis=1)
    low |= _below_jaw(points, xy * step)[mesh.faces].all(axis=1)
    adj = mesh.face_adjacency
    both = low[adj[:, 0]] & low[adj[:, 1]]
    n = len(skin)
    g = coo_matrix((np.ones(both.sum()), (adj[both, 0], adj[both, 1])), shape=(n, n))
    _, comp = connected_components(g, directed=False)
    edge_faces = np.unique(trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1) // 3)  # on the border
    rim = np.isin(comp, np.unique(comp[edge_faces[low[edge_faces]]])) & low
    part = rig.face_part.copy()
    part[skin[rim]] = rig.part_names.index("hidden")
    return replace(rig, face_part=part)


def bake_texels(rig: FaceRig, vertices: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each skin texel's point and unit normal on ``vertices`` and which texels are skin."""
    import trimesh

    from stimulus_engine.geometry.uv_raster import rasterize_uv

    sel = np.flatnonzero(rig.face_part == rig.part_names.index("skin"))
    rows, cols, fid, bary = rasterize_uv(rig.uv, rig.face_uv[sel], size, size)
    tri = rig.faces[sel][fid]
    vn = trimesh.Trimesh(vertices, rig.faces[sel], process=False).vertex_normals
    pts = np.zeros((size, size, 3))
    nrm = np.zeros((size, size, 3))
    valid = np.zeros((size, size), bool)
    pts[rows, cols] = np.einsum("ij,ijk->ik", bary, vertices[tri])
    n = np.einsum("ij,ijk->ik", bary, vn[tri])
    nrm[rows, cols] = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    valid[rows, cols] = True
    return pts, nrm, valid


def photo_character(photo: str | os.PathLike, ict_dir: str | os.PathLike, identity_model: str | os.PathLike | None = None,
                    *, name: str | None = None, template: str | os.PathLike | None = None,
                    texture_size: int = 2048, lighting: str | None = REFERENCE_LIGHTING,
                    portrait: tuple[float, float, float] | None = PORTRAIT,
                    neutral: str = "identity") -> PhotoCharacter:
    """A character from one frontal photograph.

    Parameters
    ----------
    photo : path-like
        A frontal photograph of one person (JPEG or PNG).
    ict_dir : path-like
        The ICT face kit (``data:ict-facekit``: the mean face, expression shapes, three identity
        components).
    identity_model : path-like, optional
        Further identity components (``data:ict-facekit-more``: with the kit's three, all 100).
    name : str, optional
        The character's name (default: the photograph's file stem).
    template : path-like, optional
        A ``.tem`` of the photograph (:func:`photo_points`; :func:`found_template` finds the one
        beside it).
    texture_size : int
        Side of the texture in the rig's UV layout.
    portrait : (yfov_deg, eye_row, face_fraction) or None
        The renderer's camera the photograph is laid on through (a grid's ``render`` settings;
        default :data:`PORTRAIT`, a grid's default framing): a pinhole where that camera frames
        the fitted face, so the face drawn from there shows the photograph undistorted (None:
        orthographic, as the fit).
    lighting : str or None
        The light the photograph is taken to be lit by (a lighting preset, default
        :data:`REFERENCE_LIGHTING`): its shading of the fitted face, as the renderer draws it
        (:func:`_reference_light`), is divided out of the photograph, so the face rendered under
        that light gives the photograph back and other lights relight it. None keeps the
        photograph's light in the albedo (it is then shaded twice).
    neutral : {"identity", "photograph"}
        The character's neutral: the fitted identity alone (the default: the photograph's residual
        expression removed, its lips then parting on the rig's teeth) or the fitted shape with the
        photograph's own expression (its realistic neutral render is the photograph: over the 87
        public London people the SSIM against the photograph rose from a median 0.921 to 0.949; at
        stylised levels the aligned expression transfer and the lashes are not yet verified on it).

    Returns
    -------
    PhotoCharacter
    """
    from stimulus_engine.characters import photo_texture as pt
    from stimulus_engine.characters.skin_maps import rig_albedo
    from stimulus_engine.parts.eyes import tint_iris

    where = str(photo)
    if neutral not in NEUTRALS:
        raise ValueError(f"neutral: expected one of {', '.join(NEUTRALS)}, got {neutral!r}")
    img = read_photo(photo)
    points = photo_points(img, where, template)
    base, basis, lm, expressions = _model(str(ict_dir), None if identity_model is None else str(identity_model))
    E = np.array([base.blendshapes[k] for k in expressions])
    fit = fit_landmarks(points, base.vertices[lm], basis[:, lm], E[:, lm], noise=FIT_NOISE,
                        prior_expression=FIT_PRIOR_EXPRESSION)
    turn = max(abs(fit.camera.yaw_degrees), abs(fit.camera.pitch_degrees))
    if turn > MAX_TURN_DEG:
        raise AppealInputError(f"{where}: the head is turned {turn:.0f} degrees from the camera (expected a frontal "
                               f"photograph, within {MAX_TURN_DEG:.0f} degrees)")
    identity = base.vertices + np.tensordot(fit.identity, basis, 1)
    posed = identity + np.tensordot(fit.expression, E, 1)
    rig = _hide_scalp(base.with_vertices(posed if neutral == "photograph" else identity, name=name or Path(photo).stem),
                      str(ict_dir))
    camera = fit.camera if portrait is None else _through(fit.camera, rig, posed, portrait)
    skin = rig.part_names.index("skin")
    zbuf = pt.depth_buffer(camera, posed, rig.faces[rig.face_part == skin], img.shape[:2])
    rig = _hide_rim(rig, posed, camera, zbuf, img, points)
    pts, nrm, valid = bake_texels(rig, posed, texture_size)
    drawn = rig.faces[rig.face_part == skin]
    zbuf = pt.depth_buffer(camera, posed, drawn, img.shape[:2])
    tex, seen = pt.project_photo(img, camera, pts, nrm, valid, zbuf)
    _, masks = rig_albedo(base, size=1024)
    masks = {k: _resized(v, texture_size) for k, v in masks.items()}
    if lighting is not None:  # the photograph's light taken to be the reference light: divided out
        tex = _unlit(tex, _reference_light(rig, posed, camera, img.shape[:2], pts, valid, lighting))
    mirrored, w = pt.mirror_fill(tex, seen)
    texture = np.clip(np.rint(pt.smooth_fill(mirrored, w)), 0, 255).astype(np.uint8)
    iris = np.mean([pt.iris_colour(img, points[36:42]), pt.iris_colour(img, points[42:48])], axis=0)
    textures = dict(rig.part_textures)
    if "eye" in textures:
        textures["eye"] = tint_iris(textures["eye"], iris)
    depth = float(camera.depth(posed[lm[:17]]).mean()) - SURROUND_BEHIND
    front = zbuf > depth  # what the mesh draws in front of the plane: the photographed face there is filled in
    face_mask = _resized(front.astype(np.float32), img.shape[0], img.shape[1]) > 0.5
    face_mask &= ~_eye_openings(img.shape[:2], points)  # kept: seen through the lids (photo_eyed)
    image, pad = pt.padded(pt.surround_image(img, face_mask, grow=-3))
    surround = Surround(pt.surround_corners(camera, img.shape[:2], depth, pad), image)
    rig = replace(rig, texture=texture, texture_masks=masks, part_textures=textures, surround=surround)
    return PhotoCharacter(rig, fit, points, img, seen, posed, lm)


def _through(camera, rig: FaceRig, posed: np.ndarray, portrait: tuple[float, float, float]):
    """``camera`` as the pinhole a grid's camera (``portrait``) puts where it frames the face
    (:func:`stimulus_engine.render.face_camera`), agreeing with the fit at the eyes' depth."""
    from stimulus_engine.render import face_camera

    yfov, eye_row, fraction = portrait
    lm = rig.landmark_points(posed)
    eye = (lm["eye_left"] + lm["eye_right"]) / 2
    length = float(np.linalg.norm(lm["forehead_top"] - lm["chin"]))
    cam = face_camera(eye, length, yfov_deg=yfov, eye_row=eye_row, face_fraction=fraction,
                      view_dir=tuple(camera.view_direction), up=tuple(camera.rotation[1]))
    return camera.perspective(np.asarray(cam.position), float(camera.depth(eye[None])[0]))


def _reference_light(rig: FaceRig, posed: np.ndarray, camera, shape: tuple[int, int], points: np.ndarray,
                     valid: np.ndarray, lighting: str) -> np.ndarray:
    """The light ``lighting`` gives each texel of the fitted face seen from the photograph's camera,
    as the renderer shades it (linear; 1: the skin's albedo unchanged).

    The face is drawn in a uniform grey from far along the photograph's viewing direction (a
    nearly orthographic view, as the fit's camera), framed as the photograph, and each texel
    reads the render where its point projects."""
    import cv2

    from stimulus_engine.characters.photo_texture import _sample
    from stimulus_engine.characters.render_parts import rig_render_parts
    from stimulus_engine.render import CameraSpec, render_mesh

    h, w = shape
    far = 2000.0
    centre = camera.unproject(np.array([[w / 2, h / 2]]), float(camera.depth(posed).max()))[0]
    pos = centre + camera.view_direction * far
    yfov = float(np.degrees(2 * np.arctan(h / camera.scale / 2 / far)))
    cam = CameraSpec(tuple(pos), tuple(centre), yfov, tuple(camera.rotation[1]))
    grey = np.full((8, 8, 3), _GREY, np.uint8)
    k = min(1.0, 768 / max(h, w))
    img, depth = render_mesh(rig_render_parts(rig, posed, grey, shading=REFERENCE_SHADING), width=round(w * k),
                             height=round(h * k), lighting=lighting, camera=cam, background=(0.0, 0.0, 0.0),
                             shadows=False, return_depth=True)
    lin = lambda a: np.where(a <= 0.04045, a / 12.92, ((a + 0.055) / 1.055) ** 2.4)
    light_img = lin(img.astype(np.float64) / 255.0).mean(axis=2) / lin(_GREY / 255.0)
    # off the face (and on its anti-aliased edge) the light is continued from the face beside it
    on = cv2.erode((depth > 0).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(np.float64)
    near = cv2.GaussianBlur(light_img * on, (0, 0), 4) / np.maximum(cv2.GaussianBlur(on, (0, 0), 4), 1e-6)
    light_img = np.where(on > 0, light_img, np.where(cv2.GaussianBlur(on, (0, 0), 4) > 1e-3, near, 1.0))
    xy = camera.project(points.reshape(-1, 3)[valid.ravel()]) * k
    light = np.ones(valid.shape)
    light[valid] = _sample(light_img[..., None], xy)[:, 0]
    return np.clip(light, *_LIGHT_RANGE)


def _unlit(texture: np.ndarray, light: np.ndarray) -> np.ndarray:
    """An sRGB texture (0-255) with ``light`` (linear, per texel) divided out."""
    t = np.clip(texture / 255.0, 0, 1)
    lin = np.where(t <= 0.04045, t / 12.92, ((t + 0.055) / 1.055) ** 2.4) / light[..., None]
    lin = np.clip(lin, 0, 1)
    return 255.0 * np.where(lin <= 0.0031308, lin * 12.92, 1.055 * lin ** (1 / 2.4) - 0.055)


def _eye_openings(shape: tuple[int, int], points: np.ndarray, grow: float = 0.12) -> np.ndarray:
    """The eyes' openings between the lids in the photograph (iBUG 36-41, 42-47), grown by
    ``grow`` of each eye's width."""
    import cv2

    mask = np.zeros(shape, np.uint8)
    for eye in (points[36:42], points[42:48]):
        c = eye.mean(axis=0)
        width = float(np.linalg.norm(eye[3] - eye[0]))
        poly = c + (eye - c) * (1 + 2 * grow * width / max(np.linalg.norm(eye - c, axis=1).mean(), 1e-6) / 2)
        cv2.fillPoly(mask, [np.rint(poly).astype(np.int32)], 1)
    return mask.astype(bool)


def photo_eyed(rig: FaceRig) -> FaceRig:
    """``rig`` drawn with the photograph's own eyes: :data:`PHOTO_EYE_PARTS` and the orbit's lining
    hidden, so its surround's eyes show through the lids."""
    from stimulus_engine.geometry.ict_topology import ict_regions

    hidden = rig.part_names.index("hidden")
    drop = np.isin(rig.face_part, [rig.part_names.index(p) for p in PHOTO_EYE_PARTS if p in rig.part_names])
    r = ict_regions()
    socket = np.zeros(len(rig.vertices), bool)  # the skin lining the orbit behind the eyeballs
    socket[np.concatenate([r["eye_socket_left"], r["eye_socket_right"]])] = True
    drop |= socket[rig.faces].all(axis=1)
    return replace(rig, face_part=np.where(drop, hidden, rig.face_part))


def widens_eyes(weights: dict[str, float]) -> bool:
    """Whether blendshape ``weights`` raise the upper lids past the photograph's (ARKit
    ``eyeWide``): the lids then open onto what the photograph never showed, and the rig's eyeballs
    are drawn."""
    return any(v > 0 for k, v in weights.items() if k.startswith("eyeWide"))


def _resized(a: np.ndarray, height: int, width: int | None = None) -> np.ndarray:
    import cv2

    return cv2.resize(np.asarray(a, np.float32), (width or height, height), interpolation=cv2.INTER_LINEAR)


def write_photo_character(pc: PhotoCharacter, out: str | os.PathLike) -> list[Path]:
    """Write a photo character for inspection and reuse into folder ``out``.

    Files: ``<name>.obj`` (+ ``.mtl``, the texture ``<name>_albedo.png``: the fitted neutral with
    the rig's UVs), ``<name>_surround.png``, ``<name>_landmarks.csv`` (the photograph's 68 points,
    their fitted projections and residuals), ``<name>_fit.json`` (coefficients, camera, residual
    summary) and ``<name>_overlay.png`` (the photograph with the points and the fitted mesh).
    Everything is written to a temporary folder first and moved in at the end.
    """
    import json
    import shutil
    import tempfile

    import pandas as pd
    from PIL import Image

    from appeal.cells import write_table

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rig, fit, n = pc.rig, pc.fit, pc.rig.name
    with tempfile.TemporaryDirectory(dir=out) as tmp:
        t = Path(tmp)
        Image.fromarray(rig.texture).save(t / f"{n}_albedo.png")
        Image.fromarray(rig.surround.image).save(t / f"{n}_surround.png")
        _write_obj(t / f"{n}.obj", rig, f"{n}_albedo.png")
        proj = fit.camera.project(_landmark_vertices(pc))
        df = pd.DataFrame({"point": np.arange(len(pc.points)), "x": pc.points[:, 0], "y": pc.points[:, 1],
                           "fit_x": proj[:, 0], "fit_y": proj[:, 1], "residual_px": fit.residuals})
        write_table(df, t / f"{n}_landmarks.csv", float_format="%.3f")
        cam = fit.camera
        summary = {"photo_shape": list(pc.photo.shape[:2]), "eye_distance_px": fit.eye_distance,
                   "rms_residual_iod": fit.rms, "max_residual_px": float(fit.residuals.max()),
                   "yaw_deg": cam.yaw_degrees, "pitch_deg": cam.pitch_degrees,
                   "camera": {"scale_px_per_cm": cam.scale, "rotation": cam.rotation.tolist(),
                              "translation_px": cam.translation.tolist()},
                   "identity": fit.identity.tolist(),
                   "expression": dict(zip(sorted(rig.blendshapes), fit.expression.tolist()))}
        (t / f"{n}_fit.json").write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
        Image.fromarray(overlay_image(pc)).save(t / f"{n}_overlay.png")
        written = []
        for f in sorted(t.iterdir()):
            shutil.move(str(f), out / f.name)
            written.append(out / f.name)
    return written


def _landmark_vertices(pc: PhotoCharacter) -> np.ndarray:
    """The posed shape at the model's 68 landmark vertices."""
    return pc.posed[pc.landmark_ids]


def overlay_image(pc: PhotoCharacter) -> np.ndarray:
    """The photograph with the fitted mesh's edges (thin, light) and the 68 points (green: found,
    red: fitted)."""
    import cv2

    img = np.ascontiguousarray(pc.photo.copy())
    cam = pc.fit.camera
    rig = pc.rig
    faces = rig.faces[rig.face_part == rig.part_names.index("skin")]
    xy = cam.project(pc.posed)
    e1, e2 = xy[faces[:, 1]] - xy[faces[:, 0]], xy[faces[:, 2]] - xy[faces[:, 0]]
    front = faces[e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0]  # facing the camera (image y is down)
    lines = np.rint(xy[front[::3]][:, [0, 1, 2, 0]]).astype(np.int32)
    over = img.copy()
    cv2.polylines(over, list(np.ascontiguousarray(lines).reshape(-1, 4, 1, 2)), False, (235, 235, 235), 1, cv2.LINE_AA)
    img = cv2.addWeighted(over, 0.35, img, 0.65, 0)
    r = max(2, int(round(pc.fit.eye_distance / 60)))
    fitted = cam.project(_landmark_vertices(pc))
    for (x0, y0), (x1, y1) in zip(pc.points, fitted):
        cv2.circle(img, (int(round(x0)), int(round(y0))), r, (40, 220, 60), -1, cv2.LINE_AA)
        cv2.circle(img, (int(round(x1)), int(round(y1))), r, (230, 40, 40), 1, cv2.LINE_AA)
    return img


def _write_obj(path: Path, rig: FaceRig, texture_name: str) -> None:
    """The drawn skin of the fitted neutral as an OBJ with the rig's UVs and an ``.mtl`` naming the texture."""
    keep = rig.face_part == rig.part_names.index("skin")
    faces, fuv = rig.faces[keep], rig.face_uv[keep]
    used = np.unique(faces)
    remap = np.full(len(rig.vertices), -1)
    remap[used] = np.arange(len(used))
    uused = np.unique(fuv)
    uremap = np.full(len(rig.uv), -1)
    uremap[uused] = np.arange(len(uused))
    mtl = path.with_suffix(".mtl")
    mtl.write_text(f"newmtl skin\nKd 1 1 1\nmap_Kd {texture_name}\n", encoding="utf-8")
    lines = [f"mtllib {mtl.name}", "usemtl skin"]
    lines += [f"v {x:.5f} {y:.5f} {z:.5f}" for x, y, z in rig.vertices[used]]
    lines += [f"vt {u:.6f} {v:.6f}" for u, v in rig.uv[uused]]
    lines += [f"f {a}/{ta} {b}/{tb} {c}/{tc}" for (a, b, c), (ta, tb, tc)
              in zip(remap[faces] + 1, uremap[fuv] + 1)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
