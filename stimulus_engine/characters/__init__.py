"""Characters: a rig (topology, expression shapes, landmarks, parts) of each kind — the ICT
model, the procedural head, a mesh or scan corresponded onto a rig — with its expressions, its
own skin maps and its parts as the renderer's parts. Imports ``geometry``, ``parts``, ``morphpca``
and ``faces2d`` (a photograph's landmarks),
``correspondence`` (a scan on a rig) and ``render`` (the renderer's part type).

Public API
----------
FaceRig, LANDMARK_NAMES, IBUG_LANDMARKS
    The rig every character is (module ``rig``).
load_ict_rig, ict_identity_basis
    An ICT Face Model identity with its 33 ARKit/FACS shapes, and the model's identity components
    (module ``ict``).
Design, correspond_design, design_head
    An artist's stylised head brought into the rig's topology: the surface by ElastiFace, the
    eyes, nose and mouth carried over whole (module ``design``).
procedural_head
    A head made by code, with a painted texture (module ``procedural_head``).
MeshCharacter, correspond_rig, front_region
    Any mesh or scan carried onto a rig through a dense correspondence (module
    ``mesh_character``); a scan's surface, eyes, mouth and regions: ``bind_scan``,
    ``eye_geometry``, ``cut_lips``, ``scan_masks`` (modules ``scan_surface``, ``scan_eyes``,
    ``scan_mouth``, ``scan_regions``, ``scan_cut``).
photo_character, PhotoCharacter, write_photo_character, fit_landmarks, OrthoCamera
    A character from one frontal photograph: the ICT model fitted to its landmarks with a camera
    (module ``photo_fit``, pure), the photograph laid into the rig's layout (``photo_texture``),
    its head and shoulders behind it (module ``photo_character``).
EXPRESSIONS, apply_expression, expression_weights, pose_weights, deformation_transfer
    FACS expressions as weighted action units, any blendshape weights, and deformation
    transfer (module ``expressions``).
transfer_blendshapes, align_blendshapes, range_of_motion, marker_vertices
    A rig's blendshapes carried onto another face with range-of-motion alignment (thesis
    ch. 4; modules ``blendshape_transfer``, ``motion_similarity``, ``markers``).
retarget_frames, retarget_performance, read_motion
    Marker or weight performances (C3D, CSV) to blendshape weights, frame by frame (modules
    ``retarget``, ``motion_files``).
rig_albedo, rig_detail_maps, check_map
    The character's own albedo, pore normal map and specular map (module ``skin_maps``).
rig_render_parts, hair_render_part, SHADINGS
    The character as pyrender parts for a shading model (module ``render_parts``).
aim_eyes, lines_of_sight
    Each eye's line of sight, and eyeballs turned to look at a point (module ``gaze``).
seat_lashes
    Eyelashes kept rooted on the lids in every shape and pose (module ``lashes``).
"""

from stimulus_engine.characters.blendshape_transfer import (
    align_blendshapes,
    range_of_motion,
    transfer_blendshapes,
)
from stimulus_engine.characters.design import Design, correspond_design, design_head
from stimulus_engine.characters.expressions import (
    EXPRESSIONS,
    apply_expression,
    deformation_transfer,
    expression_weights,
    pose_weights,
)
from stimulus_engine.characters.gaze import aim_eyes, lines_of_sight
from stimulus_engine.characters.ict import ict_identity_basis, load_ict_rig
from stimulus_engine.characters.lashes import seat_lashes
from stimulus_engine.characters.markers import marker_vertices
from stimulus_engine.characters.mesh_character import (
    MeshCharacter,
    correspond_rig,
    front_region,
)
from stimulus_engine.characters.motion_files import read_motion
from stimulus_engine.characters.photo_character import (
    PhotoCharacter,
    photo_character,
    write_photo_character,
)
from stimulus_engine.characters.photo_fit import OrthoCamera, fit_landmarks
from stimulus_engine.characters.procedural_head import procedural_head
from stimulus_engine.characters.render_parts import (
    SHADINGS,
    hair_render_part,
    rig_render_parts,
)
from stimulus_engine.characters.retarget import retarget_frames, retarget_performance
from stimulus_engine.characters.rig import IBUG_LANDMARKS, LANDMARK_NAMES, FaceRig
from stimulus_engine.characters.scan_eyes import eye_geometry
from stimulus_engine.characters.scan_mouth import cut_lips
from stimulus_engine.characters.scan_regions import scan_masks
from stimulus_engine.characters.scan_surface import ScanSurface, bind_scan
from stimulus_engine.characters.skin_maps import check_map, rig_albedo, rig_detail_maps

__all__ = [
    "EXPRESSIONS",
    "IBUG_LANDMARKS",
    "LANDMARK_NAMES",
    "SHADINGS",
    "Design",
    "FaceRig",
    "MeshCharacter",
    "OrthoCamera",
    "PhotoCharacter",
    "ScanSurface",
    "aim_eyes",
    "align_blendshapes",
    "apply_expression",
    "bind_scan",
    "check_map",
    "correspond_design",
    "correspond_rig",
    "cut_lips",
    "deformation_transfer",
    "design_head",
    "expression_weights",
    "eye_geometry",
    "fit_landmarks",
    "front_region",
    "hair_render_part",
    "ict_identity_basis",
    "lines_of_sight",
    "load_ict_rig",
    "marker_vertices",
    "photo_character",
    "pose_weights",
    "procedural_head",
    "range_of_motion",
    "read_motion",
    "retarget_frames",
    "retarget_performance",
    "rig_albedo",
    "rig_detail_maps",
    "rig_render_parts",
    "scan_masks",
    "seat_lashes",
    "transfer_blendshapes",
    "write_photo_character",
]
