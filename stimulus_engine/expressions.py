"""Facial expressions from FACS recipes on delta-blendshape rigs, and deformation transfer.

A :class:`FaceRig` is one head in one topology: neutral vertices, triangles, UVs, a part label
per triangle (skin, eyes, teeth ...), named landmark vertex sets and expression blendshapes
stored as per-vertex *deltas* from the neutral. Rigs come from the ICT Face Model
(:func:`load_ict_rig`, 33 ARKit/FACS shapes, MIT) or from code
(:func:`stimulus_engine.procedural_head.procedural_head`).

Expressions are built from FACS action-unit recipes kept in a data file
(``stimulus_engine/data/facs_recipes.yaml``): an expression is a weighted set of AUs, an AU a set
of blendshapes; ``intensity`` scales all weights. On the rig's own neutral the result is
``neutral + Σ w_k δ_k``. On a *stylised* shape in the same topology (from
:func:`stimulus_engine.stylise.stylise` or a correspondence fit) the deltas would be wrong in
size and direction (thesis ch. 4), so the expression is carried over by deformation transfer
(Sumner & Popović 2004): each triangle's deformation gradient of the source expression is
applied to the target's triangle and the target vertices are solved in the least-squares sense.
"""

from __future__ import annotations

import functools
import hashlib
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import yaml

from appeal.errors import AppealInputError

__all__ = [
    "EXPRESSIONS",
    "FaceRig",
    "apply_expression",
    "deformation_transfer",
    "expression_weights",
    "facs_recipes",
    "load_ict_rig",
    "resolve_expression",
]

_RECIPES = Path(__file__).resolve().parent / "data" / "facs_recipes.yaml"

#: The thesis's five expressions (ch. 5, §6.3).
EXPRESSIONS: tuple[str, ...] = ("neutral", "anger", "happiness", "sadness", "surprise")

#: Landmark names every rig defines (vertex sets; a landmark point is the mean of its set).
LANDMARK_NAMES: tuple[str, ...] = (
    "eye_right", "eye_left",  # eyeball vertices: the mean is the eye centre
    "eye_right_outer", "eye_right_inner", "eye_right_top", "eye_right_bottom",
    "eye_left_outer", "eye_left_inner", "eye_left_top", "eye_left_bottom",
    "nasion", "subnasale", "nose_tip", "nose_right", "nose_left",
    "mouth_right", "mouth_left", "mouth_top", "mouth_bottom",
    "chin", "face_right", "face_left", "forehead_top", "brow_right", "brow_left",
)


@dataclass
class FaceRig:
    """A head mesh with parts, landmarks, expression blendshapes and (optionally) a texture.

    Attributes
    ----------
    name : str
    vertices : (N, 3) float array
        Neutral shape. Units are centimetres for the shipped rigs (+y up, +z towards the viewer).
    faces : (F, 3) int array
    uv : (K, 2) float array or None
        UV coordinates; ``face_uv`` says which one each triangle corner uses (the exact
        per-corner layout, so texture seams stay sharp).
    face_uv : (F, 3) int array or None
    face_part : (F,) int array
        Index into ``part_names`` per triangle; parts named ``hidden`` are not rendered.
    part_names : tuple of str
        E.g. ``skin``, ``sclera``, ``iris``, ``teeth``, ``mouth``, ``lashes``, ``hidden``.
    landmarks : dict of str to int array
        Vertex sets (see :data:`LANDMARK_NAMES`).
    blendshapes : dict of str to (N, 3) array
        Per-vertex deltas from the neutral.
    rigid_sets : list of int arrays
        Vertex sets that must move rigidly (eyeballs) when the shape is stylised.
    skin : int array
        Vertices of the skin surface (smoothed by stylisation).
    texture : (H, W, 3) uint8 array or None
        Albedo of the skin in UV space.
    texture_masks : dict of str to (H, W) float array
        Region masks in UV space (``lips``, ``brows`` ...) for per-region material stylisation.
    part_textures : dict of str to (H, W, 3) uint8 array
        Fixed albedos of other parts in the rig's UV layout (e.g. ``eye``: sclera, iris and pupil
        from :func:`stimulus_engine.eyes.eye_texture`); never stylised.
    texture_maps : dict of str to uint8 array
        Optional skin maps in the texture's layout: ``normal`` (H, W, 3) tangent-space and
        ``specular`` (H, W) (see :mod:`stimulus_engine.materials`); e.g. a mesh character's own
        maps re-laid by :func:`stimulus_engine.mesh_character.correspond_rig`.
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray | None
    face_uv: np.ndarray | None
    face_part: np.ndarray
    part_names: tuple[str, ...]
    landmarks: dict[str, np.ndarray]
    blendshapes: dict[str, np.ndarray] = field(default_factory=dict)
    rigid_sets: list[np.ndarray] = field(default_factory=list)
    skin: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    texture: np.ndarray | None = None
    texture_masks: dict[str, np.ndarray] = field(default_factory=dict)
    part_textures: dict[str, np.ndarray] = field(default_factory=dict)
    texture_maps: dict[str, np.ndarray] = field(default_factory=dict)

    def landmark_points(self, vertices: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Landmark positions (mean of each vertex set) on ``vertices`` (default: the neutral)."""
        v = self.vertices if vertices is None else np.asarray(vertices)
        return {k: v[idx].mean(axis=0) for k, idx in self.landmarks.items()}

    def with_vertices(self, vertices: np.ndarray, name: str | None = None) -> FaceRig:
        """A copy with another neutral shape in the same topology (blendshapes kept as deltas)."""
        vertices = np.asarray(vertices, dtype=np.float64)
        if vertices.shape != self.vertices.shape:
            raise ValueError(f"vertices have shape {vertices.shape}, expected {self.vertices.shape}")
        return replace(self, vertices=vertices, name=name or self.name)


