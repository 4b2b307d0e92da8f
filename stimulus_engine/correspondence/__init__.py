"""ElastiFace dense correspondence (Zell's thesis ch. 3): correspondences, similarity alignment,
joint bi-Laplacian fairing, non-rigid registration, metrics.

Public API
----------
correspond, CorrespondParams, CorrespondenceResult, deformed_mesh
    The whole geometry matching (§3.2) and its result.
SurfacePoints, Correspondences, parse_points, parse_pairs, load_pairs_file
    Reference points (vertex, barycentric, or snapped 3D point) and their pairs (§3.2.1;
    module ``points``).
boundary_correspondences
    Boundary-loop correspondences by relative arc length (Fig. 3.5; module ``boundary``, with
    rims mapped onto curves drawn on the target, module ``curves``). The loops themselves:
    :func:`stimulus_engine.geometry.mesh_ops.boundary_loops`.
reorder_landmarks, read_ljson, landmark_orderings, LANDMARK_SUBSET_16
    68-point landmark orderings (iBUG/Multi-PIE vs menpo LJSON; module ``landmark_sets``).
umeyama, Similarity
    Closed-form similarity alignment.
joint_fairing, nonrigid_register, Pruning
    The two energies (eq. 3.7-3.10, 3.11-3.13).
fit_metrics, flipped_triangles
    Distances and fold-overs.
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["alignment", "auto_landmarks", "boundary", "curves", "datasets", "fairing", "landmark_sets",
                "laplacian", "metrics", "ordering", "pipeline", "points", "registration", "repair", "sheet",
                "solve", "synthetic", "texture_transfer", "untangle", "workflow"],
    submod_attrs={
        "alignment": ["Similarity", "umeyama"],
        "fairing": ["FairingResult", "joint_fairing"],
        "boundary": ["boundary_correspondences"],
        "landmark_sets": ["LANDMARK_SUBSET_16", "landmark_orderings", "read_ljson", "reorder_landmarks"],
        "metrics": ["fit_metrics", "flipped_triangles"],
        "pipeline": ["CorrespondParams", "CorrespondenceResult", "correspond", "deformed_mesh"],
        "points": ["Correspondences", "SurfacePoints", "load_pairs_file", "parse_pairs", "parse_points"],
        "registration": ["Pruning", "nonrigid_register"],
    },
)

__all__ = [
    "LANDMARK_SUBSET_16",
    "CorrespondParams",
    "CorrespondenceResult",
    "Correspondences",
    "FairingResult",
    "Pruning",
    "Similarity",
    "SurfacePoints",
    "boundary_correspondences",
    "correspond",
    "deformed_mesh",
    "fit_metrics",
    "flipped_triangles",
    "joint_fairing",
    "landmark_orderings",
    "load_pairs_file",
    "nonrigid_register",
    "parse_pairs",
    "parse_points",
    "read_ljson",
    "reorder_landmarks",
    "umeyama",
]
