"""Preparing a grid's inputs in ``DIR/.cache`` and turning its plan into render items.

Each character is loaded once (:mod:`stimulus_engine.grid.characters`), each material once per
albedo character (albedo and maps stylised by one :func:`stimulus_engine.stylisation.materials.stylise_material`
call), each (character, shape, expression) geometry once; every image of
:func:`~stimulus_engine.grid.plan.plan_images` then gets its input hash, a manifest row and a
:class:`~stimulus_engine.grid.worker.RenderItem`. Everything that can be wrong with the inputs
is found here, before any rendering.
"""

from __future__ import annotations

import json
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from appeal.atomic import atomic_write_text
from appeal.errors import AppealInputError
from stimulus_engine.grid.cache import (
    GRID_VERSION,
    file_sha,
    npz_cached,
    save_npy,
    save_png_once,
    save_rig,
    sha,
)
from stimulus_engine.grid.characters import Character, character_albedo
from stimulus_engine.grid.inputs import load_map
from stimulus_engine.grid.plan import (
    PlannedImage,
    material_sources,
    plan_images,
    plan_photos,
)
from stimulus_engine.grid.schema import GridFile, MaterialSpec
from stimulus_engine.grid.worker import RenderItem
from stimulus_engine.render.vignette import face_oval

if TYPE_CHECKING:
    from stimulus_engine.grid.animation import ClipItem

__all__ = ["PreparedMaterial", "level_blendshapes", "measured_grid", "posed_vertices", "prepare_grid"]


@dataclass(frozen=True)
class PreparedMaterial:
    """A material as worn by one albedo character: cached PNGs and content hashes."""

    albedo_png: str
    albedo_hash: str
    normal_png: str
    specular_png: str
    maps_hash: str


def _check_shared_uv(grid: GridFile, chars: dict[str, Character], source: str) -> None:
    """An albedo from another character needs every character to share its UV layout."""
    for m in grid.material_specs():
        if m.from_character is None:
            continue
        a = chars[m.from_character].rig
        for c in grid.characters:
            if c.name != m.from_character and (chars[c.name].scan is not None or chars[m.from_character].scan is not None):
                raise AppealInputError(
                    f"{source}: materials.{m.name}: '{c.name}' and '{m.from_character}' cannot share an albedo: a "
                    "character with mesh.topology: scan keeps its texture in its own UV layout (expected topology: rig)")
            b = chars[c.name].rig
            if b.uv is None or a.uv is None or a.uv.shape != b.uv.shape or not np.allclose(a.uv, b.uv):
                raise AppealInputError(
                    f"{source}: materials.{m.name}: characters '{c.name}' and '{m.from_character}' do not share a UV "
                    "layout (expected corresponded meshes; transfer the texture with the correspondence first)")


def _painted_maps(ch: Character, m: MaterialSpec, size: tuple[int, int], cache: Path,
                  source: str) -> dict[str, np.ndarray]:
    """Normal and specular maps painted by code on the character (``procedural_maps``), cached."""
    from stimulus_engine.characters.skin_maps import rig_detail_maps

    if ch.rig.uv is None:
        raise AppealInputError(f"{source}: materials.{m.name}.procedural_maps: character '{ch.spec.name}' has no "
                               "UVs (expected a mesh with texture coordinates)")
    seed = ch.spec.texture_seed
    return npz_cached(cache / "painted" / f"{sha(GRID_VERSION, ch.rig_hash, 'maps', seed, size)}.npz",
                      lambda: dict(zip(("normal", "specular"), rig_detail_maps(ch.rig, size=size[0], seed=seed))))


def _material_maps(m: MaterialSpec, ch: Character, size: tuple[int, int], cache: Path,
                   source: str) -> dict[str, np.ndarray]:
    """The material's unstylised maps: its files, else the character's own maps, else painted by code."""
    own = ch.rig.texture_maps
    painted = None
    found = {}
    for kind, path in (("normal", m.normal_map), ("specular", m.specular_map)):
        if path is not None:
            found[kind] = load_map(path, kind, size, f"{source}: materials.{m.name}.{kind}_map")
        elif kind in own:
            found[kind] = own[kind]
        elif m.procedural_maps:
            painted = painted or _painted_maps(ch, m, size, cache, source)
            found[kind] = painted[kind]
        if kind in found and found[kind].shape[:2] != size:
            raise AppealInputError(f"{source}: materials.{m.name}: the {kind} map of '{ch.spec.name}' is "
                                   f"{found[kind].shape[1]} x {found[kind].shape[0]}, expected {size[1]} x {size[0]} "
                                   "like its albedo")
    return found


