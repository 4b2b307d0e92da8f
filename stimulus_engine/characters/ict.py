"""The ICT Face Model as a character kind: :func:`load_ict_rig` reads an identity and its
expression shapes as a :class:`~stimulus_engine.characters.rig.FaceRig` (33 ARKit/FACS shapes, MIT).

The topology's named vertex sets (the README's ranges plus ``vertex_indices.json``) are
:mod:`stimulus_engine.geometry.ict_topology`: correspondence benchmarks select regions with them
without loading a rig.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError
from stimulus_engine.characters.expressions import facs_recipes
from stimulus_engine.geometry.ict_topology import ict_regions
from stimulus_engine.characters.rig import IBUG_LANDMARKS, LANDMARK_NAMES, FaceRig

__all__ = ["load_ict_rig", "ict_identity_basis"]

#: ICT eyeball vertex ranges (README "Eyeball Details"): the first range of each eyeball (called
#: "sclera" there) is the front cap with the corneal bulge, meant as a *transparent* wet/cornea
#: layer for Unreal's eye shader; the second ("iris") is the whole ball with the iris cone.
#: Drawn opaque, the cap hides the iris, so it is not rendered; the ball gets a procedural eye
#: texture (:mod:`stimulus_engine.parts.eyes`) on UVs made from its geometry.
_ICT_CORNEA = ((21451, 22220), (23021, 23790))
_ICT_BALL = ((22221, 23020), (23791, 24590))
_ICT_PART_OF_REGION = {
    "face": "skin", "head_and_neck": "skin", "eye_socket_left": "skin", "eye_socket_right": "skin",
    "mouth_socket": "mouth", "gums_and_tongue": "tongue", "teeth": "teeth",
    "eyeball_left": "eye", "eyeball_right": "eye", "eyelashes_left": "lashes", "eyelashes_right": "lashes",
    "lacrimal_fluid_left": "tear", "lacrimal_fluid_right": "tear",
    "eye_occlusion_left": "eye_shadow", "eye_occlusion_right": "eye_shadow",
}
# the lacrimal fluid is drawn as the lids' wet line ("tear": a clear, glossy film), the eye
# occlusion shells as the shadow along the lids and the caruncle ("eye_shadow": see
# parts.eyes.eye_shadow_texture); the eye blend shells (transparent helpers in Unreal) stay hidden
_ICT_PARTS = ("skin", "eye", "teeth", "mouth", "tongue", "lashes", "tear", "eye_shadow", "hidden")


def _ict_eyes(v: np.ndarray, faces: np.ndarray, face_part: np.ndarray, uv: np.ndarray | None,
              face_uv: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, dict]:
    """Hide the corneal caps and give the eyeballs their own UVs about each eye's gaze axis.

    The gaze axis of an eye points from the centre of the sphere fitted to its corneal cap
    through the cap's bulge (its 15 % of vertices farthest from the centre). Also returns each
    eye's pupil ring (``pupil_left``, ``pupil_right``: :func:`~stimulus_engine.characters.gaze.pupil_ring`).
    """
    from stimulus_engine.characters.gaze import pupil_ring
    from stimulus_engine.parts.eyes import eyeball_uv, fit_sphere

    pupils = {}
    face_part = face_part.copy()
    hidden = _ICT_PARTS.index("hidden")
    new_uv, fuv = [], None if face_uv is None else face_uv.copy()
    n_uv = 0 if uv is None else len(uv)
    for side, (c0, c1), (b0, b1) in zip(("left", "right"), _ICT_CORNEA, _ICT_BALL):
        cap = v[c0:c1 + 1]
        centre, _ = fit_sphere(cap)
        d = np.linalg.norm(cap - centre, axis=1)
        axis = (cap[d > np.percentile(d, 85)] - centre).mean(axis=0)
        face_part[((faces >= c0) & (faces <= c1)).any(axis=1)] = hidden
        ball_centre, _ = fit_sphere(v[b0:b1 + 1])
        pupils[f"pupil_{side}"] = pupil_ring(v, np.arange(b0, b1 + 1), ball_centre, axis)
        if fuv is not None:
            ball = ((faces >= b0) & (faces <= b1)).all(axis=1)
            new_uv.append(eyeball_uv(v[b0:b1 + 1], ball_centre, axis))
            fuv[ball] = faces[ball] - b0 + n_uv
            n_uv += b1 + 1 - b0
    if fuv is None:
        return face_part, uv, fuv, pupils
    return face_part, np.concatenate([uv, *new_uv]), fuv, pupils


def _ict_landmarks(v: np.ndarray, lm: np.ndarray, regions: Mapping[str, np.ndarray],
                   pupils: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Named landmark sets from the 68 Multi-PIE landmarks (iBUG order) of the ICT README, the
    eyeballs and their pupil rings."""
    face = regions["face"]
    fv = v[face]
    mid = face[(np.abs(fv[:, 0]) < 0.6) & (fv[:, 2] > 0)]
    top = mid[np.argmax(v[mid, 1])]
    special = {"eye_right": regions["eyeball_right"], "eye_left": regions["eyeball_left"],
               "forehead_top": np.array([top]), **pupils}
    return {name: special[name] if name in special else lm[list(IBUG_LANDMARKS[name])] for name in LANDMARK_NAMES}


