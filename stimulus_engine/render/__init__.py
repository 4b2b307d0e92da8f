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

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["baked_shadows", "camera", "clip_video", "contact_sheet", "cycles", "cycles_worker",
                "hair_strands", "light_shadows", "lighting", "occlusion", "renderer", "scene_export",
                "skin_shader", "vignette"],
    submod_attrs={
        "camera": ["CameraSpec", "face_camera", "fit_camera"],
        "contact_sheet": ["contact_sheet", "save_png"],
        "cycles": ["render_cycles"],
        "lighting": ["LIGHTING_PRESETS", "LightSpec", "lighting_preset"],
        "occlusion": ["light_visibility", "vertex_occlusion"],
        "renderer": ["RenderPart", "release_renderers", "render_mesh"],
        "scene_export": ["export_scene"],
    },
)

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