def _albedo_key(albedo: tuple[np.ndarray, dict]) -> str:
    """Content key of a character's unstylised albedo and its region masks."""
    from stimulus_engine.stylisation.materials import albedo_hash

    img, masks = albedo
    return sha(albedo_hash(img), *[(k, albedo_hash(np.ascontiguousarray(masks[k]))) for k in sorted(masks)])


def _prepare_material(m: MaterialSpec, ch: Character, albedo: tuple[np.ndarray, dict], cache: Path,
                      source: str, key: str = "") -> PreparedMaterial:
    """Stylise the material on the character's albedo once and keep the PNGs in the cache.

    With the albedo's content ``key`` (:func:`_albedo_key`) the result is remembered in
    ``cache/looks``: a material met again (a continuum's probes, then its grid; a re-run) is not
    stylised again.
    """
    from stimulus_engine.stylisation.materials import (
        albedo_hash,
        maps_hash,
        stylise_material,
    )

    img, masks = albedo
    unstyled = _material_maps(m, ch, img.shape[:2], cache, source)
    amount = m.amount_for(ch.spec.name)
    memo = cache / "looks" / f"{sha(GRID_VERSION, key, maps_hash(unstyled.get('normal'), unstyled.get('specular')), m.style, amount)}.json"
    if key and memo.exists():
        look = PreparedMaterial(**json.loads(memo.read_text()))
        if all(Path(p).exists() for p in (look.albedo_png, look.normal_png, look.specular_png) if p):
            return look
    styl, maps = stylise_material(img, m.style, masks, unstyled, amount)
    ah = albedo_hash(styl)
    paths = {kind: str(save_png_once(a if a.ndim == 3 else np.repeat(a[..., None], 3, axis=2),
                                     cache / "maps" / f"{kind}_{albedo_hash(a)}.png")) for kind, a in maps.items()}
    look = PreparedMaterial(str(save_png_once(styl, cache / "albedo" / f"{ah}.png")), ah, paths.get("normal", ""),
                            paths.get("specular", ""), maps_hash(maps.get("normal"), maps.get("specular")))
    if key:
        memo.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(memo, json.dumps(asdict(look)))
    return look


def _surround_look(ch: Character, m: MaterialSpec, cache: Path) -> tuple[str, str]:
    """A photo character's surround stylised with material ``m`` (its PNG in ``cache/albedo`` and
    its hash); ``("", "")`` for a character without one."""
    from stimulus_engine.stylisation.materials import albedo_hash, stylise_photograph

    s = ch.rig.surround
    if s is None:
        return "", ""
    amount = m.amount_for(ch.spec.name)
    h = sha(albedo_hash(s.image), "photograph", m.style, amount)
    path = cache / "albedo" / f"surround_{h}.png"
    if not path.exists():
        save_png_once(stylise_photograph(s.image, m.style, amount), path)
    return str(path), h


def level_up(eye_right: np.ndarray, eye_left: np.ndarray, view_dir: tuple[float, float, float] = (0.0, 0.0, 1.0)
             ) -> tuple[float, float, float]:
    """The camera's up vector that puts both eyes on one image row when looking along ``-view_dir``.

    Examples
    --------
    >>> level_up(np.array([-3.0, 0.0, 0.0]), np.array([3.0, 0.0, 0.0]))
    (0.0, 1.0, 0.0)
    >>> [round(x, 6) for x in level_up(np.array([-1.0, -1.0, 0.0]), np.array([1.0, 1.0, 0.0]))]
    [-0.707107, 0.707107, 0.0]
    """
    d = np.asarray(view_dir, np.float64) / np.linalg.norm(view_dir)
    across = np.asarray(eye_left, np.float64) - np.asarray(eye_right, np.float64)  # towards the subject's left
    across -= d * (across @ d)
    up = np.cross(d, across)
    return tuple(float(x) for x in up / np.linalg.norm(up))


