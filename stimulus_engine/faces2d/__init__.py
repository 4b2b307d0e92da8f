"""2-D face photographs, WebMorph-style: templates, alignment, composites, continua, transforms,
caricatures, symmetry and masks, on landmarked images (``appeal faces``)."""

from stimulus_engine.faces2d.template import Template, read_template, template_text, write_template
from stimulus_engine.faces2d.warp import warp_to_points

__all__ = ["Template", "read_template", "template_text", "write_template", "warp_to_points"]

# align, average, continuum, mask (issue 33)
from stimulus_engine.faces2d.align import Face, align_face, default_eyes, eye_points, load_faces, read_face
from stimulus_engine.faces2d.composite import average_faces, composite_ghosting, pixel_average
from stimulus_engine.faces2d.continuum import continuum, morph
from stimulus_engine.faces2d.mask import apply_mask, face_mask
from stimulus_engine.faces2d.outputs import FaceOutput, write_outputs

__all__ += ["Face", "align_face", "default_eyes", "eye_points", "load_faces", "read_face", "average_faces",
            "composite_ghosting", "pixel_average", "continuum", "morph", "apply_mask", "face_mask", "FaceOutput",
            "write_outputs"]

# transform, caricature, symmetrise (issue 33)
from stimulus_engine.faces2d.caricature import caricature, caricature_points
from stimulus_engine.faces2d.symmetry import (DLIB_68_MIRROR, FRL_189_MIRROR, derive_mirror_map, mirror_map,
                                              mirror_template, symmetric_points, symmetrise)
from stimulus_engine.faces2d.transform import face_region, transform

__all__ += ["caricature", "caricature_points", "DLIB_68_MIRROR", "FRL_189_MIRROR", "derive_mirror_map", "mirror_map",
            "mirror_template", "symmetric_points", "symmetrise", "face_region", "transform"]