def _ict_dir(path: str | os.PathLike) -> Path:
    p = Path(path)
    if not p.is_dir():
        raise AppealInputError(f"{p}: ICT face kit folder not found (expected a folder with identity*.obj.gz)")
    return p


@functools.lru_cache(maxsize=8)
def _ict_mesh(path: str) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
    from stimulus_engine.geometry.mesh_io import load_mesh, mesh_uv_layout

    m = load_mesh(path)
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64), mesh_uv_layout(m)


@functools.lru_cache(maxsize=128)
def _obj_vertices(path: str) -> np.ndarray:
    """Only the ``v`` lines of an OBJ (``.obj.gz``) file, fast: the ICT expression shapes share
    the neutral's topology, so their faces and UVs need not be parsed again (a full parse of the
    33 shapes took ~14 s per identity)."""
    import gzip

    try:
        raw = gzip.open(path, "rb").read() if path.endswith(".gz") else Path(path).read_bytes()
    except (OSError, EOFError) as exc:
        raise AppealInputError(f"{path}: cannot read mesh file ({exc})".splitlines()[0]) from None
    lines = [ln[2:] for ln in raw.splitlines() if ln.startswith(b"v ")]
    try:
        v = np.array(b" ".join(lines).split(), dtype=np.float64).reshape(len(lines), -1)[:, :3]
    except ValueError:
        raise AppealInputError(f"{path}: malformed vertex lines (expected 'v x y z')") from None
    return v


def _ict_file(d: Path, name: str) -> str:
    for suffix in (".obj.gz", ".obj"):
        if (d / f"{name}{suffix}").exists():
            return str(d / f"{name}{suffix}")
    raise AppealInputError(f"{d}: {name}: mesh not found (expected {name}.obj.gz or {name}.obj)")