def _camera_for(ch: Character, shape_vertices: np.ndarray, grid: GridFile) -> tuple:
    """Same face size and eye position for every shape: framed on the shape's neutral landmarks,
    the camera rolled so the two eye centres lie on one image row (a scan sits as it was
    scanned, often with the head slightly tilted)."""
    from stimulus_engine.render import face_camera

    lm = ch.rig.landmark_points(shape_vertices)
    eye = (lm["eye_left"] + lm["eye_right"]) / 2
    length = float(np.linalg.norm(lm["forehead_top"] - lm["chin"]))
    r = grid.render
    if ch.rig.surround is not None:  # a photo character: seen as its photograph was taken
        from stimulus_engine.parts.surround import surround_view

        view, up = surround_view(ch.rig.surround)
        cam = face_camera(eye, length, yfov_deg=r.yfov_deg, eye_row=r.eye_row, face_fraction=r.face_fraction,
                          view_dir=tuple(view), up=tuple(up))
        return (cam.position, cam.target, cam.yfov_deg, cam.up)
    cam = face_camera(eye, length, yfov_deg=r.yfov_deg, eye_row=r.eye_row, face_fraction=r.face_fraction,
                      up=level_up(lm["eye_right"], lm["eye_left"]))
    return (cam.position, cam.target, cam.yfov_deg, cam.up)


def _camera_text(cam: tuple) -> str:
    from stimulus_engine.render import CameraSpec

    return CameraSpec(tuple(cam[0]), tuple(cam[1]), cam[2], tuple(cam[3])).describe()


def _gaze_target(grid: GridFile, cam: tuple) -> np.ndarray | None:
    """The point the eyes look at (``render.gaze``): the camera, a given point, or None (as modelled)."""
    gaze = grid.render.gaze
    if gaze == "model":
        return None
    return np.asarray(cam[0] if gaze == "camera" else gaze, np.float64)


#: Each (character, shape level, method)'s transferred blendshapes, made once per process.
_LEVEL_RIGS: dict[tuple, dict[str, np.ndarray]] = {}


def level_blendshapes(ch: Character, shape: float, shape_v: np.ndarray, method: str) -> dict[str, np.ndarray]:
    """The character's blendshapes carried onto one shape level by ``method`` (``aligned`` or ``rbf``:
    :func:`~stimulus_engine.characters.blendshape_transfer.transfer_blendshapes`), made once. A designed
    level's (a grid ``design``) then move each main landmark at least as far, in units of the face's width
    and length, as the character's realistic level's do."""
    from stimulus_engine.characters.blendshape_transfer import transfer_blendshapes

    key = (ch.rig_hash, float(shape), method)
    if key not in _LEVEL_RIGS:
        if len(_LEVEL_RIGS) >= 16:
            _LEVEL_RIGS.clear()
        if ch.cartoon is not None and shape > 0:  # a designed level moves at least as far as the realistic one
            reference = (ch.rig.vertices, level_blendshapes(ch, 0.0, ch.rig.vertices, method))
            _LEVEL_RIGS[key] = transfer_blendshapes(ch.expression_rig, shape_v, method, face_units="larger",
                                                    reference=reference)
        else:
            _LEVEL_RIGS[key] = transfer_blendshapes(ch.expression_rig, shape_v, method)
    return _LEVEL_RIGS[key]


def posed_vertices(ch: Character, shape: float, shape_v: np.ndarray, weights: dict[str, float],
                   grid: GridFile) -> np.ndarray:
    """The character's rig at one shape level (neutral ``shape_v``) posed by blendshape ``weights``.

    The rig's own blendshapes on its own neutral; carried onto a stylised shape or a
    corresponded mesh character by the grid's ``expression_transfer``: deformation transfer of
    the whole pose, or the level's own blendshapes (:func:`level_blendshapes`: aligned to the
    rig's range of motion in face units, or RBF proportion matching) weighted and added.
    ValueError names a weight's blendshape the rig lacks.
    """
    from stimulus_engine.characters.expressions import check_blendshapes, pose_weights

    plain = shape == 0 and ch.expression_rig is ch.rig
    method = grid.expression_transfer
    if plain or method == "deformation_transfer" or not any(weights.values()):
        return pose_weights(ch.expression_rig, weights, target=None if plain else shape_v)
    check_blendshapes(ch.expression_rig, weights)
    shapes = level_blendshapes(ch, shape, shape_v, method)
    out = np.array(shape_v, np.float64, copy=True)
    for name, w in sorted(weights.items()):
        if w:
            out += w * shapes[name]
    return out