# --------------------------------------------------------------------------------------------
# Recipes
# --------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=4)
def facs_recipes(path: str | None = None) -> dict:
    """The FACS recipe file (``action_units``, ``expressions``, ``aliases``) as a dict."""
    p = Path(path) if path else _RECIPES
    try:
        data = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise AppealInputError(f"{p}: cannot read FACS recipes ({exc})".splitlines()[0]) from None
    for key in ("action_units", "expressions"):
        if not isinstance(data.get(key), dict):
            raise AppealInputError(f"{p}: {key}: missing (expected a mapping)")
    for expr, aus in data["expressions"].items():
        for au in aus or {}:
            if au not in data["action_units"]:
                raise AppealInputError(f"{p}: expressions.{expr}: unknown action unit '{au}'")
    data.setdefault("aliases", {})
    return data


def resolve_expression(name: str) -> str:
    """The canonical recipe name for ``name`` (aliases like ``happy`` → ``happiness``)."""
    rec = facs_recipes()
    key = str(name).strip().lower()
    key = rec["aliases"].get(key, key)
    if key not in rec["expressions"]:
        known = sorted(set(rec["expressions"]) | set(rec["aliases"]))
        raise ValueError(f"unknown expression '{name}' (expected one of: {', '.join(known)})")
    return key


def expression_weights(name: str, intensity: float = 1.0) -> dict[str, float]:
    """Blendshape weights of an expression: Σ over its AUs of AU weight × intensity per shape.

    Examples
    --------
    >>> w = expression_weights("happiness")
    >>> w["mouthSmile_L"], w["cheekSquint_R"]
    (1.0, 0.8)
    """
    rec = facs_recipes()
    weights: dict[str, float] = {}
    for au, w in (rec["expressions"][resolve_expression(name)] or {}).items():
        for shape in rec["action_units"][au]:
            weights[shape] = weights.get(shape, 0.0) + float(w) * float(intensity)
    return weights


# --------------------------------------------------------------------------------------------
# Deformation transfer
# --------------------------------------------------------------------------------------------


