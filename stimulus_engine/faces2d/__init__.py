"""2-D face photographs, WebMorph-style: templates, alignment, composites, continua, transforms,
caricatures, symmetry and masks, on landmarked images (``appeal faces``)."""

from stimulus_engine.faces2d.template import Template, read_template, template_text, write_template
from stimulus_engine.faces2d.warp import warp_to_points

__all__ = ["Template", "read_template", "template_text", "write_template", "warp_to_points"]