def rig_geometry(ch: Character, shape: float, shape_v: np.ndarray, weights: dict[str, float], grid: GridFile,
                 target: np.ndarray | None, what: tuple[str, str]) -> np.ndarray:
    """The rig at one shape level posed by ``weights`` (:func:`posed_vertices`), its lashes seated
    on the lids and its eyeballs turned to look at ``target`` (if given); float32, as cached.

    ``what``: (where, expression) for the one-line error of a weight the rig lacks
    (``"<file>: characters.<name>: <the rig's complaint> needed by '<expression>'"``).
    """
    from stimulus_engine.characters.eye_openings import centre_eyes
    from stimulus_engine.characters.gaze import aim_eyes
    from stimulus_engine.characters.lashes import seat_lashes

    try:
        v = posed_vertices(ch, shape, shape_v, weights, grid)
    except ValueError as exc:  # a recipe shape the rig lacks
        raise AppealInputError(f"{what[0]}: {exc} needed by '{what[1]}'") from None
    v = seat_lashes(ch.rig, ch.rig.vertices, v)
    if target is not None:  # centred in their openings (a scan draws its own), then aimed
        if ch.scan is None:
            v = centre_eyes(v, _eye_shifts(ch, shape, shape_v))
        v = aim_eyes(ch.rig.landmarks, v, target)
    return v.astype(np.float32)


_EYE_SHIFTS: dict[tuple[str, float], list] = {}


def _eye_shifts(ch: Character, shape: float, shape_v: np.ndarray) -> list:
    """:func:`~stimulus_engine.characters.eye_openings.eye_shifts` of the character's neutral at
    one shape level, found once per character and level."""
    from stimulus_engine.characters.eye_openings import eye_shifts

    key = (ch.rig_hash, float(shape))
    if key not in _EYE_SHIFTS:
        if len(_EYE_SHIFTS) > 64:
            _EYE_SHIFTS.clear()
        _EYE_SHIFTS[key] = eye_shifts(ch.rig, shape_v)
    return _EYE_SHIFTS[key]


def _upper_teeth(ch: Character, memo: dict[str, np.ndarray]) -> np.ndarray:
    """A scan character's upper teeth (:func:`~stimulus_engine.characters.incisor_display.upper_teeth`),
    found once per character (``memo``)."""
    from stimulus_engine.characters.incisor_display import upper_teeth

    if ch.spec.name not in memo:
        topo = ch.scan.topology
        memo[ch.spec.name] = upper_teeth(topo.vertices, topo.faces, topo.face_part, topo.part_names)
    return memo[ch.spec.name]


def drawn_geometry(ch: Character, posed: np.ndarray, target: np.ndarray | None,
                   teeth: dict[str, np.ndarray]) -> np.ndarray:
    """What is drawn of the posed rig ``posed`` (:func:`rig_geometry`): the rig itself, or a scan
    character's own surface posed through it, its eyeballs aimed at ``target``, its upper incisors
    shown between parted lips and the mouth's inside and the eyeballs kept behind its skin
    (``teeth``: the upper teeth met so far, by character); float32, as cached."""
    from stimulus_engine.characters.gaze import aim_eyes
    from stimulus_engine.characters.incisor_display import show_upper_incisors
    from stimulus_engine.characters.skin_clearance import (
        eyes_behind_skin,
        inside_behind_skin,
    )

    if ch.scan is None:
        return posed
    topo = ch.scan.topology
    drawn = ch.scan.pose(posed)
    if target is not None:  # the drawn eyeballs follow the rig's only nearly: aim them too
        drawn = aim_eyes(topo.landmarks, drawn, target)
    rig_pose = ch.rig.landmark_points(posed)
    drawn = show_upper_incisors(drawn, topo.faces, topo.face_part, topo.part_names, _upper_teeth(ch, teeth),
                                rig_pose["mouth_left"], rig_pose["mouth_right"],
                                float(np.linalg.norm(rig_pose["eye_left"] - rig_pose["eye_right"])))
    drawn = inside_behind_skin(drawn, topo.faces, topo.face_part, topo.part_names)
    drawn = eyes_behind_skin(drawn, topo.faces, topo.face_part, topo.part_names, topo.landmarks)
    return drawn.astype(np.float32)


