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

from stimulus_engine.morphpca.avatar import Avatar, build_avatar, morph_average, unsharp_mask
from stimulus_engine.morphpca.faceframe import align_image, faceframe_affine
from stimulus_engine.morphpca.fit import image_fit_loadings
from stimulus_engine.morphpca.flow import FLOW_BACKENDS, compute_flow, fix_foldovers, jacobian_det
from stimulus_engine.morphpca.frame_source import read_frames
from stimulus_engine.morphpca.ghosting import ghosting_index
from stimulus_engine.morphpca.io import load_model, read_images, register_faces, save_image, save_model
from stimulus_engine.morphpca.keypoints import (
    detect_faceframe,
    detect_landmarks,
    faceframe_from_tem,
    read_keypoints_csv,
    read_tem,
    write_keypoints_csv,
)
from stimulus_engine.morphpca.landmark_warp import guided_flow, tps_displacement
from stimulus_engine.morphpca.metrics import psnr, ssim
from stimulus_engine.morphpca.mimicry import component_correlations, mimicry_measures, save_contact_sheet
from stimulus_engine.morphpca.morph_video import morph_sequence, read_video_frames
from stimulus_engine.morphpca.morphvec import decompose, deserialise, serialise
from stimulus_engine.morphpca.pca import MorphModel, build_model, pca
from stimulus_engine.morphpca.project import (
    Projection,
    caricature_loadings,
    caricature_vector,
    naive_transfer,
    project_expression,
)
from stimulus_engine.morphpca.reconstruct import Reconstructor, reconstruct_image, render_morph, render_vectors
from stimulus_engine.morphpca.synthetic import EXPRESSIONS, random_identity, render_synthetic_face, synthetic_set

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
