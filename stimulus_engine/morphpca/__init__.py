"""Morph-space PCA face models (Nagle et al.): warp fields, PCA, projection, avatars.

Public API
----------
compute_flow, FLOW_BACKENDS
    Dense multi-scale optical flow (OpenCV DIS or Farnebäck; the paper's McGM is not available).
guided_flow, tps_displacement
    Landmark-guided warps for faces of different people: a thin-plate spline refined by flow.
serialise, deserialise, decompose
    Morph vectors: texture on the mean shape + absolute warp, column-wise R, G, B, x, y.
MorphModel, build_model, pca
    PCA face models (components, mean, variances, reference, faceframe, training loadings).
image_fit_loadings
    Loadings nearest as an image (linearised image error): faces of people not in the model.
render_morph, Reconstructor, reconstruct_image
    Loadings → image without holes or fold-overs; ``Reconstructor`` is the real-time call.
project_expression, naive_transfer, caricature_vector, caricature_loadings
    Expression projection between identities (§3) and its naive baseline.
build_avatar, morph_average, unsharp_mask
    Identity-blended avatars (§4 steps 1–9).
ghosting_index
    How much of the features' edge energy an average keeps (doubled features lose it).
morph_sequence, read_video_frames, read_frames
    Expression frames from two photographs (a stand-in video), from a video file, or from
    frames and videos mixed (the commands' inputs).
read_tem, faceframe_from_tem, read_keypoints_csv, detect_faceframe, detect_landmarks
    Keypoints from templates, files, or dlib (weights in the face-recognition-models wheel).
mimicry_measures, component_correlations, save_contact_sheet
    Mimicry distance/correlation between loading sequences; side-by-side sheets.
read_images, register_faces, save_model, load_model, save_image
    I/O and keypoint registration.
render_synthetic_face, synthetic_set, random_identity
    Synthetic faces with known expression weights (ground truth for tests and the demo).
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["avatar", "defaults", "faceframe", "fit", "flow", "frame_source", "ghosting", "io", "keypoints",
                "landmark_warp", "metrics", "mimicry", "mimicry_run", "morph_video", "morphvec", "pca",
                "project", "reconstruct", "synthetic", "workflow"],
    submod_attrs={
        "avatar": ["Avatar", "build_avatar", "morph_average", "unsharp_mask"],
        "faceframe": ["align_image", "faceframe_affine"],
        "fit": ["image_fit_loadings"],
        "flow": ["FLOW_BACKENDS", "compute_flow", "fix_foldovers", "jacobian_det"],
        "frame_source": ["read_frames"],
        "ghosting": ["ghosting_index"],
        "io": ["load_model", "read_images", "register_faces", "save_image", "save_model"],
        "keypoints": ["detect_faceframe", "detect_landmarks", "faceframe_from_tem", "read_keypoints_csv",
            "read_tem", "write_keypoints_csv"],
        "landmark_warp": ["guided_flow", "tps_displacement"],
        "metrics": ["psnr", "ssim"],
        "mimicry": ["component_correlations", "mimicry_measures", "save_contact_sheet"],
        "morph_video": ["morph_sequence", "read_video_frames"],
        "morphvec": ["decompose", "deserialise", "serialise"],
        "pca": ["MorphModel", "build_model", "pca"],
        "project": ["Projection", "caricature_loadings", "caricature_vector", "naive_transfer", "project_expression"],
        "reconstruct": ["Reconstructor", "reconstruct_image", "render_morph", "render_vectors"],
        "synthetic": ["EXPRESSIONS", "random_identity", "render_synthetic_face", "synthetic_set"],
    },
)

__all__ = [
    "Avatar", "EXPRESSIONS", "FLOW_BACKENDS", "MorphModel", "Projection", "Reconstructor", "align_image",
    "build_avatar", "build_model", "caricature_loadings", "caricature_vector", "component_correlations",
    "compute_flow", "decompose", "deserialise", "detect_faceframe", "detect_landmarks", "faceframe_affine",
    "faceframe_from_tem", "fix_foldovers", "ghosting_index", "guided_flow", "image_fit_loadings", "jacobian_det", "load_model",
    "mimicry_measures", "morph_average", "morph_sequence", "naive_transfer", "pca", "project_expression", "psnr",
    "random_identity", "read_frames", "read_images", "read_keypoints_csv", "read_tem", "read_video_frames", "reconstruct_image",
    "register_faces", "render_morph", "render_synthetic_face", "render_vectors", "save_contact_sheet", "save_image",
    "save_model", "serialise", "ssim", "synthetic_set", "tps_displacement", "unsharp_mask", "write_keypoints_csv",
]