def cell_vertices(ch: Character, shape: float, shape_v: np.ndarray, weights: dict[str, float], grid: GridFile,
                  target: np.ndarray | None, teeth: dict[str, np.ndarray], what: tuple[str, str]) -> np.ndarray:
    """The drawn vertices (float32) of a cell posed by ``weights``: :func:`rig_geometry`, then
    :func:`drawn_geometry` — the one chain a still image and every frame of a clip go through."""
    return drawn_geometry(ch, rig_geometry(ch, shape, shape_v, weights, grid, target, what), target, teeth)


def _geometry(ch: Character, im: PlannedImage, shape_v: np.ndarray, grid: GridFile, cache: Path,
              source: str, target: np.ndarray | None = None) -> tuple[Path, str]:
    """The posed vertices of (character, shape, expression) in ``cache/geometry`` and their hash
    (:func:`rig_geometry`: the eyeballs turned to look at ``target``, if given)."""
    from stimulus_engine.characters.expressions import expression_weights

    r = grid.render
    aim = () if target is None else ("gaze", *np.round(target, 6).tolist())
    how = () if grid.expression_transfer == "deformation_transfer" else (grid.expression_transfer,)
    gh = sha(GRID_VERSION, ch.rig_hash, im.shape, im.expression, r.intensity, *aim, *how)
    gp = cache / "geometry" / f"{gh}.npy"
    if not gp.exists():
        save_npy(gp, rig_geometry(ch, im.shape, shape_v, expression_weights(im.expression, r.intensity), grid, target,
                                  (f"{source}: characters.{im.character}", im.expression)))
    return gp, gh


def _as_clips(ch: Character, im: PlannedImage, shape_v: np.ndarray, grid: GridFile, target: np.ndarray | None,
              teeth: dict[str, np.ndarray], cache: Path, source: str, still: RenderItem,
              row: dict) -> list[tuple[ClipItem, dict]]:
    """The prepared still cell ``still``/``row`` as the clips of ``grid.animation``
    (:func:`stimulus_engine.grid.animation.prepare_clip`): one whose every frame is its apex
    weights times the curve's (or a performance's row), or with ``animation.revcorr`` one per trial
    of the pool (:func:`stimulus_engine.grid.animation.revcorr_clip`), each frame through
    :func:`cell_vertices` like the still."""
    from stimulus_engine.characters.expressions import expression_weights
    from stimulus_engine.grid.animation import clip_frame_weights, prepare_clip, revcorr_pool

    anim = grid.animation
    what = (f"{source}: characters.{im.character}", im.expression)

    def pose(w: dict[str, float]) -> np.ndarray:
        return cell_vertices(ch, im.shape, shape_v, w, grid, target, teeth, what)

    if anim.revcorr is not None:
        pool = anim.revcorr
        played = revcorr_pool(anim)
        missing = sorted({n for _, frames in played for f in frames for n in f} - set(ch.expression_rig.blendshapes))
        if missing:
            raise AppealInputError(f"{source}: animation.revcorr: character '{im.character}' has no blendshape "
                                   f"'{missing[0]}' (its rig cannot play the grammar's action units)")
        return [prepare_clip(still, row, anim, cache, frames, pose, trial) for trial, frames in played]
    apex = expression_weights(im.expression, grid.render.intensity)
    frames = clip_frame_weights(anim, apex)
    unknown = sorted({n for f in frames for n in f} - set(ch.expression_rig.blendshapes))
    if anim.performance is not None and unknown:
        raise AppealInputError(f"{anim.performance}: column '{unknown[0]}' is not a blendshape of character "
                               f"'{im.character}' (expected frame, time or one of: "
                               f"{', '.join(sorted(ch.expression_rig.blendshapes))})")
    clip, clip_row = prepare_clip(still, row, anim, cache, frames, pose)
    if anim.performance is not None:  # how far each frame moves the face (performance_measures.csv)
        from stimulus_engine.grid.performance_measures import frame_landmarks

        def landmarks(w: dict[str, float]) -> dict[str, np.ndarray]:
            return ch.rig.landmark_points(rig_geometry(ch, im.shape, shape_v, w, grid, target, what).astype(np.float64))

        clip_row["_frame_landmarks"] = str(frame_landmarks(Path(clip.still.geometry_npy).with_suffix(".landmarks.npz"),
                                                           frames, landmarks))
    return [(clip, clip_row)]


