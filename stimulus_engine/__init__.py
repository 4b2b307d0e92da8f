"""Stimulus engine: 3D face correspondence, texture transfer, morphing, rendered grids, and
2D morph-space PCA face models."""

# --- mesh I/O, correspondence, texture transfer, morphing (issue 4) ---
from stimulus_engine.mesh_io import (  # noqa: E402
    load_mesh,
    load_parts,
    mesh_uv_layout,
    save_mesh,
    select_region,
    texture_image,
)
from stimulus_engine.correspondence import (  # noqa: E402
    CorrespondParams,
    Correspondences,
    CorrespondenceResult,
    SurfacePoints,
    correspond,
    deformed_mesh,
    parse_pairs,
    reorder_landmarks,
)
from stimulus_engine.texture_transfer import transfer_texture  # noqa: E402
from stimulus_engine.morph import blend_images, blend_vertices, partial_blend  # noqa: E402

# --- 2D morph-space PCA face models (issue 6); full API in stimulus_engine.morphpca ---
from stimulus_engine.morphpca import (  # noqa: E402
    MorphModel,
    Reconstructor,
    build_avatar,
    build_model,
    load_model,
    project_expression,
)

# --- stimulus grids: expressions, materials, stylisation, procedural head, neoteny (issue 5) ---
# The renderer (pyrender/OpenGL) is the subpackage ``stimulus_engine.render`` (imported on use).
from stimulus_engine.rig import FaceRig  # noqa: E402
from stimulus_engine.ict import ict_regions, load_ict_rig  # noqa: E402
from stimulus_engine.expressions import (  # noqa: E402
    EXPRESSIONS,
    apply_expression,
    deformation_transfer,
    expression_weights,
)
from stimulus_engine.materials import (  # noqa: E402
    MATERIAL_LEVELS,
    rig_albedo,
    rig_detail_maps,
    stylise_albedo,
    stylise_map,
)
from stimulus_engine.stylise import StyliseParams, stylise, stylise_rig  # noqa: E402
from stimulus_engine.procedural_head import procedural_head  # noqa: E402
from stimulus_engine.eyes import eye_texture, eyeball_uv  # noqa: E402
from stimulus_engine.mesh_character import MeshCharacter, correspond_rig, front_region  # noqa: E402
from stimulus_engine.neoteny import neoteny_measures, neoteny_table  # noqa: E402
from stimulus_engine.grid import run_grid  # noqa: E402
