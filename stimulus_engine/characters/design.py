"""A design: an artist's stylised head brought into the rig's topology (thesis §3.2, §6.4).

The thesis's stylised levels were heads artists made (level 0 "inspired by *Pocoyo*", level 3 by
*Tangled*); ElastiFace brought each into correspondence with the realistic character so that shape
and material could be morphed and exchanged. :func:`correspond_design` does that for any head mesh
(OBJ, glTF/GLB; its own tessellation) and the ICT rig:

1. **The head.** :func:`design_head` takes the mesh part the landmarks lie on (a GLB holds body,
   hair and decals too) and welds its UV seams.
2. **The surface** (ElastiFace). The rig's skin is corresponded onto the head from the landmark pairs (the eye corners and lid apexes on the
   design's eye outlines, nose, mouth, chin, face sides, forehead):
   :func:`~stimulus_engine.characters.mesh_character.correspond_rig`. The cranium, cheeks, jaw and
   ears take the design's shape.
3. **The features** (part-based, §3.4). A painted or modelled cartoon eye, button nose or line of a
   mouth has no surface for the rig's lids, nostrils and lips to fit: squeezed onto it by the
   surface term they fold (a crumpled nose, lids folded over the eyeball). Each feature of the rig
   is instead carried over whole — the eye (eyeball, lids, lashes, wet line), the nose, the mouth
   with what is inside — scaled to the design's feature (eye and mouth width between their corners,
   nose width between the alae), turned with the head and placed at the design's feature, and
   blended smoothly into the corresponded surface around it (:data:`FEATURE_BLOCKS`). Eyeballs
   stay spheres.
4. **Rounder eyes.** A cartoon's eye is round where an adult's is almond-shaped: the lids are
   opened towards the design's eye height with the rig's own lid shapes (:data:`LID_POSE`:
   ``eyeWide`` raises the upper lid, negative ``eyeBlink`` and ``eyeSquint`` open both further),
   at most as far as the design asks (its outline's height over width).
5. **The frame.** The result is moved into the rig's frame with its eyes' midpoint on the rig's and
   its eyes as high above its chin as the rig's (a cartoon's large head is large: its face is wider,
   its cranium higher than the rig's), so a character, its design and every morph between them
   share one chin, neck and body; below the jaw the rig's own neck joins the design's head
   (:func:`neck_weights`), so the body fits every level.

What the design brings is its shape; its texture is not used (the material axis paints each
character's own colours). Eyes painted on the design (decals) give its eye outline as landmarks.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import trimesh

from appeal.errors import AppealInputError
from stimulus_engine.characters.rig import FaceRig

__all__ = ["FEATURE_BLOCKS", "LID_POSE", "Design", "design_head", "neck_weights", "correspond_design", "feature_falloff",
           "open_lids",
           "feature_sizes"]

#: Each carried-over feature: (name, the rig landmarks whose mean is its centre, the landmark pair
#: whose distance is its size, inner and outer blend radius in units of that size). Inside the
#: inner radius a rig vertex moves with the feature; beyond the outer it keeps its corresponded place.
#: Laid down in this order, each over the ones before (the nose over the mouth's reach).
FEATURE_BLOCKS: tuple[tuple[str, tuple[str, ...], tuple[str, str], float, float], ...] = (
    ("mouth", ("mouth_right", "mouth_left"), ("mouth_right", "mouth_left"), 0.6, 1.1),
    ("nose", ("nose_tip", "nose_right", "nose_left", "subnasale"), ("nose_right", "nose_left"), 0.75, 1.3),
    ("eye_right", ("eye_right_outer", "eye_right_inner"), ("eye_right_outer", "eye_right_inner"), 0.55, 1.0),
    ("eye_left", ("eye_left_outer", "eye_left_inner"), ("eye_left_outer", "eye_left_inner"), 0.55, 1.0),
)
#: The lid shapes that round a design's eyes, per eye (ARKit names, ``_L``/``_R`` appended), at their
#: full weight; scaled down when the design's eye is less tall than these make it.
LID_POSE: dict[str, float] = {"eyeWide": 1.0, "eyeBlink": -0.3, "eyeSquint": -0.6}


@dataclass
class Design:
    """A design in a rig's topology.

    Attributes
    ----------
    name : str
    vertices : (N, 3) array
        The design's neutral in the rig's topology and frame (the rig's face width, its eyes'
        midpoint on the rig's).
    metrics : dict
        The surface correspondence's fit metrics, the features' scales and the lid pose used.
    """

    name: str
    vertices: np.ndarray
    metrics: dict = field(default_factory=dict)


def _weld(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """``mesh`` with vertices at one place merged (UV seams split a game mesh's surface into patches)."""
    key = np.round(np.asarray(mesh.vertices, np.float64), 7)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    faces = inv.ravel()[np.asarray(mesh.faces)]
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    used = np.unique(faces)
    remap = np.full(len(uniq), -1)
    remap[used] = np.arange(len(used))
    return trimesh.Trimesh(uniq[used], remap[faces], process=False)


def design_head(parts: Mapping[str, trimesh.Trimesh], points: np.ndarray, where: str = "design") -> trimesh.Trimesh:
    """The head of a design file: the connected piece the landmark ``points`` lie on, seams welded.

    Parameters
    ----------
    parts : mapping of str to trimesh.Trimesh
        The file's parts (:func:`stimulus_engine.geometry.mesh_io.load_parts`), or the one part named.
    points : (k, 3) array
        The landmark points given on the head.
    where : str
        Prefix of error messages.

    Raises
    ------
    AppealInputError
        When no piece lies under the points (each farther than 2 % of the file's size).
    """
    pieces = []
    for name, mesh in parts.items():
        welded = _weld(mesh)
        labels = trimesh.graph.connected_component_labels(welded.face_adjacency, node_count=len(welded.faces))
        for k in np.unique(labels):
            piece = welded.submesh([np.flatnonzero(labels == k)], append=True)
            pieces.append((name, piece))
    size = max(float(np.linalg.norm(np.ptp(np.vstack([p.vertices for _, p in pieces]), axis=0))), 1e-12)
    votes = np.zeros(len(pieces))
    dist = np.stack([trimesh.proximity.closest_point(p, points)[1] for _, p in pieces])  # (pieces, k)
    votes += np.bincount(np.argmin(dist, axis=0), minlength=len(pieces))
    best = int(np.argmax(votes))
    if np.min(dist, axis=0).max() > 0.02 * size:
        raise AppealInputError(f"{where}: landmarks: no piece of the mesh lies under every landmark (the farthest is "
                               f"{np.min(dist, axis=0).max() / size:.0%} of the mesh's size away; expected points on the head)")
    head = pieces[best][1]
    if len(head.faces) < 200:
        raise AppealInputError(f"{where}: the landmarks lie on a piece of only {len(head.faces)} triangles "
                               f"(part {pieces[best][0]!r}); expected the design's head")
    return head


def neck_weights(rig: FaceRig, vertices: np.ndarray | None = None) -> np.ndarray:
    """How much of each rig vertex is neck (0 … 1): 0 above the plane through a point a sixth of the
    face length under the chin and, behind, the base of the skull (the height of the mouth corners at
    the back of the head), rising smoothly to 1 a third of the face length below it. A design's neck
    (a stub under a large head) would squeeze the rig's, where the body joins it: the neck keeps
    the rig's shape there and joins the design's head above."""
    from stimulus_engine.geometry.ramps import smoothstep

    v = np.asarray(rig.vertices if vertices is None else vertices, np.float64)
    lm = rig.landmark_points(v)
    length = float(np.linalg.norm(lm["forehead_top"] - lm["chin"]))
    front = lm["chin"] - np.array([0.0, length / 6, 0.0])
    back = np.array([0.0, (lm["mouth_left"][1] + lm["mouth_right"][1]) / 2, float(v[np.asarray(rig.skin), 2].min())])
    slope = (front[1] - back[1]) / (front[2] - back[2])
    below = back[1] + slope * (v[:, 2] - back[2]) - v[:, 1]
    return smoothstep(np.clip(below / (length / 3), 0, 1))


def feature_sizes(rig: FaceRig, vertices: np.ndarray) -> dict[str, float]:
    """The size of each feature of :data:`FEATURE_BLOCKS` (its landmark pair's distance), and each eye's
    height over width (``eye_right_ratio``, ``eye_left_ratio``)."""
    lm = rig.landmark_points(vertices)
    out = {name: float(np.linalg.norm(lm[a] - lm[b])) for name, _, (a, b), _, _ in FEATURE_BLOCKS}
    for side in ("right", "left"):
        out[f"eye_{side}_ratio"] = float(np.linalg.norm(lm[f"eye_{side}_top"] - lm[f"eye_{side}_bottom"])
                                         / out[f"eye_{side}"])
    return out


def feature_falloff(d: np.ndarray, r1: float, r2: float) -> np.ndarray:
    """1 within ``r1``, falling smoothly to 0 at ``r2`` (a feature's weight at distance ``d`` from its centre)."""
    from stimulus_engine.geometry.ramps import smoothstep

    return 1 - smoothstep(np.clip((d - r1) / max(r2 - r1, 1e-12), 0, 1))


def _carry_features(rig: FaceRig, surface: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, dict]:
    """The rig's features carried whole onto ``surface`` (the corresponded rig): step 3 of the module.

    The features are laid down in :data:`FEATURE_BLOCKS`' order, each over what is there: where two
    blends overlap (the mouth's reaches the nose's alae) the later one (the nose) keeps its size."""
    v0 = rig.vertices
    lm0, lmd = rig.landmark_points(v0), rig.landmark_points(surface)
    out = np.array(surface, np.float64, copy=True)
    scales = {}
    for name, centre, (a, b), r1, r2 in FEATURE_BLOCKS:
        size0 = float(np.linalg.norm(lm0[a] - lm0[b]))
        scale = float(np.linalg.norm(lmd[a] - lmd[b])) / size0
        c0 = np.mean([lm0[k] for k in centre], axis=0)
        cd = np.mean([lmd[k] for k in centre], axis=0)
        if name.startswith("eye_"):  # centred between the lids' apexes, where the design's eye is
            side = name.split("_")[1]
            cd[1] = (lmd[f"eye_{side}_top"][1] + lmd[f"eye_{side}_bottom"][1]) / 2
            c0[1] = (lm0[f"eye_{side}_top"][1] + lm0[f"eye_{side}_bottom"][1]) / 2
        w = feature_falloff(np.linalg.norm(v0 - c0, axis=1), r1 * size0, r2 * size0)
        if name in rig.landmarks:  # the eyeball moves whole (a sphere)
            w[np.asarray(rig.landmarks[name])] = 1.0
        out = out * (1 - w[:, None]) + (cd + scale * (v0 - c0) @ rotation.T) * w[:, None]
        scales[name] = scale
    return out, scales


def open_lids(rig: FaceRig, v: np.ndarray, target: dict[str, float], scales: dict[str, float] | None = None,
              rotation: np.ndarray | None = None) -> tuple[np.ndarray, dict[str, float]]:
    """``v`` with the lids opened towards each eye's ``target`` height over width (``eye_right_ratio``,
    ``eye_left_ratio``) with :data:`LID_POSE`, at most its full weight; never closed.

    ``scales`` (by ``eye_right``/``eye_left``; default each eye's width over the rig's) and ``rotation``
    (default none) carry the rig's lid shapes to the eye as it is in ``v``. Returns the vertices and
    the weight used per eye.
    """
    out = np.array(v, np.float64, copy=True)
    rotation = np.eye(3) if rotation is None else rotation
    if scales is None:
        now0, now = feature_sizes(rig, rig.vertices), feature_sizes(rig, out)
        scales = {k: now[k] / now0[k] for k in ("eye_right", "eye_left")}
    used = {}
    for side, tag in (("right", "R"), ("left", "L")):
        shapes = {f"{k}_{tag}": w for k, w in LID_POSE.items() if f"{k}_{tag}" in rig.blendshapes}
        if not shapes:
            continue
        delta = scales[f"eye_{side}"] * sum(w * rig.blendshapes[k] for k, w in shapes.items()) @ rotation.T
        now = feature_sizes(rig, out)[f"eye_{side}_ratio"]
        full = feature_sizes(rig, out + delta)[f"eye_{side}_ratio"]
        amount = float(np.clip((target[f"eye_{side}_ratio"] - now) / max(full - now, 1e-9), 0, 1))
        out += amount * delta
        used[side] = amount
    return out, used


def _into_rig_frame(rig: FaceRig, v: np.ndarray) -> np.ndarray:
    """``v`` scaled so its eyes sit as high above its chin as the rig's, its eyes' midpoint moved onto
    the rig's (step 5): the chin, and the neck and body under it, stay where the rig has them."""
    lm0, lm = rig.landmark_points(rig.vertices), rig.landmark_points(v)
    eyes0 = (lm0["eye_left"] + lm0["eye_right"]) / 2
    eyes = (lm["eye_left"] + lm["eye_right"]) / 2
    scale = float(eyes0[1] - lm0["chin"][1]) / float(eyes[1] - lm["chin"][1])
    return eyes0 + (v - eyes) * scale


def correspond_design(rig: FaceRig, head: trimesh.Trimesh, landmarks: Mapping[str, object], *,
                      name: str = "design", where: str = "design") -> Design:
    """An artist's head in ``rig``'s topology (the module's steps 2-5).

    Parameters
    ----------
    rig : FaceRig
        The rig whose topology the design takes (the ICT model's mean face: a design is of no one).
    head : trimesh.Trimesh
        The design's head (:func:`design_head`).
    landmarks : mapping of str to point
        Rig landmark name → point on ``head`` (as for
        :func:`~stimulus_engine.characters.mesh_character.correspond_rig`; every eye's four lid
        landmarks, the nose's and the mouth's corners are needed by the features).
    name : str
    where : str
        Prefix of error messages.

    Returns
    -------
    Design

    Raises
    ------
    AppealInputError
        A landmark a feature needs is missing, or the correspondence fails.
    """
    from stimulus_engine.characters.lashes import seat_lashes
    from stimulus_engine.characters.mesh_character import correspond_rig
    from stimulus_engine.correspondence import umeyama

    needed = sorted({k for _, c, pair, _, _ in FEATURE_BLOCKS for k in (*c, *pair)}
                    | {f"eye_{s}_{k}" for s in ("right", "left") for k in ("top", "bottom")}
                    | {"face_left", "face_right"})
    missing = [k for k in needed if k not in landmarks]
    if missing:
        raise AppealInputError(f"{where}: landmarks: '{missing[0]}' is needed (a design's features are placed by "
                               f"{', '.join(needed)})")
    mc = correspond_rig(rig, head, landmarks, name=name, where=where, relay_texture=False)
    surface = mc.rig.vertices
    rotation = umeyama(rig.vertices[mc.region], surface[mc.region]).rotation
    target = feature_sizes(rig, surface)
    v, scales = _carry_features(rig, surface, rotation)
    v, lids = open_lids(rig, v, target, scales, rotation)
    v = _into_rig_frame(rig, v)
    neck = neck_weights(rig)[:, None]
    v = v * (1 - neck) + rig.vertices * neck
    v = seat_lashes(rig, rig.vertices, v)
    metrics = {**mc.metrics, **{f"scale_{k}": s for k, s in scales.items()},
               **{f"lids_{k}": a for k, a in lids.items()},
               **{f"design_{k}": x for k, x in target.items() if k.endswith("ratio")}}
    return Design(name=name, vertices=v, metrics=metrics)