def _eye_style(grid: GridFile, im: PlannedImage) -> tuple[float, float] | tuple[()]:
    """(iris scale, paint) of the image's stylised eyes (:mod:`stimulus_engine.stylisation.eyes`):
    the iris grows with the shape level, the paint is a ``painted`` material's amount (``flat``
    paints fully); () where the eyes stay as modelled."""
    from stimulus_engine.stylisation.eyes import IRIS_SCALE_AT_CARTOON

    if not grid.render.stylised_eyes:
        return ()
    m = im.material
    paint = m.amount_for(im.albedo_from) if m.style == "painted" else 1.0 if m.style == "flat" else 0.0
    scale = 1.0 + (IRIS_SCALE_AT_CARTOON - 1.0) * float(im.shape)
    return () if scale == 1.0 and paint == 0.0 else (round(scale, 4), round(float(paint), 4))


def _landmark_rows(ch: Character, im: PlannedImage, vertices: np.ndarray) -> list[dict]:
    return [{"character": im.character, "shape": im.shape, "stylisation": im.stylisation, "expression": im.expression,
             "landmark": name, "x": pt[0], "y": pt[1], "z": pt[2]}
            for name, pt in ch.rig.landmark_points(vertices.astype(np.float64)).items()]


def photo_eyes(ch: Character, shape: float, expression: str) -> bool:
    """Whether an image shows the photograph's own eyes: a photo character's realistic level, its
    lids not raised past the photograph's (:func:`~stimulus_engine.characters.photo_character.widens_eyes`);
    elsewhere (the eyes grow or open wider) the rig's eyeballs, their iris in the photograph's colour."""
    if ch.rig.surround is None or shape != 0.0:
        return False
    from stimulus_engine.characters.expressions import expression_weights
    from stimulus_engine.characters.photo_character import widens_eyes

    return not widens_eyes(expression_weights(expression))


def _rig_file(ch: Character, level: float, shape_v: np.ndarray, cache: Path, saved: set[Path],
              own_eyes: bool = False) -> Path:
    """The rig file the workers draw ``ch``'s shape ``level`` with (saved once into ``saved``): one per
    character, or one per designed level, whose hair is fitted to it
    (:func:`~stimulus_engine.grid.designs.drawn_rig`); ``own_eyes``: a photo character with its
    photograph's eyes (:func:`photo_eyes`)."""
    from stimulus_engine.characters.photo_character import photo_eyed
    from stimulus_engine.grid.designs import drawn_rig

    drawn = ch.scan.topology if ch.scan is not None else drawn_rig(ch, level, shape_v)
    if own_eyes:
        drawn = photo_eyed(drawn)
    per_level = () if drawn is ch.rig or ch.scan is not None else ("level", level, own_eyes)
    path = cache / "rigs" / f"{sha(GRID_VERSION, ch.rig_hash, drawn.name, *per_level)}.npz"
    if path not in saved:
        save_rig(path, drawn)
        saved.add(path)
    return path


def _characters(grid: GridFile, cache: Path, source: str,
                loaded: dict[str, Character] | None) -> dict[str, Character]:
    """The grid's characters by name: ``loaded`` if given, else each loaded from ``cache``."""
    from stimulus_engine.grid.designs import grid_characters

    return loaded or grid_characters(grid, cache, source)


def _probe_images(probe: GridFile, source: str, cache: Path, chars: dict[str, Character]) -> list[np.ndarray]:
    """A small grid's images, prepared with the grid's cache and its loaded ``chars``, in manifest
    order (the measurements of :mod:`~stimulus_engine.grid.continuum`). Each image is kept in
    ``cache/continuum/images`` under its input hash, so a level measured again (a continuum's
    ends, in every round) is not rendered again; the rest are rendered by the local workers."""
    from PIL import Image

    from appeal.parallel import parallel_map
    from stimulus_engine.grid.worker import render_item

    scratch = cache / "continuum" / "render"
    manifest, items, _ = prepare_grid(probe, scratch, source=source, cache=cache,
                                      characters={c.name: chars[c.name] for c in probe.characters})
    kept = [cache / "continuum" / "images" / f"{h}.png" for h in manifest["input_hash"]]
    todo = [(it, k) for it, k in zip(items, kept) if not k.exists()]
    res = parallel_map(render_item, [it for it, _ in todo], desc="measuring the continuum",
                       labels=[it.file for it, _ in todo])
    if res.failures:
        raise AppealInputError(f"{source}: measuring the stylisation continuum: {res.failures[0].label}: "
                               f"{res.failures[0].error}")
    for it, k in todo:
        k.parent.mkdir(parents=True, exist_ok=True)
        os.replace(Path(it.out_dir) / it.file, k)
    images = []
    for k in kept:
        with Image.open(k) as im:
            images.append(np.asarray(im.convert("RGB")))
    return images


