"""The face rig: one head in one topology, the type every stimulus module shares.

A :class:`FaceRig` holds neutral vertices, triangles, UVs, a part label per triangle (skin,
eyes, teeth ...), named landmark vertex sets and expression blendshapes stored as per-vertex
*deltas* from the neutral. Rigs come from the ICT Face Model
(:func:`stimulus_engine.characters.ict.load_ict_rig`), from code
(:func:`stimulus_engine.characters.procedural_head.procedural_head`) or from a mesh the rig is
corresponded onto (:func:`stimulus_engine.characters.mesh_character.correspond_rig`); expressions
(:mod:`stimulus_engine.characters.expressions`), stylisation, materials and the grid take any of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from stimulus_engine.parts.body import Body
    from stimulus_engine.parts.hair import Hair
    from stimulus_engine.parts.surround import Surround

__all__ = ["LANDMARK_NAMES", "IBUG_LANDMARKS", "FaceRig"]

#: Landmark names every rig defines (vertex sets; a landmark point is the mean of its set).
LANDMARK_NAMES: tuple[str, ...] = (
    "eye_right", "eye_left",  # eyeball vertices: the mean is the eye centre
    "eye_right_outer", "eye_right_inner", "eye_right_top", "eye_right_bottom",
    "eye_left_outer", "eye_left_inner", "eye_left_top", "eye_left_bottom",
    "nasion", "subnasale", "nose_tip", "nose_right", "nose_left",
    "mouth_right", "mouth_left", "mouth_top", "mouth_bottom",
    "chin", "face_right", "face_left", "forehead_top", "brow_right", "brow_left",
    "pupil_right", "pupil_left",  # eyeball vertices about the gaze axis (stimulus_engine.characters.gaze)
)

#: iBUG 68 points (0-based) whose mean is each rig landmark, where the 68-point markup has one
#: ("right" is the subject's right, iBUG's 36-41 eye; the eye centres and the top of the
#: forehead have no iBUG point).
IBUG_LANDMARKS: dict[str, tuple[int, ...]] = {
    "eye_right_outer": (36,), "eye_right_inner": (39,), "eye_right_top": (37, 38), "eye_right_bottom": (40, 41),
    "eye_left_outer": (45,), "eye_left_inner": (42,), "eye_left_top": (43, 44), "eye_left_bottom": (46, 47),
    "nasion": (27,), "subnasale": (33,), "nose_tip": (30,), "nose_right": (31,), "nose_left": (35,),
    "mouth_right": (48,), "mouth_left": (54,), "mouth_top": (51,), "mouth_bottom": (57,),
    "chin": (8,), "face_right": (0,), "face_left": (16,),
    "brow_right": (17, 18, 19, 20, 21), "brow_left": (22, 23, 24, 25, 26),
}


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
        from :func:`stimulus_engine.parts.eyes.eye_texture`); never stylised.
    texture_maps : dict of str to uint8 array
        Optional skin maps in the texture's layout: ``normal`` (H, W, 3) tangent-space and
        ``specular`` (H, W) (see :mod:`stimulus_engine.stylisation.materials`); e.g. a mesh character's own
        maps re-laid by :func:`stimulus_engine.characters.mesh_character.correspond_rig`.
    hair : Hair or None
        Hair bound to the skin (:func:`stimulus_engine.parts.hair.fit_hair`); drawn posed with the
        skin, whatever the vertices (an expression, a stylised shape).
    body : Body or None
        Neck, shoulders and garment bound to the skin (:func:`stimulus_engine.parts.body.fit_body`),
        drawn posed with it like the hair.
    surround : Surround or None
        A character from a photograph: the photograph's head and shoulders on a plane behind
        the face (:mod:`stimulus_engine.parts.surround`), fixed in the head's frame.
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
    hair: Hair | None = None
    body: Body | None = None
    surround: Surround | None = None

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
