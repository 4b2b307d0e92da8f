"""Stimulus engine: face stimuli from 3D scans and rigs (correspondence, characters, stylisation,
rendered grids) and from photographs (2D morph-space PCA face models).

Sub-packages, lowest first; each imports only those listed before it (``docs/architecture.md``):

``data``            the shipped assets (eyes, hair, one scan, eight photographs, tables)
``geometry``        meshes, OBJ files, closest points, UV rasterisation, sampling, polylines
``render``          cameras, lights, the pyrender and Cycles engines, contact sheets
``morphpca``        2D morph-space PCA face models, expression projection, avatars
``audit``           low-level image measures of a stimulus set and SHINE-style equalisation
``correspondence``  ElastiFace dense correspondence and texture transfer (thesis ch. 3)
``parts``           eyes, eyelashes, hair
``characters``      rigs of each kind, scans on rigs, expressions, blendshape transfer, retargeting, skin maps
``stylisation``     shape and material stylisation, morphs, neoteny measures
``grid``            a study's stimulus grid from its file to the PNGs

The names below are the user-facing ones, grouped by what they do; each sub-package's own
``__all__`` has the rest.
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["audit", "characters", "correspondence", "data", "faces2d", "geometry", "grid", "morphpca",
                "parts", "render", "stylisation"],
    submod_attrs={
        "geometry": ["load_mesh", "load_parts", "mesh_uv_layout", "save_mesh", "select_region", "texture_image"],
        "correspondence": ["CorrespondParams", "CorrespondenceResult", "Correspondences", "SurfacePoints",
            "correspond", "deformed_mesh", "parse_pairs", "reorder_landmarks"],
        "correspondence.texture_transfer": ["transfer_texture"],
        "characters": ["EXPRESSIONS", "FaceRig", "MeshCharacter", "apply_expression", "correspond_rig",
            "deformation_transfer", "expression_weights", "front_region", "load_ict_rig", "procedural_head",
            "rig_albedo", "rig_detail_maps"],
        "geometry.ict_topology": ["ict_regions"],
        "parts": ["eye_texture", "eyeball_uv"],
        "stylisation": ["MATERIAL_LEVELS", "StyliseParams", "blend_images", "blend_vertices", "neoteny_measures",
            "neoteny_table", "partial_blend", "stylise", "stylise_albedo", "stylise_map", "stylise_rig"],
        "grid": ["run_grid"],
        "morphpca": ["MorphModel", "Reconstructor", "build_avatar", "build_model", "load_model",
            "project_expression"],
    },
)


from stimulus_engine._moved import install as _install_moved_paths

__all__ = [
    "apply_expression",
    "blend_images",
    "blend_vertices",
    "build_avatar",
    "build_model",
    "correspond",
    "correspond_rig",
    "CorrespondenceResult",
    "Correspondences",
    "CorrespondParams",
    "deformation_transfer",
    "deformed_mesh",
    "expression_weights",
    "EXPRESSIONS",
    "eye_texture",
    "eyeball_uv",
    "FaceRig",
    "front_region",
    "ict_regions",
    "load_ict_rig",
    "load_mesh",
    "load_model",
    "load_parts",
    "MATERIAL_LEVELS",
    "mesh_uv_layout",
    "MeshCharacter",
    "MorphModel",
    "neoteny_measures",
    "neoteny_table",
    "parse_pairs",
    "partial_blend",
    "procedural_head",
    "project_expression",
    "Reconstructor",
    "reorder_landmarks",
    "rig_albedo",
    "rig_detail_maps",
    "run_grid",
    "save_mesh",
    "select_region",
    "stylise",
    "stylise_albedo",
    "stylise_map",
    "stylise_rig",
    "StyliseParams",
    "SurfacePoints",
    "texture_image",
    "transfer_texture",
]

_install_moved_paths()