def _frames(v: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Per-triangle 3 × 3 frames [e1, e2, n / sqrt|n|] (Sumner & Popović's fourth vertex)."""
    e1 = v[faces[:, 1]] - v[faces[:, 0]]
    e2 = v[faces[:, 2]] - v[faces[:, 0]]
    n = np.cross(e1, e2)
    n = n / np.sqrt(np.linalg.norm(n, axis=1, keepdims=True) + 1e-300)
    return np.stack([e1, e2, n], axis=2)


#: Weak pull towards "target + source delta": fixes what edges alone leave free (the position of
#: parts that touch no fixed vertex, e.g. the lower teeth under jawOpen).
_DT_LAMBDA = 1e-4
_DT_SYSTEMS: dict[tuple, tuple] = {}


def _dt_system(src_rest: np.ndarray, faces: np.ndarray, moved: np.ndarray) -> tuple:
    """The target-independent part of :func:`deformation_transfer`, cached.

    The triangles used, their inverse rest frames, the free vertices, the edge matrix ``A`` and
    the factorisation of ``AᵀA + λI`` depend only on the source rest shape, the faces and which
    vertices the source moves, not on the target: every stylisation level of a character with
    the same expression reuses them (Exp. 2: 32 → 8 factorisations). Same numbers as solving
    afresh, so results are bit-identical.
    """
    key = tuple(hashlib.sha1(np.ascontiguousarray(a).tobytes()).hexdigest() for a in (src_rest, faces, moved))
    hit = _DT_SYSTEMS.get(key)
    if hit is not None:
        return hit
    tri = moved[faces].any(axis=1)
    fr = _frames(src_rest, faces[tri])
    ok = np.abs(np.linalg.det(fr)) > 1e-12
    tri_ids = np.flatnonzero(tri)[ok]
    f = faces[tri_ids]
    free = np.flatnonzero(moved)
    col = np.full(len(src_rest), -1)
    col[free] = np.arange(len(free))
    heads = np.concatenate([f[:, 1], f[:, 2]])
    tails = np.concatenate([f[:, 0], f[:, 0]])
    rows = np.arange(len(heads))
    data, ri, ci = [], [], []
    for idx, sign in ((heads, 1.0), (tails, -1.0)):
        c = col[idx]
        is_free = c >= 0
        ri.append(rows[is_free]); ci.append(c[is_free]); data.append(np.full(is_free.sum(), sign))
    A = sp.csr_matrix((np.concatenate(data), (np.concatenate(ri), np.concatenate(ci))),
                      shape=(len(rows), len(free)))
    AtA = (A.T @ A).tocsc() + sp.identity(len(free), format="csc") * _DT_LAMBDA
    out = (tri_ids, np.linalg.inv(fr[ok]), free, A, spla.factorized(AtA))
    if len(_DT_SYSTEMS) >= 16:
        _DT_SYSTEMS.clear()
    _DT_SYSTEMS[key] = out
    return out


def deformation_transfer(src_rest: np.ndarray, src_deformed: np.ndarray, tgt_rest: np.ndarray,
                         faces: np.ndarray, *, tol: float = 1e-7) -> np.ndarray:
    """Carry the deformation ``src_rest → src_deformed`` onto ``tgt_rest`` (same topology).

    Each triangle's deformation gradient ``S = F_def F_rest⁻¹`` (frames of two edges and the
    scaled normal) is applied to the target triangle's edges; vertices the source does not move
    stay fixed and the moved ones are solved by sparse least squares on edge vectors.

    Parameters
    ----------
    src_rest, src_deformed, tgt_rest : (N, 3) arrays
    faces : (F, 3) int array
    tol : float
        Vertices moving less than this are held fixed.

    Returns
    -------
    (N, 3) array
        The deformed target. With ``tgt_rest == src_rest`` it equals ``src_deformed`` (up to
        solver precision).
    """
    src_rest, src_deformed, tgt_rest = (np.asarray(a, np.float64) for a in (src_rest, src_deformed, tgt_rest))
    faces = np.asarray(faces, np.int64)
    moved = np.linalg.norm(src_deformed - src_rest, axis=1) > tol
    out = tgt_rest.copy()
    if not moved.any():
        return out
    tri_ids, inv_fr, free, A, solve = _dt_system(src_rest, faces, moved)
    f = faces[tri_ids]
    S = _frames(src_deformed, f) @ inv_fr
    e1 = tgt_rest[f[:, 1]] - tgt_rest[f[:, 0]]
    e2 = tgt_rest[f[:, 2]] - tgt_rest[f[:, 0]]
    d = np.concatenate([np.einsum("tij,tj->ti", S, e1), np.einsum("tij,tj->ti", S, e2)])  # (2T, 3)
    col = np.full(len(tgt_rest), -1)
    col[free] = np.arange(len(free))
    heads = np.concatenate([f[:, 1], f[:, 2]])
    tails = np.concatenate([f[:, 0], f[:, 0]])
    b = d.copy()
    for idx, sign in ((heads, 1.0), (tails, -1.0)):
        fixed = col[idx] < 0
        b[fixed] -= sign * tgt_rest[idx[fixed]]
    lam = _DT_LAMBDA
    Atb = A.T @ b + lam * (tgt_rest[free] + src_deformed[free] - src_rest[free])
    out[free] = np.column_stack([solve(Atb[:, k]) for k in range(3)])
    return out


def apply_expression(rig: FaceRig, expression: str, intensity: float = 1.0, *,
                     target: np.ndarray | None = None, method: str = "deformation_transfer") -> np.ndarray:
    """Vertices of ``rig`` (or of a stylised ``target`` in its topology) showing an expression.

    Parameters
    ----------
    rig : FaceRig
        Supplies the blendshapes (deltas from ``rig.vertices``).
    expression : str
        A recipe name (``neutral``, ``anger``, ``happiness``, ``sadness``, ``surprise``, ``fear``,
        ``disgust``) or an alias (``angry``, ``happy`` ...).
    intensity : float
        Scales all AU weights (0 = neutral, 1 = the recipe).
    target : (N, 3) array, optional
        A different neutral shape in the rig's topology (e.g. stylised). Default: the rig's own.
    method : {"deformation_transfer", "delta"}
        How to carry the expression onto ``target``; ``delta`` simply adds the deltas.

    Raises
    ------
    ValueError
        Unknown expression, or a recipe shape the rig lacks (the message names it).
    """
    weights = expression_weights(expression, intensity)
    missing = sorted(s for s in weights if s not in rig.blendshapes)
    if missing:
        raise ValueError(f"rig '{rig.name}' lacks blendshape(s) {', '.join(missing)} needed by '{expression}'")
    delta = np.zeros_like(rig.vertices)
    for s, w in sorted(weights.items()):
        delta += w * rig.blendshapes[s]
    if target is None:
        return rig.vertices + delta
    target = np.asarray(target, np.float64)
    if method == "delta" or not weights:
        return target + delta
    if method != "deformation_transfer":
        raise ValueError(f"unknown method '{method}' (expected deformation_transfer or delta)")
    return deformation_transfer(rig.vertices, rig.vertices + delta, target, rig.faces)


# --------------------------------------------------------------------------------------------
# The ICT Face Model
# --------------------------------------------------------------------------------------------

#: ICT eyeball vertex ranges (README "Eyeball Details"): the first range of each eyeball (called
#: "sclera" there) is the front cap with the corneal bulge, meant as a *transparent* wet/cornea
#: layer for Unreal's eye shader; the second ("iris") is the whole ball with the iris cone.
#: Drawn opaque, the cap hides the iris, so it is not rendered; the ball gets a procedural eye
#: texture (:mod:`stimulus_engine.eyes`) on UVs made from its geometry.
_ICT_CORNEA = ((21451, 22220), (23021, 23790))
_ICT_BALL = ((22221, 23020), (23791, 24590))
_ICT_PART_OF_REGION = {
    "face": "skin", "head_and_neck": "skin", "eye_socket_left": "skin", "eye_socket_right": "skin",
    "mouth_socket": "mouth", "gums_and_tongue": "tongue", "teeth": "teeth",
    "eyeball_left": "eye", "eyeball_right": "eye", "eyelashes_left": "lashes", "eyelashes_right": "lashes",
}
# lacrimal fluid, eye blend and eye occlusion shells (transparent helpers in Unreal) stay hidden
_ICT_PARTS = ("skin", "eye", "teeth", "mouth", "tongue", "lashes", "hidden")


def _ict_eyes(v: np.ndarray, faces: np.ndarray, face_part: np.ndarray, uv: np.ndarray | None,
              face_uv: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Hide the corneal caps and give the eyeballs their own UVs about each eye's gaze axis.

    The gaze axis of an eye points from the centre of the sphere fitted to its corneal cap
    through the cap's bulge (its 15 % of vertices farthest from the centre).
    """
    from stimulus_engine.eyes import eyeball_uv, fit_sphere

    face_part = face_part.copy()
    hidden = _ICT_PARTS.index("hidden")
    new_uv, fuv = [], None if face_uv is None else face_uv.copy()
    n_uv = 0 if uv is None else len(uv)
    for (c0, c1), (b0, b1) in zip(_ICT_CORNEA, _ICT_BALL):
        cap = v[c0:c1 + 1]
        centre, _ = fit_sphere(cap)
        d = np.linalg.norm(cap - centre, axis=1)
        axis = (cap[d > np.percentile(d, 85)] - centre).mean(axis=0)
        face_part[((faces >= c0) & (faces <= c1)).any(axis=1)] = hidden
        if fuv is not None:
            ball = ((faces >= b0) & (faces <= b1)).all(axis=1)
            ball_centre, _ = fit_sphere(v[b0:b1 + 1])
            new_uv.append(eyeball_uv(v[b0:b1 + 1], ball_centre, axis))
            fuv[ball] = faces[ball] - b0 + n_uv
            n_uv += b1 + 1 - b0
    if fuv is None:
        return face_part, uv, fuv
    return face_part, np.concatenate([uv, *new_uv]), fuv


def _ict_landmarks(v: np.ndarray, lm: np.ndarray, regions: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Named landmark sets from the 68 Multi-PIE landmarks (iBUG order) of the ICT README."""
    one = lambda i: np.array([lm[i]])  # noqa: E731
    pair = lambda i, j: np.array([lm[i], lm[j]])  # noqa: E731
    face = regions["face"]
    fv = v[face]
    mid = face[(np.abs(fv[:, 0]) < 0.6) & (fv[:, 2] > 0)]
    top = mid[np.argmax(v[mid, 1])]
    return {
        "eye_right": regions["eyeball_right"], "eye_left": regions["eyeball_left"],
        "eye_right_outer": one(36), "eye_right_inner": one(39), "eye_right_top": pair(37, 38),
        "eye_right_bottom": pair(40, 41),
        "eye_left_outer": one(45), "eye_left_inner": one(42), "eye_left_top": pair(43, 44),
        "eye_left_bottom": pair(46, 47),
        "nasion": one(27), "subnasale": one(33), "nose_tip": one(30), "nose_right": one(31), "nose_left": one(35),
        "mouth_right": one(48), "mouth_left": one(54), "mouth_top": one(51), "mouth_bottom": one(57),
        "chin": one(8), "face_right": one(0), "face_left": one(16), "forehead_top": np.array([top]),
        "brow_right": lm[17:22], "brow_left": lm[22:27],
    }


def _ict_dir(path: str | os.PathLike) -> Path:
    p = Path(path)
    if not p.is_dir():
        raise AppealInputError(f"{p}: ICT face kit folder not found (expected a folder with identity*.obj.gz)")
    return p


@functools.lru_cache(maxsize=8)
def _ict_mesh(path: str) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
    from stimulus_engine.mesh_io import load_mesh, mesh_uv_layout

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
                 shapes: list[str] | None = None) -> FaceRig:
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

    Notes
    -----
    ICT expression meshes are the *generic* neutral plus the expression, and ICT composes
    identity and expression linearly, so the deltas are ``shape − generic_neutral`` and are added
    to any identity unchanged.
    """
    from stimulus_engine.eyes import eye_texture
    from stimulus_engine.mesh_io import ict_regions

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
    face_part, uv, face_uv = _ict_eyes(v, faces, face_part, uv, face_uv)
    skin = np.concatenate([regions["face"], regions["head_and_neck"], regions["eye_socket_left"],
                           regions["eye_socket_right"]])
    return FaceRig(
        name=identity, vertices=v, faces=faces, uv=uv, face_uv=face_uv, face_part=face_part, part_names=_ICT_PARTS,
        landmarks=_ict_landmarks(v, regions["landmarks"], regions), blendshapes=blend,
        rigid_sets=[regions["eyeball_left"], regions["eyeball_right"]], skin=skin,
        part_textures={} if uv is None else {"eye": eye_texture()},
    )
