"""Stimulus audit: low-level image measures of a stimulus set (luminance, contrast, spectrum, edges, face geometry).

Public API
----------
audit_manifest, read_audit_inputs, run_audit, plot_audit
    One tidy row per image of a grid's manifest (or a folder of images) and its figure
    (``appeal stimuli audit``).
lab_image, colour_stats, spectrum_slope, band_energy, edge_density, face_area, eye_positions
    The measures: pure functions on an RGB image and a boolean face mask (CIE L*a*b* D65).
iris_positions, gaze_check
    Where each iris sits between its eye's corners, and whether both sit where photographed ones do.
rendered_face_mask, landmark_face_mask, whole_image_mask
    Face masks: a grid's face oval minus its background; the hull of a photograph's 68 dlib landmarks.
match_luminance, match_histogram, match_spectrum, ssim_lightness
    SHINE-style matching of mean luminance and contrast, of luminance histograms and of Fourier
    amplitude spectra across a set (Willenbockel et al. 2010); the whole step is
    ``stimulus_engine.audit.equalise.equalise`` (``appeal stimuli equalise``).
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["equalise", "iris", "masks", "measures", "workflow"],
    submod_attrs={
        "equalise": ["match_histogram", "match_luminance", "match_spectrum", "ssim_lightness"],
        "iris": ["gaze_check", "iris_positions"],
        "masks": ["landmark_face_mask", "rendered_face_mask", "whole_image_mask"],
        "measures": ["band_energy", "colour_stats", "edge_density", "eye_positions", "face_area", "lab_image",
            "spectrum_slope"],
        "workflow": ["audit_manifest", "plot_audit", "read_audit_inputs", "run_audit"],
    },
)

__all__ = [
    # workflow
    "audit_manifest", "read_audit_inputs", "run_audit", "plot_audit",
    # measures
    "lab_image", "colour_stats", "spectrum_slope", "band_energy", "edge_density", "face_area", "eye_positions",
    # iris (the gaze a participant sees)
    "iris_positions", "gaze_check",
    # masks
    "rendered_face_mask", "landmark_face_mask", "whole_image_mask",
    # equalise (SHINE-style matching)
    "match_luminance", "match_histogram", "match_spectrum", "ssim_lightness",
]
