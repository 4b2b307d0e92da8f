"""Deterministic offscreen rendering of face meshes with pyrender (OSMesa on the CPU, or EGL).

:func:`render_mesh` is the single entry point: give it a mesh (or a list of meshes / parts),
a lighting preset and a camera, get an ``(H, W, 3) uint8`` image. The same inputs always give
the same pixels: no random state is used, lights come in a fixed order, and one
:class:`pyrender.OffscreenRenderer` per image size and process is reused (one OpenGL context
per worker process when grids render in parallel).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Union

import numpy as np
import trimesh

from stimulus_engine.render._pyrender import pyrender
from stimulus_engine.render.camera import CameraSpec, fit_camera
from stimulus_engine.render.lighting import LightSpec, lighting_preset

__all__ = ["RenderPart", "render_mesh", "release_renderers", "split_uv_seams"]


@dataclass
class RenderPart:
    """A mesh with an optional explicit pyrender material.

    Attributes
    ----------
    mesh : trimesh.Trimesh
        Geometry; its visuals (texture with UVs, or vertex/face colours) are used when
        ``material`` is None.
    material : pyrender.Material or None
        Overrides the mesh's own material (e.g. a PBR or Phong-like material made by
        :mod:`stimulus_engine.materials`).
    smooth : bool
        Interpolate vertex normals (True) or shade per face.
    name : str
        For messages only.
    occlusion : (N,) array or None
        Baked ambient visibility per vertex (:func:`~stimulus_engine.render.occlusion.vertex_occlusion`);
        a material that asks for it (the ``skin`` shading) dims its ambient light by it.
    """

    mesh: trimesh.Trimesh
    material: Any = None
    smooth: bool = True
    name: str = ""
    occlusion: Any = None


MeshLike = Union[trimesh.Trimesh, trimesh.Scene, RenderPart, "pyrender.Mesh"]

_RENDERERS: dict[tuple[int, int], Any] = {}


def _renderer(width: int, height: int) -> Any:
    """The process's renderer for this size (kept for reuse; OpenGL contexts are expensive).

    Only one renderer lives at a time: textures are shared between images (see
    :func:`_smooth_mesh`) and a pyrender texture can be loaded in one OpenGL context only, so a
    new size first releases the old context (and with it the textures loaded there).
    """
    key = (int(width), int(height))
    r = _RENDERERS.get(key)
    if r is None:
        release_renderers()
        r = pyrender.OffscreenRenderer(viewport_width=key[0], viewport_height=key[1])
        _RENDERERS[key] = r
    return r


def release_renderers() -> None:
    """Free this process's OpenGL context (it is otherwise kept for reuse) and the textures
    loaded into it (call before rendering the same materials with a renderer of your own)."""
    while _RENDERERS:
        _, r = _RENDERERS.popitem()
        r.delete()


def _smooth_mesh(mesh: trimesh.Trimesh, material: Any, occlusion: np.ndarray | None = None) -> Any:
    """A smooth-shaded pyrender mesh that *shares* ``material`` (what ``from_trimesh`` builds, minus
    its deep copy of the material). Sharing lets the renderer keep a texture on the GPU from one
    image to the next (pyrender uploads a texture only when a new one appears in the scene); the
    copy re-uploaded (and re-mipmapped) every albedo for every image. ``occlusion`` (one value per
    vertex) travels as the vertex colour, which the ``skin`` shading reads as ambient visibility."""
    uv = mesh.visual.uv if getattr(mesh.visual, "kind", None) == "texture" else None
    colour = None
    wants = "AO_IN_COLOR0" in (getattr(material, "appeal_defines", None) or {})  # else pyrender would tint everything
    if wants and occlusion is not None and len(occlusion) == len(mesh.vertices):
        a = np.asarray(occlusion, np.float32)
        colour = np.stack([a, a, a, np.ones_like(a)], axis=1)
    prim = pyrender.Primitive(positions=mesh.vertices, normals=mesh.vertex_normals, texcoord_0=uv, color_0=colour,
                              indices=mesh.faces, material=material, mode=pyrender.constants.GLTF.TRIANGLES)
    return pyrender.Mesh(primitives=[prim])


def split_uv_seams(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """A copy of ``mesh`` for drawing, with a vertex per (vertex, UV) pair of its exact layout.

    A textured scan keeps one position per vertex but several UVs where its texture charts meet
    (an OBJ's per-corner ``vt`` indices, kept by :func:`stimulus_engine.mesh_io.load_mesh` as
    ``uv_coords``/``face_uv``); drawn with one UV per vertex, every triangle along such a seam
    samples across the texture's empty background — on the menpo3d james scan a jagged black
    band down the middle of the face. Normals are the unsplit mesh's, so shading stays smooth
    across the seam. Meshes without such seams are returned as they are.
    """
    from stimulus_engine.mesh_io import mesh_uv_layout

    if "uv_coords" not in mesh.metadata or getattr(mesh.visual, "kind", None) != "texture":
        return mesh  # one UV per vertex: nothing to split
    layout = mesh_uv_layout(mesh)
    if layout is None:
        return mesh
    uv, fuv = layout
    faces = np.asarray(mesh.faces)
    pairs = np.stack([faces.ravel(), np.asarray(fuv).ravel()], axis=1)
    unique, inverse = np.unique(pairs, axis=0, return_inverse=True)
    if len(unique) == len(mesh.vertices) and np.array_equal(unique[:, 0], np.arange(len(mesh.vertices))) \
            and np.allclose(uv[unique[:, 1]], getattr(mesh.visual, "uv", uv[unique[:, 1]])):
        return mesh
    out = trimesh.Trimesh(np.asarray(mesh.vertices)[unique[:, 0]], inverse.reshape(-1, 3), process=False,
                          visual=trimesh.visual.TextureVisuals(uv=uv[unique[:, 1]], material=mesh.visual.material))
    out.vertex_normals = np.asarray(mesh.vertex_normals)[unique[:, 0]]
    return out


def _as_parts(meshes: MeshLike | Sequence[MeshLike]) -> list[Any]:
    items = [meshes] if not isinstance(meshes, (list, tuple)) else list(meshes)
    flat: list[Any] = []
    for m in items:  # a trimesh.Scene (e.g. a multi-material OBJ) contributes its parts
        flat.extend(m.dump() if isinstance(m, trimesh.Scene) else [m])
    items = flat
    if not items:
        raise ValueError("render_mesh: nothing to render (empty list of meshes)")
    out = []
    for i, m in enumerate(items):
        if isinstance(m, pyrender.Mesh):
            out.append(m)
        elif isinstance(m, RenderPart) and m.material is not None and m.smooth:
            out.append(_smooth_mesh(split_uv_seams(m.mesh), m.material, m.occlusion))
        elif isinstance(m, RenderPart):
            out.append(pyrender.Mesh.from_trimesh(split_uv_seams(m.mesh), material=m.material, smooth=m.smooth))
        elif isinstance(m, trimesh.Trimesh):
            out.append(pyrender.Mesh.from_trimesh(split_uv_seams(m), smooth=True))
        else:
            raise TypeError(f"render_mesh: item {i} is a {type(m).__name__}, expected trimesh.Trimesh, "
                            "RenderPart or pyrender.Mesh")
    return out


def _points(parts: list[Any]) -> np.ndarray:
    return np.concatenate([p.bounds for p in parts], axis=0)


class _OrderedNode(pyrender.Node):
    """A scene node hashed by its position in the scene, not by its memory address.

    pyrender keeps meshes and lights in Python sets and draws / sums them in set order; with the
    default identity hash that order changes from process to process, so pixels where two parts
    meet at equal depth (and the floating-point sum over lights) could differ between two renders
    of the same inputs. Small consecutive integer hashes give the same order every time.
    """

    def __init__(self, order: int, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._order = order

    def __hash__(self) -> int:
        return self._order

    def __eq__(self, other: object) -> bool:
        return self is other


def _add(scene: Any, counter: list[int], pose: np.ndarray | None = None, **what: Any) -> None:
    counter[0] += 1
    scene.add_node(_OrderedNode(counter[0], matrix=pose, **what))


class _FittedDirectionalLight(pyrender.DirectionalLight):
    """A directional light whose shadow map covers the scene's bounding sphere and nothing more.

    pyrender places the shadow camera one scene diagonal ``s`` from the scene's centre, looking
    along the light, with an orthographic half-width of ``s`` and depths ``0.01 s .. 10 s``: the
    scene fills a quarter of the map's width and a tenth of its depth range. The scene lies within
    ``s / 2`` of its centre, so a half-width of ``s / 2`` and depths ``s / 2 .. 3 s / 2`` (plus 2 %)
    see all of it with twice the texels across and seven times the depth resolution.
    """

    def _get_shadow_camera(self, scene_scale: float) -> Any:
        s = float(scene_scale)
        return pyrender.OrthographicCamera(xmag=0.51 * s, ymag=0.51 * s, znear=0.48 * s, zfar=1.52 * s)


class _FittedSpotLight(pyrender.SpotLight):
    """A spot light whose (perspective) shadow map just covers a bounding sphere of the scene.

    pyrender's shadow camera for a spot light has the cone's full opening plus 11 degrees and depths
    ``0.01 s .. 10 s``; a face a metre away then covers a small part of the map and of its depth
    range. Here the field of view is the angle the sphere subtends seen from the light (about the
    light's own axis) and the depth range is the sphere's. Falls back to pyrender's camera when the
    light sits inside the sphere.
    """

    def __init__(self, *, centre: np.ndarray, radius: float, pose: np.ndarray, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        to_c = np.asarray(centre, float) - pose[:3, 3]
        dist = float(np.linalg.norm(to_c))
        self._fit = None
        if dist > 1.05 * radius:
            axis = -pose[:3, 2]
            off_axis = math.acos(float(np.clip(np.dot(axis, to_c / dist), -1.0, 1.0)))
            half = off_axis + math.asin(radius / dist)
            if half < 0.49 * math.pi:
                self._fit = (min(2.04 * half, 0.98 * math.pi), 0.98 * (dist - radius), 1.02 * (dist + radius))

    def _get_shadow_camera(self, scene_scale: float) -> Any:
        if self._fit is None:
            return super()._get_shadow_camera(scene_scale)
        yfov, znear, zfar = self._fit
        return pyrender.PerspectiveCamera(yfov=yfov, znear=znear, zfar=zfar, aspectRatio=1.0)


def _add_lights(scene: Any, lights: list[LightSpec], camera: CameraSpec, counter: list[int],
                bounds: np.ndarray) -> bool:
    """Add camera-relative lights to ``scene``; return True if any casts a shadow.

    ``bounds`` (points of the meshes' bounding boxes) fit the shadow maps to the scene.
    """
    rot = camera.rotation()
    target = np.asarray(camera.target, float)
    dist = 1.6 * camera.distance
    lo, hi = bounds.min(axis=0), bounds.max(axis=0)
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
    shadows = False
    for spec in lights:
        d = rot @ np.asarray(spec.direction, float)
        d /= np.linalg.norm(d)
        # light pose: its -z axis points along d
        z = -d
        helper = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
        x = np.cross(helper, z)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        pose = np.eye(4)
        pose[:3, :3] = np.stack([x, y, z], axis=1)
        if spec.kind == "directional":
            light = _FittedDirectionalLight(color=spec.color, intensity=spec.intensity)
            pose[:3, 3] = target - d * dist
        elif spec.kind == "spot":
            pose[:3, 3] = target - d * dist + (x * spec.offset[0] + y * spec.offset[1]) * dist
            light = _FittedSpotLight(color=spec.color, intensity=spec.intensity * dist**2, innerConeAngle=0.25,
                                     outerConeAngle=0.5, centre=centre, radius=radius, pose=pose)
        else:
            raise ValueError(f"unknown light kind '{spec.kind}' (expected directional or spot)")
        _add(scene, counter, pose, light=light)
        shadows |= spec.shadow
    return shadows


def render_mesh(meshes: MeshLike | Sequence[MeshLike], *, width: int = 1024, height: int = 768,
                lighting: str | tuple[list[LightSpec], float] = "gi_soft", camera: CameraSpec | None = None,
                background: tuple[float, float, float] = (0.5, 0.5, 0.5), shadows: bool = True,
                return_depth: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Render meshes to an RGB image.

    Parameters
    ----------
    meshes : trimesh.Trimesh, trimesh.Scene, RenderPart, pyrender.Mesh, or a list of them
        What to draw (e.g. the parts of a head: skin, eyes, teeth).
    width, height : int
        Image size in pixels (default 1024 × 768, the thesis's stimulus size).
    lighting : str or (lights, ambient)
        A preset name from :data:`stimulus_engine.render.LIGHTING_PRESETS` (``direct_hard``,
        ``direct_soft``, ``gi_soft``, ``flat``) or an explicit list of lights with ambient level.
    camera : CameraSpec, optional
        Default: :func:`~stimulus_engine.render.camera.fit_camera` on the meshes' bounds, from the front.
    background : tuple of float
        RGB in 0..1; default 50 % grey (pixel value 128).
    shadows : bool
        Render the shadow maps the preset asks for (False = faster, no shadows).
    return_depth : bool
        Also return the depth buffer (float32, 0 where empty).

    Returns
    -------
    image : (height, width, 3) uint8 array
    depth : (height, width) float32 array, only if ``return_depth``

    Examples
    --------
    >>> import trimesh
    >>> img = render_mesh(trimesh.creation.icosphere(), width=64, height=48)
    >>> img.shape, img.dtype.name
    ((48, 64, 3), 'uint8')
    """
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive (got {width} x {height})")
    parts = _as_parts(meshes)
    lights, ambient = lighting_preset(lighting) if isinstance(lighting, str) else lighting
    if camera is None:
        camera = fit_camera(_points(parts), width / height)
    scene = pyrender.Scene(bg_color=[*map(float, background), 1.0], ambient_light=[ambient] * 3)
    counter = [0]
    for p in parts:
        _add(scene, counter, mesh=p)
    dist = camera.distance
    cam = pyrender.PerspectiveCamera(yfov=math.radians(camera.yfov_deg), aspectRatio=width / height,
                                     znear=max(dist * 0.05, 1e-4), zfar=dist * 20)
    _add(scene, counter, camera.pose(), camera=cam)
    want_shadows = _add_lights(scene, lights, camera, counter, _points(parts)) and shadows
    flags = pyrender.RenderFlags.NONE
    if want_shadows:
        flags |= pyrender.RenderFlags.SHADOWS_DIRECTIONAL | pyrender.RenderFlags.SHADOWS_SPOT
    color, depth = _renderer(width, height).render(scene, flags=flags)
    color = np.ascontiguousarray(color[..., :3], dtype=np.uint8)
    if return_depth:
        return color, np.asarray(depth, dtype=np.float32)
    return color
