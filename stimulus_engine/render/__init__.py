"""Offscreen rendering of face stimuli (pyrender; OSMesa on the CPU by default, EGL on a GPU).

Public API
----------
render_mesh
    Mesh(es) → ``(H, W, 3) uint8`` image; same inputs give the same pixels.
RenderPart
    A mesh with an explicit material (skin, eyes, teeth ...).
CameraSpec, fit_camera, face_camera
    Cameras; ``face_camera`` gives every stimulus the same face size and eye position.
LIGHTING_PRESETS, lighting_preset, LightSpec
    ``direct_hard``, ``direct_soft``, ``gi_soft``, ``flat``: key + rim lights (thesis §6.3.2).
contact_sheet, save_png
    Labelled grids of images (thesis Fig. 6.11) and deterministic PNG writing.
render_cycles, export_scene
    The path-traced tier: the same parts and camera exported once and rendered by Blender's
    Cycles in its own Python (``make cycles``).
vertex_occlusion, light_visibility
    Ambient occlusion and a light's visibility baked per vertex (Embree rays), used by the
    ``skin`` shading (its ambient light and the soft shadows of ``direct_soft``).

Import ``pyrender`` only through :mod:`stimulus_engine.render._pyrender`.
"""

from stimulus_engine.render.camera import CameraSpec, face_camera, fit_camera
from stimulus_engine.render.contact_sheet import contact_sheet, save_png
from stimulus_engine.render.cycles import render_cycles
from stimulus_engine.render.lighting import LIGHTING_PRESETS, LightSpec, lighting_preset
from stimulus_engine.render.occlusion import light_visibility, vertex_occlusion
from stimulus_engine.render.renderer import RenderPart, release_renderers, render_mesh
from stimulus_engine.render.scene_export import export_scene

__all__ = [
    "CameraSpec",
    "LIGHTING_PRESETS",
    "LightSpec",
    "RenderPart",
    "contact_sheet",
    "export_scene",
    "face_camera",
    "fit_camera",
    "light_visibility",
    "lighting_preset",
    "release_renderers",
    "render_cycles",
    "render_mesh",
    "save_png",
    "vertex_occlusion",
]
