"""2-D face photographs, WebMorph-style: templates, alignment, composites, continua, transforms,
caricatures, symmetry and masks, on landmarked images (``appeal faces``)."""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["align", "caricature", "composite", "continuum", "mask", "outputs", "pyramid", "symmetry",
                "template", "transform", "warp"],
    submod_attrs={
        "template": ["Template", "read_template", "template_text", "write_template"],
        "warp": ["warp_to_points"],
        "align": ["Face", "align_face", "default_eyes", "eye_points", "load_faces", "read_face"],
        "composite": ["average_faces", "composite_ghosting", "pixel_average"],
        "continuum": ["continuum", "morph"],
        "mask": ["apply_mask", "face_mask"],
        "outputs": ["FaceOutput", "write_outputs"],
        "caricature": ["caricature", "caricature_points"],
        "symmetry": ["DLIB_68_MIRROR", "FRL_189_MIRROR", "derive_mirror_map", "mirror_map", "mirror_template",
            "symmetric_points", "symmetrise"],
        "transform": ["face_region", "transform"],
    },
)

__all__ = ["Template", "read_template", "template_text", "write_template", "warp_to_points"]


__all__ += ["Face", "align_face", "default_eyes", "eye_points", "load_faces", "read_face", "average_faces",
            "composite_ghosting", "pixel_average", "continuum", "morph", "apply_mask", "face_mask", "FaceOutput",
            "write_outputs"]


__all__ += ["caricature", "caricature_points", "DLIB_68_MIRROR", "FRL_189_MIRROR", "derive_mirror_map", "mirror_map",
            "mirror_template", "symmetric_points", "symmetrise", "face_region", "transform"]