def measured_grid(grid: GridFile, out: Path, *, source: str = "grid", cache: Path | None = None,
                  characters: dict[str, Character] | None = None) -> GridFile:
    """``grid`` with its material and shape continua measured out
    (:func:`stimulus_engine.grid.continuum.measured`: the probes prepared in ``out/.cache`` or
    ``cache``, with the grid's ``characters`` loaded once, and rendered here); a grid of listed
    levels as it is; continua with ``spacing: even`` written out by value, nothing rendered
    (:func:`stimulus_engine.grid.continuum.spaced_by_value`)."""
    from stimulus_engine.grid.continuum import (
        measured,
        needs_measuring,
        spaced_by_value,
    )

    grid = spaced_by_value(grid)
    if not needs_measuring(grid):
        return grid
    cache = Path(cache) if cache is not None else Path(out) / ".cache"
    chars = _characters(grid, cache, source, characters)
    still = grid.model_copy(update={"animation": None})  # measured on still images (an animated grid's apexes)
    done = measured(still, cache, lambda probe: _probe_images(probe, source, cache, chars))
    return done.model_copy(update={"animation": grid.animation})


def prepare_grid(grid: GridFile, out: Path, *, source: str = "grid", cache: Path | None = None,
                 characters: dict[str, Character] | None = None
                 ) -> tuple[pd.DataFrame, list[RenderItem | ClipItem], pd.DataFrame]:
    """Prepare the inputs of every image in ``out/.cache`` (or ``cache``) and list the images
    (``characters``: the grid's, already loaded).

    Material and shape continua are measured out first (:func:`measured_grid`).

    Returns
    -------
    manifest : DataFrame
        One row per image (``seconds`` and ``status`` still empty; photographs carry their
        source file in ``_photo``).
    items : list of RenderItem or ClipItem
        One per rendered image, in manifest order (photographs need no rendering); with
        ``grid.animation`` one :class:`~stimulus_engine.grid.animation.ClipItem` per cell, whose
        row gives its clip (:mod:`stimulus_engine.grid.animation`).
    landmarks : DataFrame
        Long table: character, shape, stylisation, expression, landmark, x, y, z.
    """
    from stimulus_engine.grid.designs import shape_vertices

    cache = Path(cache) if cache is not None else out / ".cache"
    chars = _characters(grid, cache, source, characters)
    grid = measured_grid(grid, out, source=source, cache=cache, characters=chars)
    albedos = {name: character_albedo(ch, source, cache) for name, ch in chars.items()}
    _check_shared_uv(grid, chars, source)
    images = plan_images(grid)
    sources = material_sources(images)
    keys = {src: _albedo_key(albedos[src]) for src in dict.fromkeys(src for src, _ in sources)}
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:  # numpy, OpenCV and zlib let go of the GIL
        looks = dict(zip(((src, m.name) for src, m in sources), pool.map(
            lambda sm: _prepare_material(sm[1], chars[sm[0]], albedos[sm[0]], cache, source, keys[sm[0]]), sources)))
    r = grid.render
    rows, items, lm_rows = [], [], []
    rig_files: set[Path] = set()
    shapes: dict[tuple, tuple[np.ndarray, tuple, Path]] = {}
    geometry: dict[tuple, tuple[Path, str]] = {}
    uppers: dict[str, np.ndarray] = {}
    for im in images:
        ch = chars[im.character]
        if (im.character, im.shape) not in shapes:
            shape_v = shape_vertices(ch, im.shape)
            shapes[im.character, im.shape] = (shape_v, _camera_for(ch, shape_v, grid),
                                              _rig_file(ch, im.shape, shape_v, cache, rig_files))
        shape_v, cam, rig_file = shapes[im.character, im.shape]
        if photo_eyes(ch, im.shape, im.expression):
            rig_file = _rig_file(ch, im.shape, shape_v, cache, rig_files, own_eyes=True)
        gkey = (im.character, im.shape, im.expression)
        target = _gaze_target(grid, cam)
        if gkey not in geometry:
            geometry[gkey] = _geometry(ch, im, shape_v, grid, cache, source, target)
            lm_rows += _landmark_rows(ch, im, np.load(geometry[gkey][0]))
        gp, gh = geometry[gkey]
        if ch.scan is not None:  # the posed rig carries the scan's own surface
            gp = cache / "geometry" / f"{sha(gh, 'scan', ch.scan.topology.name)}.npy"
            if not gp.exists():
                save_npy(gp, drawn_geometry(ch, np.load(geometry[gkey][0]), target, uppers))
        look = looks[im.albedo_from, im.material.name]
        extra = () if look.maps_hash == "none" else (look.maps_hash,)  # hashes without maps as before
        eyes = _eye_style(grid, im)
        surround_png, surround_hash = _surround_look(ch, im.material, cache)
        ih = sha(GRID_VERSION, gh, look.albedo_hash, im.lighting, im.shading, cam, r.model_dump(exclude={"stylised_eyes"}),
                 *extra, *((("eyes",) + eyes) if eyes else ()),  # the eyes' style where it changes them
                 *((surround_hash,) if surround_hash else ()))
        items.append(RenderItem(im.file, str(out), str(rig_file), str(gp), look.albedo_png,
                                im.lighting, im.shading, cam, r.width, r.height, r.shadows, tuple(r.background),
                                look.normal_png, look.specular_png, r.engine, r.samples, r.seed,
                                face_oval(r.width, r.height, r.eye_row, r.face_fraction) if r.vignette else (),
                                r.supersample, eyes, surround_png=surround_png))
        rows.append({"file": im.file, "character": im.character, "shape": im.shape, "shape_label": im.shape_label,
                     "stylisation": im.stylisation, "material": im.material.name,
                     "material_style": im.material.style, "material_from": im.albedo_from,
                     "material_amount": im.material.amount_for(im.albedo_from) if im.material.style == "painted"
                     else float("nan"),
                     "expression": im.expression, "emotion": im.emotion, "lighting": im.lighting,
                     "shading": im.shading, "geometry_hash": gh, "albedo_hash": look.albedo_hash,
                     "maps_hash": look.maps_hash, "input_hash": ih, "camera": _camera_text(cam),
                     "width": r.width, "height": r.height})
        if grid.animation is not None:  # the cell as a clip (a reverse-correlation pool's: a clip per trial)
            clips = _as_clips(ch, im, shape_v, grid, target, uppers, cache, source, items[-1], rows[-1])
            items[-1:], rows[-1:] = [c[0] for c in clips], [c[1] for c in clips]
    for p in plan_photos(grid):
        rows.append({"file": p.file, "character": p.character, "shape": "photograph", "shape_label": "photograph",
                     "stylisation": len(grid.shape_levels()), "material": "photograph",
                     "material_style": "photograph", "material_amount": float("nan"),
                     "material_from": p.character, "expression": p.expression, "emotion": p.emotion,
                     "lighting": "photograph", "shading": "photograph", "geometry_hash": "", "albedo_hash": "",
                     "maps_hash": "", "input_hash": sha(GRID_VERSION, "photo", file_sha(p.source), r.width, r.height),
                     "camera": f"photo:{p.source.name}", "width": r.width, "height": r.height,
                     "_photo": str(p.source)})
    return _with_people(pd.DataFrame(rows), grid), items, pd.DataFrame(lm_rows)


def _with_people(manifest: pd.DataFrame, grid: GridFile) -> pd.DataFrame:
    """The manifest with the London set's ``age``, ``gender`` and ``ethnicity`` of each photo
    character that comes from it (:func:`~stimulus_engine.characters.photo_character.photo_person`)."""
    from stimulus_engine.characters.photo_character import photo_person

    people = {c.name: photo_person(c.photo) for c in grid.characters if c.photo is not None}
    if not any(people.values()):
        return manifest
    for col in ("age", "gender", "ethnicity"):
        manifest[col] = manifest["character"].map(lambda n, col=col: people.get(n, {}).get(col))
    return manifest
