"""A grid's characters: the rig of each :class:`CharacterSpec`, by kind, and its albedo.

A character's *base rig* comes from one of :data:`CHARACTER_KINDS` (``ict``: an ICT Face Model
identity, ``procedural``: a head made by code); a new kind (e.g. a scanned head) is one more
entry there: a function from the spec to the rig and a hash of its inputs. A ``mesh`` on top of
any kind makes the character that mesh, corresponded in the base rig's topology
(:func:`stimulus_engine.characters.mesh_character.correspond_rig`, cached in ``.cache/mesh``); its
expressions are then carried over from the base rig by deformation transfer.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import trimesh

from appeal.errors import AppealInputError
from appeal.logs import logger
from stimulus_engine.characters.rig import FaceRig
from stimulus_engine.characters.scan_surface import ScanSurface, wear_rig_hair
from stimulus_engine.correspondence.alignment import Similarity
from stimulus_engine.geometry.mesh_io import load_mesh
from stimulus_engine.grid.cache import GRID_VERSION, file_sha, npz_cached, save_npz, sha
from stimulus_engine.grid.inputs import load_map, load_texture
from stimulus_engine.grid.schema import CharacterSpec, MeshSpec

__all__ = ["CHARACTER_KINDS", "Character", "base_rig", "character_albedo", "character_kind", "load_character"]


def _ict_rig(c: CharacterSpec, cache: Path | None = None, render: object = None) -> tuple[FaceRig, str]:
    from stimulus_engine.characters.ict import load_ict_rig

    return load_ict_rig(c.ict, c.identity), sha(_ict_rig_key(c.ict), c.identity)


def _procedural_rig(c: CharacterSpec, cache: Path | None = None, render: object = None) -> tuple[FaceRig, str]:
    from stimulus_engine.characters.procedural_head import procedural_head

    p = c.procedural
    rig = procedural_head(p.seed, texture_size=p.texture_size, resolution=p.resolution)
    return rig, sha("procedural", p.model_dump())


def _photo_rig(c: CharacterSpec, cache: Path | None = None, render: object = None) -> tuple[FaceRig, str]:
    """The ICT model fitted to a photograph, wearing it (:mod:`stimulus_engine.characters.photo_character`),
    laid on through the grid's camera (``render``: its :class:`~stimulus_engine.grid.schema.RenderSettings`; default framing
    without); kept in ``cache/photo`` (the fit and the texture take a few seconds, the model's
    100 components longer to read)."""
    from stimulus_engine.characters.photo_character import PHOTO_VERSION, found_template
    from stimulus_engine.grid.schema import RenderSettings
    from stimulus_engine.parts.surround import surround_arrays, surround_from_arrays

    r = render if render is not None else RenderSettings()
    portrait = (r.yfov_deg, r.eye_row, r.face_fraction)
    template = c.template or found_template(c.photo)
    h = sha(GRID_VERSION, PHOTO_VERSION, file_sha(c.photo), file_sha(template) if template else None,
            _ict_rig_key(c.ict), str(c.identity_model), portrait, c.neutral)

    def make() -> dict[str, np.ndarray]:
        from stimulus_engine.characters.photo_character import photo_character

        logger.info("%s: fitting the ICT model to %s", c.name, c.photo)
        pc = photo_character(c.photo, c.ict, c.identity_model, name=c.name, template=template, portrait=portrait,
                             neutral=c.neutral)
        r = pc.rig
        return {"vertices": r.vertices, "face_part": r.face_part, "texture": r.texture,
                "part_texture_eye": r.part_textures["eye"], **{f"mask_{k}": v for k, v in r.texture_masks.items()},
                **surround_arrays(r.surround), "rms_residual_iod": np.array(pc.fit.rms)}

    from stimulus_engine.characters.ict import load_ict_rig

    d = npz_cached(cache / "photo" / f"{h}.npz", make) if cache is not None else make()
    base = load_ict_rig(c.ict, "generic_neutral_mesh")
    rig = replace(base.with_vertices(d["vertices"], name=c.name), face_part=d["face_part"], texture=d["texture"],
                  texture_masks={k[5:]: v for k, v in d.items() if k.startswith("mask_")},
                  part_textures={**base.part_textures, "eye": d["part_texture_eye"]},
                  surround=surround_from_arrays(d))
    return rig, h


def _ict_rig_key(ict: Path) -> str:
    files = sorted(Path(ict).glob("*.obj*"))
    return sha("ict", [(f.name, f.stat().st_size, int(f.stat().st_mtime)) for f in files])


#: Character kinds, each named like the :class:`CharacterSpec` field that holds its settings
#: (the first set wins: a photo character names its ICT model too): the base rig of a spec and a
#: hash of its inputs, given the grid's cache folder (None: nothing kept) and render settings.
CHARACTER_KINDS: dict[str, Callable[..., tuple[FaceRig, str]]] = {
    "photo": _photo_rig,
    "ict": _ict_rig,
    "procedural": _procedural_rig,
}


def character_kind(c: CharacterSpec) -> str:
    """The kind of a character's base rig: the key of :data:`CHARACTER_KINDS` whose spec field is set.

    The grid file's schema lets exactly one of those fields be given.
    """
    return next(k for k in CHARACTER_KINDS if getattr(c, k) is not None)


def base_rig(c: CharacterSpec, cache: Path | None = None, render: object = None) -> tuple[FaceRig, str]:
    """The character's own rig (before any ``mesh``) and a hash of its inputs (``cache``: the
    grid's cache folder, where a photo character's fit is kept; ``render``: the grid's
    :class:`~stimulus_engine.grid.schema.RenderSettings`, whose camera a photo is laid on through)."""
    return CHARACTER_KINDS[character_kind(c)](c, cache, render)


@dataclass(frozen=True)
class Character:
    """A grid character, ready to pose and paint.

    Attributes
    ----------
    spec : CharacterSpec
    rig : FaceRig
        Its shape, topology and texture (a mesh character: the mesh in the base rig's topology).
    rig_hash : str
        Hash of everything the rig is made from (part of every input hash below it).
    expression_rig : FaceRig
        The rig whose blendshapes make its expressions (the base rig; ``rig`` itself unless
        the character is a mesh).
    scan : ScanSurface or None
        With ``mesh.topology: scan``: the mesh drawn as itself, bound to ``rig``.
    cartoon : (N, 3) array or None
        With a grid ``design``: the character's own cartoon, the shape axis's stylised end
        (:mod:`stimulus_engine.grid.designs`); None: the analytic operator's.
    eyes_ahead : float
        How far the eyes lead the morph toward ``cartoon``.
    """

    spec: CharacterSpec
    rig: FaceRig
    rig_hash: str
    expression_rig: FaceRig
    scan: ScanSurface | None = None
    cartoon: np.ndarray | None = field(default=None, compare=False)
    eyes_ahead: float = 0.0


def _with_hair(c: CharacterSpec, rig: FaceRig, rig_hash: str, over: FaceRig | None = None) -> tuple[FaceRig, str]:
    """``rig`` wearing the character's hair (if any; laid over ``over``'s skin, a scan drawn as
    itself) and the hash of both."""
    from stimulus_engine.parts.hair import fit_hair, linear_rgb

    style = c.hair_style
    if style is None:
        return rig, rig_hash
    colour = None if c.hair_colour is None else linear_rgb(c.hair_colour)
    surface = None if over is None else (over.vertices, over.faces[over.face_part == over.part_names.index("skin")])
    return replace(rig, hair=fit_hair(rig, style, colour, over=surface)), sha(rig_hash, "hair", style, c.hair_colour)


def _with_body(c: CharacterSpec, rig: FaceRig, rig_hash: str, eyes: FaceRig | None = None,
               fade: bool = False) -> tuple[FaceRig, str]:
    """``rig`` with the character's bust under its head (``body: bust``) and the hash of both;
    the eye centres are ``eyes``' (a rig in the same frame; default ``rig`` itself). With
    ``fade`` (a scan, whose lower border the bust's neck continues) its skin fades into the
    neck's colour toward that border (:func:`~stimulus_engine.parts.body.fade_into_neck`)."""
    from stimulus_engine.characters.scan_regions import skin_texels
    from stimulus_engine.parts.body import (
        clothes_faces,
        fade_into_neck,
        fit_body,
        under_garment,
    )
    from stimulus_engine.parts.hair import linear_rgb

    if not c.draws_bust:
        return rig, rig_hash
    skin = rig.face_part == rig.part_names.index("skin")
    lm = (eyes or rig).landmark_points()
    hide = under_garment(rig.vertices, rig.faces, skin, lm["eye_right"], lm["eye_left"])
    if "other" in rig.texture_masks and rig.uv is not None:  # a scan's own collar
        collar = clothes_faces(rig.vertices, rig.faces, skin, rig.uv, rig.face_uv, rig.texture_masks["other"],
                               lm["eye_right"], lm["eye_left"])
        skin, hide = skin & ~collar, hide | collar
    whole = rig.faces[skin]  # the skin the collar may hug: all of it but a scan's own clothes
    rig = _hide_faces(rig, hide)
    skin = rig.face_part == rig.part_names.index("skin")
    colour = None if c.garment_colour is None else linear_rgb(c.garment_colour)
    tex = None if rig.texture is None or rig.uv is None else skin_texels(rig.texture_masks, rig.texture.shape)
    body = fit_body(rig.vertices, rig.faces[skin], rig.uv, rig.face_uv[skin], lm["eye_right"], lm["eye_left"], colour,
                    neck_faces=whole, skin=tex)
    if fade and tex is not None:
        rig = replace(rig, texture=fade_into_neck(rig.texture, body, rig.vertices, rig.faces[skin], rig.uv,
                                                  rig.face_uv[skin], lm["eye_right"], lm["eye_left"], tex))
    return replace(rig, body=body), sha(rig_hash, "body", c.body, c.garment_colour)


def _hide_faces(rig: FaceRig, hide: np.ndarray) -> FaceRig:
    """``rig`` with the faces of mask ``hide`` moved to a part named ``hidden`` (not drawn)."""
    if not hide.any():
        return rig
    names = rig.part_names if "hidden" in rig.part_names else (*rig.part_names, "hidden")
    part = rig.face_part.copy()
    part[hide] = names.index("hidden")
    return replace(rig, face_part=part, part_names=names)


def _dressed(c: CharacterSpec, rig: FaceRig, rig_hash: str) -> tuple[FaceRig, str]:
    """``rig`` with the character's hair and bust."""
    return _with_body(c, *_with_hair(c, rig, rig_hash))


def load_character(c: CharacterSpec, cache: Path, source: str, render: object = None) -> Character:
    """The character of ``c``; a ``mesh`` is corresponded once and kept in ``cache/mesh``
    (``render``: the grid's render settings, for a photo character's camera)."""
    base, base_hash = base_rig(c, cache, render)
    if c.mesh is None:
        return Character(c, *_dressed(c, base, base_hash), base)
    m = c.mesh
    files = {"file": m.file, "texture": m.texture, "normal_map": m.normal_map, "specular_map": m.specular_map}
    h = sha(GRID_VERSION, "mesh", base_hash, *[file_sha(f) if f else None for f in files.values()],
            m.model_dump(mode="json", exclude=set(files)))
    p = cache / "mesh" / f"{h}.npz"
    mesh = load_mesh(m.file) if m.topology == "scan" or not p.exists() else None
    ibug = None
    if p.exists():
        d = np.load(p)
        ibug = d["ibug_points"] if "ibug_points" in d.files else None
        masks = {k[5:]: d[k] for k in d.files if k.startswith("mask_")}
        maps = {k[4:]: d[k] for k in d.files if k.startswith("map_")}
        rig = replace(base.with_vertices(d["vertices"], name=c.name),
                      texture=d["texture"] if "texture" in d.files else None, texture_masks=masks, texture_maps=maps)
        alignment = Similarity(float(d["align_scale"]), d["align_rotation"], d["align_translation"])
    else:
        found = _scan_landmarks(c, mesh, source)
        rig, alignment = _corresponded(c, base, mesh, source, found)
        extra = {} if rig.texture is None else {"texture": rig.texture}
        if found is not None:
            ibug = extra["ibug_points"] = found.points
        save_npz(p, {"vertices": rig.vertices, **extra, **{f"mask_{k}": v for k, v in rig.texture_masks.items()},
                     **{f"map_{k}": v for k, v in rig.texture_maps.items()}, "align_scale": np.array(alignment.scale),
                     "align_rotation": alignment.rotation, "align_translation": alignment.translation})
    if _needs_ibug(m) and ibug is None:
        ibug = _scan_landmarks(c, mesh, source).points
    if m.topology != "scan":
        return Character(c, *_dressed(c, rig, h), base)
    scan = _scan_surface(c, rig, mesh, alignment, source, ibug)
    drawn, h = _with_body(c, scan.topology, sha(h, "scan"), eyes=rig, fade=True)
    scan = replace(scan, topology=drawn)
    rig, h = _with_hair(c, rig, h, over=drawn)
    return Character(c, rig, h, base, scan if rig.hair is None else wear_rig_hair(scan, rig.hair))


def _needs_ibug(m: MeshSpec) -> bool:
    """Whether drawing the scan needs its 68 points (eyeballs behind cut lids, or cut lips)."""
    return m.topology == "scan" and (m.eyes == "eyeballs" or m.mouth == "inside")


def _scan_landmarks(c: CharacterSpec, mesh: trimesh.Trimesh, source: str) -> object | None:
    """The 68 points detected on the mesh when its drawing needs them or its landmarks are
    automatic; None otherwise."""
    m = c.mesh
    if not (m.auto_landmarks or _needs_ibug(m)):
        return None
    from stimulus_engine.correspondence.auto_landmarks import detect_mesh_landmarks

    return detect_mesh_landmarks(mesh, name=f"{source}: characters.{c.name}.mesh.landmarks")


#: The rig's parts drawn behind a scan's cut lips, moving as on the rig: the mouth socket (a dark
#: cavity), the teeth, and the gums with the tongue.
MOUTH_PARTS: tuple[str, ...] = ("mouth", "teeth", "tongue")


def _scan_surface(c: CharacterSpec, rig: FaceRig, mesh: trimesh.Trimesh, alignment: Similarity,
                  source: str, ibug: np.ndarray | None) -> ScanSurface:
    """The character's mesh as drawn itself (``topology: scan``), in the rig's frame, bound to
    ``rig``, wearing its own albedo (``mesh.texture``, else the mesh file's texture), with
    eyeballs behind its lids (``mesh.eyes: eyeballs``) and lips that part over the rig's mouth
    (``mesh.mouth: inside``); ``ibug``: the 68 points on the mesh."""
    from stimulus_engine.characters.scan_eyes import erase_painted_eyes, eye_geometry
    from stimulus_engine.characters.scan_mouth import cut_lips
    from stimulus_engine.characters.scan_regions import scan_masks
    from stimulus_engine.characters.scan_surface import bind_scan
    from stimulus_engine.geometry.mesh_io import mesh_uv_layout, texture_image

    where = f"{source}: characters.{c.name}.mesh"
    layout = mesh_uv_layout(mesh)
    if layout is None:
        raise AppealInputError(f"{where}.topology: scan needs a mesh with texture coordinates "
                               "(expected UVs; or use topology: rig)")
    if c.mesh.texture is not None:
        albedo = load_texture(c.mesh.texture)
    else:
        own = texture_image(mesh)
        if own is None:
            raise AppealInputError(f"{where}: topology: scan needs the mesh's texture "
                                   "(expected a map_Kd texture in its .mtl, or mesh.texture)")
        albedo = np.asarray(own.convert("RGB"))
    v = alignment.inverse().apply(np.asarray(mesh.vertices, np.float64))
    f = np.asarray(mesh.faces)
    pts = None if ibug is None else alignment.inverse().apply(ibug)
    eyes, keep, splits = None, np.ones(len(f), bool), {}
    if c.mesh.eyes == "eyeballs":
        try:
            eyes = eye_geometry(v, f, pts[36:48], (albedo, *layout))
        except ValueError as exc:
            raise AppealInputError(f"{where}.eyes: {exc}") from None
    if eyes is not None:
        v, keep = eyes.vertices, eyes.keep
        albedo = erase_painted_eyes(albedo, v, f, *layout, keep, pts[36:48])
    if c.mesh.mouth == "inside":
        cut, v, splits["lips"] = cut_lips(v, f, pts[60:68])
        keep = keep & cut
    inside = tuple(p for p in MOUTH_PARTS if p in rig.part_names) if "lips" in splits else ()
    scan = bind_scan(rig, v, f, *layout, name=f"{c.name}_scan", eyes=eyes, keep=keep, splits=splits, inside_parts=inside)
    masks = {} if pts is None else scan_masks(albedo, v, f, *layout, pts)
    return replace(scan, topology=replace(scan.topology, texture=albedo, texture_masks=masks))


def _mesh_region(c: CharacterSpec, base: FaceRig, where: str) -> np.ndarray | None:
    """The base rig's vertices to correspond onto the mesh (``mesh.region``), None = all skin."""
    region = c.mesh.region
    if region is None:
        return None
    if region == "front":
        from stimulus_engine.characters.mesh_character import front_region

        return front_region(base)
    from stimulus_engine.geometry.ict_topology import ict_regions

    regions = ict_regions(Path(c.ict) / "vertex_indices.json")
    if region not in regions or region == "landmarks":
        names = ", ".join(k for k in regions if k != "landmarks")
        raise AppealInputError(f"{where}: region: unknown ICT region '{region}' (expected one of: {names})")
    return regions[region]


def _corresponded(c: CharacterSpec, base: FaceRig, mesh: trimesh.Trimesh, source: str,
                  found: object | None = None) -> tuple[FaceRig, Similarity]:
    """The character's mesh in the base rig's topology, with its texture and maps re-laid."""
    from stimulus_engine.characters.mesh_character import correspond_rig

    m = c.mesh
    where = f"{source}: characters.{c.name}.mesh"
    region = _mesh_region(c, base, where)
    texture = load_texture(m.texture) if m.texture is not None else None
    maps = {kind: load_map(path, kind, None, f"{where}.{kind}_map")
            for kind, path in (("normal", m.normal_map), ("specular", m.specular_map)) if path is not None}
    landmarks = {k: (list(v) if isinstance(v, tuple) else v) for k, v in m.given_landmarks().items()}
    if m.auto_landmarks:
        from stimulus_engine.characters.mesh_character import auto_landmark_points

        auto = {k: list(v) for k, v in auto_landmark_points(base, mesh, region, name=f"{where}.landmarks",
                                                             found=found).items()}
        landmarks = {**auto, **landmarks}
    logger.info("%s: corresponding %s onto %s", c.name, base.name, m.file)
    mc = correspond_rig(base, mesh, landmarks, region=region, texture=texture, texture_size=m.texture_size,
                        name=c.name, where=where, maps=maps, relay_texture=m.topology != "scan")
    logger.info("%s: correspondence metrics %s", c.name,
                {k: round(v, 5) for k, v in mc.metrics.items() if isinstance(v, float)})
    return mc.rig, mc.alignment


def character_albedo(ch: Character, source: str, cache: Path | None = None) -> tuple[np.ndarray, dict]:
    """The character's albedo and region masks before any stylisation.

    The spec's ``texture`` file, else the rig's own texture, else one painted by code on its UVs
    (:func:`stimulus_engine.characters.skin_maps.rig_albedo`; cached in ``cache/painted`` when given).
    """
    from stimulus_engine.characters.skin_maps import rig_albedo

    c, rig = ch.spec, ch.rig
    if ch.scan is not None:  # drawn as itself: the mesh's own albedo (and found regions) in its own layout
        return ch.scan.topology.texture, ch.scan.topology.texture_masks
    if c.texture is not None:
        if rig.uv is None:
            raise AppealInputError(f"{source}: characters.{c.name}.texture: the mesh has no UVs, "
                                   "so a texture cannot be applied (expected a mesh with texture coordinates)")
        return load_texture(c.texture), {}
    if rig.uv is None and rig.texture is None:
        raise AppealInputError(f"{source}: characters.{c.name}: the mesh has no UVs, so no albedo texture can be "
                               "painted (expected a mesh with texture coordinates)")
    if rig.texture is None and cache is not None:
        def paint() -> dict[str, np.ndarray]:
            img, masks = rig_albedo(rig, seed=c.texture_seed)
            return {"albedo": img, **{f"mask_{k}": v for k, v in masks.items()}}

        d = npz_cached(cache / "painted" / f"{sha(GRID_VERSION, ch.rig_hash, 'albedo', c.texture_seed)}.npz", paint)
        return d["albedo"], {k[5:]: v for k, v in d.items() if k.startswith("mask_")}
    if rig.texture is not None and c.mesh is not None and c.mesh.skin_detail:
        return _with_skin_detail(ch, cache)
    return rig_albedo(rig, seed=c.texture_seed)


def _with_skin_detail(ch: Character, cache: Path | None) -> tuple[np.ndarray, dict]:
    """A mesh character's re-laid texture with fine skin detail where it lacks it
    (:func:`stimulus_engine.characters.skin_detail.with_skin_detail`), cached in ``cache/painted``."""
    from stimulus_engine.characters.scan_regions import skin_texels
    from stimulus_engine.characters.skin_detail import DETAIL_TARGET, with_skin_detail
    from stimulus_engine.characters.skin_maps import bake_surface_points, rig_albedo

    rig = ch.rig
    albedo, masks = rig_albedo(rig, seed=ch.spec.texture_seed)

    def detailed() -> dict[str, np.ndarray]:
        pts, valid = bake_surface_points(rig, albedo.shape[0])
        lm = rig.landmark_points()
        iod = float(np.linalg.norm(lm["pupil_left"] - lm["pupil_right"]))
        return {"albedo": with_skin_detail(albedo, pts, valid, skin_texels(masks, albedo.shape), iod,
                                           seed=ch.spec.texture_seed)}

    if cache is None:
        return detailed()["albedo"], masks
    key = sha(GRID_VERSION, ch.rig_hash, "skin_detail", DETAIL_TARGET, ch.spec.texture_seed)
    return npz_cached(cache / "painted" / f"{key}.npz", detailed)["albedo"], masks
