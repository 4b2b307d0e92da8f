"""Stylisation: the operators that move a character along the realism scale — its shape, its
material, and blends between corresponded faces — and the neoteny measures that describe where
a shape lies. Imports everything below it (characters, parts, correspondence, render, geometry).

Public API
----------
stylise, stylise_rig, StyliseParams
    The shape operator: neotenous proportions by regions of the rig (module ``shape``).
own_cartoon, designed_shape, model_identity
    The shape axis toward a design: each person's own cartoon of an artist's head and the morphs
    on the way (module ``designed_shape``).
MATERIAL_LEVELS, stylise_albedo, stylise_map, stylise_material
    Material levels 0 (original) … 4 (flat) on albedos and their maps (module ``materials``).
blend_vertices, blend_images, partial_blend, blend_meshes, part_morph
    Morphs between corresponded meshes, whole or by facial region (modules ``morph``,
    ``morph_regions``; gradient-domain texture blending in ``gradient_blend``).
neoteny_measures, neoteny_table
    Baby-schema proportions of a face (module ``neoteny``).
stylised_eye_texture, bold_lash_texture, hair_mass_texture
    Eyes, lashes and hair painted along the scale: a larger, flat iris and a plain white, a bold
    lid line, hair in solid locks (modules ``eyes``, ``hair``).
ssim_distance, face_descriptor
    How far apart two stimuli look, and whose face they show (modules ``image_distance``,
    ``identity``).
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["designed_shape", "eyes", "gradient_blend", "hair", "identity", "image_distance", "materials",
                "morph", "morph_regions", "neoteny", "photo_match", "shape"],
    submod_attrs={
        "designed_shape": ["designed_shape", "model_identity", "own_cartoon"],
        "eyes": ["bold_lash_texture", "stylised_eye_texture"],
        "hair": ["hair_mass_texture"],
        "identity": ["face_descriptor"],
        "image_distance": ["ssim_distance"],
        "materials": ["MATERIAL_LEVELS", "stylise_albedo", "stylise_map", "stylise_material"],
        "morph": ["blend_images", "blend_meshes", "blend_vertices", "part_morph", "partial_blend"],
        "neoteny": ["neoteny_measures", "neoteny_table"],
        "shape": ["StyliseParams", "stylise", "stylise_rig"],
    },
)

__all__ = [
    "MATERIAL_LEVELS",
    "StyliseParams",
    "blend_images",
    "blend_meshes",
    "blend_vertices",
    "designed_shape",
    "model_identity",
    "own_cartoon",
    "bold_lash_texture",
    "face_descriptor",
    "hair_mass_texture",
    "neoteny_measures",
    "neoteny_table",
    "part_morph",
    "partial_blend",
    "ssim_distance",
    "stylise",
    "stylise_albedo",
    "stylise_map",
    "stylise_material",
    "stylise_rig",
    "stylised_eye_texture",
]