def load_ict_rig(ict_dir: str | os.PathLike, identity: str = "identity000", *,
                 shapes: list[str] | None = None, textures: bool = True) -> FaceRig:
    """The ICT Face Model as a :class:`FaceRig`.

    Parameters
    ----------
    ict_dir : path-like
        The ICT-FaceKit folder (``identity000.obj.gz`` …, ``generic_neutral_mesh.obj.gz``,
        the expression shapes and ``vertex_indices.json``).
    identity : str
        File stem of the neutral identity (``identity000``, ``identity001``, ``identity002`` or
        ``generic_neutral_mesh``).
    shapes : list of str, optional
        Blendshapes to load (default: every shape the FACS recipes use that exists in the folder).
    textures : bool
        Make the eyes' textures (the photographic iris and the lid shadow, ~3 s); False for a rig
        that is only posed, never drawn (retargeting, rig transfer).

    Notes
    -----
    ICT expression meshes are the *generic* neutral plus the expression, and ICT composes
    identity and expression linearly, so the deltas are ``shape − generic_neutral`` and are added
    to any identity unchanged.
    """
    from stimulus_engine.parts.eyes import eye_shadow_texture, photographic_eye_texture

    d = _ict_dir(ict_dir)
    v, faces, layout = _ict_mesh(_ict_file(d, identity))
    generic = _obj_vertices(_ict_file(d, "generic_neutral_mesh"))
    regions = ict_regions(d / "vertex_indices.json")
    rec = facs_recipes()
    if shapes is None:
        wanted = sorted({s for au in rec["action_units"].values() for s in au})
        shapes = [s for s in wanted if any((d / f"{s}{x}").exists() for x in (".obj.gz", ".obj"))]
    blend = {}
    for s in shapes:
        sv = _obj_vertices(_ict_file(d, s))
        if sv.shape != generic.shape:
            raise AppealInputError(f"{d}: {s}: {len(sv)} vertices, expected {len(generic)} (same topology)")
        blend[s] = sv - generic
    vpart = np.full(len(v), _ICT_PARTS.index("hidden"))
    for region, part in _ICT_PART_OF_REGION.items():
        vpart[regions[region]] = _ICT_PARTS.index(part)
    face_part = vpart[faces].max(axis=1)  # a triangle touching a hidden vertex is hidden
    face_part = np.where((vpart[faces] == vpart[faces][:, :1]).all(axis=1), vpart[faces[:, 0]], face_part)
    # the lash strips are hair cards meant for an alpha texture; opaque, the lower ones lie on
    # the cheek as a black band: keep the upper lashes (a dark lid line) only
    for side in ("left", "right"):
        lash = np.isin(faces[:, 0], regions[f"eyelashes_{side}"])
        low = v[faces[lash]].mean(axis=1)[:, 1] < v[regions[f"eyeball_{side}"]].mean(axis=0)[1]
        face_part[np.flatnonzero(lash)[low]] = _ICT_PARTS.index("hidden")
    uv, face_uv = (None, None) if layout is None else layout
    face_part, uv, face_uv, pupils = _ict_eyes(v, faces, face_part, uv, face_uv)
    skin = np.concatenate([regions["face"], regions["head_and_neck"], regions["eye_socket_left"],
                           regions["eye_socket_right"]])
    return FaceRig(
        name=identity, vertices=v, faces=faces, uv=uv, face_uv=face_uv, face_part=face_part, part_names=_ICT_PARTS,
        landmarks=_ict_landmarks(v, regions["landmarks"], regions, pupils), blendshapes=blend,
        rigid_sets=[regions["eyeball_left"], regions["eyeball_right"]], skin=skin,
        part_textures={} if uv is None or not textures else {"eye": photographic_eye_texture(),
                                                             "eye_shadow": eye_shadow_texture()},
    )


def ict_identity_basis(*ict_dirs: str | os.PathLike) -> np.ndarray:
    """The ICT model's identity components as deltas from its mean face, ``(K, N, 3)``.

    Every ``identity*.obj(.gz)`` in the folders (the face kit's three and ``ict-facekit-more``'s
    97: the model's 100 principal components of the light-stage scans) minus the mean
    (``generic_neutral_mesh``, from the first folder that has it), in file-name order.
    """
    dirs = [_ict_dir(d) for d in ict_dirs]
    mean_dir = next((d for d in dirs if any((d / f"generic_neutral_mesh{x}").exists() for x in (".obj.gz", ".obj"))),
                    None)
    if mean_dir is None:
        raise AppealInputError(f"{dirs[0]}: generic_neutral_mesh: mesh not found (expected the ICT face kit folder)")
    mean = _obj_vertices(_ict_file(mean_dir, "generic_neutral_mesh"))
    files = sorted({f.name.split(".")[0]: f for d in dirs for f in d.glob("identity*.obj*")}.items())
    if not files:
        raise AppealInputError(f"{dirs[0]}: no identity*.obj.gz files (expected the ICT identity components)")
    out = np.empty((len(files), *mean.shape))
    for k, (name, f) in enumerate(files):
        v = _obj_vertices(str(f))
        if v.shape != mean.shape:
            raise AppealInputError(f"{f}: {len(v)} vertices, expected {len(mean)} (the ICT topology)")
        out[k] = v - mean
    return out
