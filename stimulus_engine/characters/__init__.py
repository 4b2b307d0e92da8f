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

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["au_poses", "blendshape_transfer", "blendshape_weights", "design", "expressions", "gaze", "ict",
                "incisor_display", "lashes", "markers", "mesh_character", "motion_files", "motion_similarity",
                "photo_character", "photo_fit", "photo_texture", "procedural_head", "render_parts", "retarget",
                "rig", "scan_cut", "scan_eyes", "scan_mouth", "scan_regions", "scan_surface", "skin_clearance",
                "skin_maps", "synthetic_actor"],
    submod_attrs={
        "blendshape_transfer": ["align_blendshapes", "range_of_motion", "transfer_blendshapes"],
        "design": ["Design", "correspond_design", "design_head"],
        "expressions": ["EXPRESSIONS", "apply_expression", "deformation_transfer", "expression_weights",
            "pose_weights"],
        "gaze": ["aim_eyes", "lines_of_sight"],
        "ict": ["ict_identity_basis", "load_ict_rig"],
        "lashes": ["seat_lashes"],
        "markers": ["marker_vertices"],
        "mesh_character": ["MeshCharacter", "correspond_rig", "front_region"],
        "motion_files": ["read_motion"],
        "photo_character": ["PhotoCharacter", "photo_character", "write_photo_character"],
        "photo_fit": ["OrthoCamera", "fit_landmarks"],
        "procedural_head": ["procedural_head"],
        "render_parts": ["SHADINGS", "hair_render_part", "rig_render_parts"],
        "retarget": ["retarget_frames", "retarget_performance"],
        "rig": ["FaceRig", "IBUG_LANDMARKS", "LANDMARK_NAMES"],
        "scan_eyes": ["eye_geometry"],
        "scan_mouth": ["cut_lips"],
        "scan_regions": ["scan_masks"],
        "scan_surface": ["ScanSurface", "bind_scan"],
        "skin_maps": ["check_map", "rig_albedo", "rig_detail_maps"],
    },
)

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
