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
from dataclasses import dataclass, replace
from typing import Any, Union

import numpy as np
import trimesh

from stimulus_engine.render._pyrender import pyrender, scene_defines
from stimulus_engine.render.camera import CameraSpec, fit_camera
from stimulus_engine.render.light_shadows import (
    SHADOW_BAKED,
    SHADOW_KEY,
    SHADOW_MAP,
    SHADOW_NONE,
    key_shadow_defines,
)
from stimulus_engine.render.lighting import Disc, LightSpec, group_discs, lighting_preset

__all__ = ["RenderPart", "downsample", "render_mesh", "release_renderers", "split_uv_seams"]


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
        :mod:`stimulus_engine.stylisation.materials`).
    smooth : bool
        Interpolate vertex normals (True) or shade per face.
    name : str
        For messages only.
    occlusion : (N,) array or None
        Baked ambient visibility per vertex (:func:`~stimulus_engine.render.occlusion.vertex_occlusion`);
        a material that asks for it (the ``skin`` shading) dims its ambient light by it.
    tangents : (N, 3) array or None
        A direction per vertex in the surface (hair: along the strands), passed to the shader as
        the vertex tangent (the ``HAIR_KAJIYA`` switch of :mod:`.skin_shader` reads it).
    """

    mesh: trimesh.Trimesh
    material: Any = None
    smooth: bool = True
    name: str = ""
    occlusion: Any = None
    tangents: Any = None


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
    _SHADOW_TEXTURES.clear()  # they lived in that context


def _smooth_mesh(mesh: trimesh.Trimesh, material: Any, occlusion: np.ndarray | None = None,
                 visibility: np.ndarray | None = None, tangents: np.ndarray | None = None) -> Any:
    """A smooth-shaded pyrender mesh that *shares* ``material`` (what ``from_trimesh`` builds, minus
    its deep copy of the material). Sharing lets the renderer keep a texture on the GPU from one
    image to the next (pyrender uploads a texture only when a new one appears in the scene); the
    copy re-uploaded (and re-mipmapped) every albedo for every image. ``occlusion`` (one value per
    vertex) travels as the vertex colour's red channel, which the ``skin`` shading reads as ambient
    visibility, and ``visibility`` (of the shadow-casting lights, :mod:`.baked_shadows`) as its green."""
    uv = mesh.visual.uv if getattr(mesh.visual, "kind", None) == "texture" else None
    colour = None
    wants = "VISIBILITY_IN_COLOR0" in (getattr(material, "appeal_defines", None) or {})  # else pyrender would tint everything
    n = len(mesh.vertices)
    ao = None if occlusion is None or len(occlusion) != n else np.asarray(occlusion, np.float32)
    vis = None if visibility is None or len(visibility) != n else np.asarray(visibility, np.float32)
    if wants and (ao is not None or vis is not None):
        ao = np.ones(n, np.float32) if ao is None else ao
        vis = np.ones(n, np.float32) if vis is None else vis
        colour = np.stack([ao, vis, ao, np.ones_like(ao)], axis=1)
    tan = None
    if tangents is not None and len(tangents) == n:  # xyz and the bitangent's handedness
        tan = np.column_stack([np.asarray(tangents, np.float32), np.ones(n, np.float32)])
    prim = pyrender.Primitive(positions=mesh.vertices, normals=mesh.vertex_normals, texcoord_0=uv, color_0=colour,
                              tangents=tan, indices=mesh.faces, material=material, mode=pyrender.constants.GLTF.TRIANGLES)
    return pyrender.Mesh(primitives=[prim])


def split_uv_seams(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """A copy of ``mesh`` for drawing, with a vertex per (vertex, UV) pair of its exact layout.

    A textured scan keeps one position per vertex but several UVs where its texture charts meet
    (an OBJ's per-corner ``vt`` indices, kept by :func:`stimulus_engine.geometry.mesh_io.load_mesh` as
    ``uv_coords``/``face_uv``); drawn with one UV per vertex, every triangle along such a seam
    samples across the texture's empty background — on the menpo3d james scan a jagged black
    band down the middle of the face. Normals are the unsplit mesh's, so shading stays smooth
    across the seam. Meshes without such seams are returned as they are.
    """
    from stimulus_engine.geometry.mesh_io import mesh_uv_layout

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


def _items(meshes: MeshLike | Sequence[MeshLike]) -> list[Any]:
    """The things to draw, a trimesh.Scene split into its parts and UV seams split (see
    :func:`split_uv_seams`) so that per-vertex data lines up with what is drawn."""
    items = [meshes] if not isinstance(meshes, (list, tuple)) else list(meshes)
    flat: list[Any] = []
    for m in items:  # a trimesh.Scene (e.g. a multi-material OBJ) contributes its parts
        flat.extend(m.dump() if isinstance(m, trimesh.Scene) else [m])
    if not flat:
        raise ValueError("render_mesh: nothing to render (empty list of meshes)")
    out = []
    for i, m in enumerate(flat):
        if isinstance(m, RenderPart):
            split = split_uv_seams(m.mesh)
            out.append(m if split is m.mesh else replace(m, mesh=split))
        elif isinstance(m, trimesh.Trimesh):
            out.append(split_uv_seams(m))
        elif isinstance(m, pyrender.Mesh):
            out.append(m)
        else:
            raise TypeError(f"render_mesh: item {i} is a {type(m).__name__}, expected trimesh.Trimesh, "
                            "RenderPart or pyrender.Mesh")
    return out


def _as_part(m: Any, visibility: np.ndarray | None = None) -> Any:
    """One item of :func:`_items` as a pyrender mesh (``visibility``: baked shadows per vertex)."""
    if isinstance(m, pyrender.Mesh):
        return m
    if isinstance(m, RenderPart) and m.material is not None and m.smooth:
        return _smooth_mesh(m.mesh, m.material, m.occlusion, visibility, m.tangents)
    if isinstance(m, RenderPart):
        return pyrender.Mesh.from_trimesh(m.mesh, material=m.material, smooth=m.smooth)
    return pyrender.Mesh.from_trimesh(m, smooth=True)


def _back_to_front(item: Any, camera: CameraSpec) -> Any:
    """An alpha-blended :class:`RenderPart` with its triangles in order of distance from the
    camera, farthest first (OpenGL blends a draw call's triangles in their order: hair cards
    drawn in the mesh's order hid the cards behind them or showed them through the front ones);
    anything else as it is."""
    if not (isinstance(item, RenderPart) and getattr(item.material, "alphaMode", "OPAQUE") == "BLEND"):
        return item
    m = item.mesh
    faces = np.asarray(m.faces)
    centres = np.asarray(m.vertices)[faces].mean(axis=1)
    order = np.argsort(-np.linalg.norm(centres - np.asarray(camera.position, np.float64), axis=1), kind="stable")
    if np.array_equal(order, np.arange(len(faces))):
        return item
    out = trimesh.Trimesh(m.vertices, faces[order], vertex_normals=m.vertex_normals, process=False)
    out.visual = m.visual.copy() if getattr(m.visual, "kind", None) == "texture" else m.visual
    return replace(item, mesh=out)


def _wants_baked_shadows(items: list[Any]) -> bool:
    """True when every item is a smooth :class:`RenderPart` whose material reads baked
    visibility from its vertex colour (the ``VISIBILITY_IN_COLOR0`` switch every rig part's
    material has, :mod:`.skin_shader`)."""
    return bool(items) and all(
        isinstance(m, RenderPart) and m.smooth and m.material is not None
        and "VISIBILITY_IN_COLOR0" in (getattr(m.material, "appeal_defines", None) or {}) for m in items)


def _baked_visibility(items: list[Any], lights: list[LightSpec], camera: CameraSpec) -> list[np.ndarray]:
    """The shadow-casting lights' visibility per vertex of every item (:mod:`.baked_shadows`)."""
    from stimulus_engine.render.baked_shadows import bake_shadows
    from stimulus_engine.render.scene_export import world_lights

    opaque = [getattr(m.material, "alphaMode", "OPAQUE") != "BLEND" for m in items]
    return bake_shadows([m.mesh for m in items], opaque, world_lights(lights, camera))


def _points(parts: list[Any]) -> np.ndarray:
    """The corners of the parts' bounding boxes (pyrender meshes, trimeshes or render parts)."""
    return np.concatenate([(p.mesh if isinstance(p, RenderPart) else p).bounds for p in parts], axis=0)


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


#: Shadow-map textures of the current renderer, reused by the shadow-casting lights of one
#: image after another (slot = the light's rank among them), and one 1 x 1 texture that every
#: light without a shadow map binds: pyrender gives *every* light of a type with shadows on a
#: new 2048 x 2048 depth texture per image, and allocating those was 20 ms of a 120 ms image.
_SHADOW_TEXTURES: dict[int, Any] = {}


def _pooled_shadow_texture(slot: int) -> Any:
    tex = _SHADOW_TEXTURES.get(slot)
    if tex is None:
        size = 1 if slot < 0 else pyrender.constants.SHADOW_TEX_SZ
        tex = _SHADOW_TEXTURES[slot] = pyrender.Texture(width=size, height=size, source_channels="D",
                                                        data_format=pyrender.light.GL_FLOAT)
    return tex


class _PooledShadowTexture:
    """Mixin: the light's shadow texture comes from :data:`_SHADOW_TEXTURES` (``pool_slot``)."""

    pool_slot = -1

    def _generate_shadow_texture(self, size: int | None = None) -> None:
        self.shadow_texture = _pooled_shadow_texture(self.pool_slot)


class _FittedDirectionalLight(_PooledShadowTexture, pyrender.DirectionalLight):
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


class _FittedSpotLight(_PooledShadowTexture, pyrender.SpotLight):
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


def _discs_as_suns(lights: list[LightSpec]) -> tuple[list[LightSpec], frozenset[int]]:
    """The lights to shade with once a soft light's shadow is baked, and which of them it is.

    A preset's area light is a disc of shadow-casting spot samples (``direct_soft``); with its
    shadow baked per vertex the samples only shade, and one directional light at the disc's
    centre with their summed intensity shades the same light, one light instead of six in
    every pixel's loop.
    """
    out, baked = [], set()
    for light in group_discs(lights):
        if isinstance(light, Disc):
            if light.shadow:
                baked.add(len(out))
            light = LightSpec("directional", light.direction, light.intensity, light.color, light.shadow)
        out.append(light)
    return out, frozenset(baked)


def _add_lights(scene: Any, lights: list[LightSpec], camera: CameraSpec, counter: list[int],
                bounds: np.ndarray, *, shadows: bool = True, baked: frozenset[int] = frozenset()) -> int:
    """Add camera-relative lights to ``scene``; return the pyrender shadow flags they need.

    ``bounds`` (points of the meshes' bounding boxes) fit the shadow maps to the scene;
    ``shadows``: False = no light casts one; ``baked``: the indices of the lights whose shadow
    is the visibility baked per vertex (:mod:`.baked_shadows`, :func:`_discs_as_suns`). Shadow
    kinds: :mod:`.light_shadows`.
    """
    rot = camera.rotation()
    target = np.asarray(camera.target, float)
    dist = 1.6 * camera.distance
    lo, hi = bounds.min(axis=0), bounds.max(axis=0)
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
    flags, slots, any_key = pyrender.RenderFlags.NONE, 0, False
    for index, spec in enumerate(lights):
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
        # a baked light reads its shadow from the vertex colour; the first other directional
        # caster is the key (its own map); the rest (a soft light's spot samples on meshes
        # without baked visibility) get pyrender's maps
        if not (spec.shadow and shadows):
            mode = SHADOW_NONE
        elif index in baked:
            mode = SHADOW_BAKED
        elif spec.kind == "directional" and not any_key:
            mode = SHADOW_KEY
        else:
            mode = SHADOW_MAP
        any_key |= mode == SHADOW_KEY
        light.appeal_shadow = mode
        if mode in (SHADOW_MAP, SHADOW_KEY):
            light.pool_slot, slots = slots, slots + 1
        if mode == SHADOW_KEY:  # its map is rendered outside pyrender's flags
            light._generate_shadow_texture()
        _add(scene, counter, pose, light=light)
        if mode == SHADOW_MAP:
            flags |= pyrender.RenderFlags.SHADOWS_SPOT if spec.kind == "spot" else pyrender.RenderFlags.SHADOWS_DIRECTIONAL
    return flags


def render_mesh(meshes: MeshLike | Sequence[MeshLike], *, width: int = 1024, height: int = 768,
                lighting: str | tuple[list[LightSpec], float] = "gi_soft", camera: CameraSpec | None = None,
                background: tuple[float, float, float] = (0.5, 0.5, 0.5), shadows: bool = True,
                return_depth: bool = False, supersample: float = 1.0) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
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
        Draw the shadows the preset asks for: the key light's shadow map, and a soft light's
        (:mod:`.light_shadows`; on parts whose materials read baked visibility — a rig's, in
        every shading — a soft light's are baked per vertex, :mod:`.baked_shadows`). False = faster, no shadows.
    return_depth : bool
        Also return the depth buffer (float32, 0 where empty).
    supersample : float
        Render ``supersample`` times larger in each direction and average every output pixel's
        area in linear light (:func:`downsample`): anti-aliased edges, as a photograph has
        (OSMesa draws one sample per pixel: every silhouette, the lips' and teeth's outlines and
        the hair's edge stepped). 1 = none; the depth buffer is then sampled, not averaged.

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
    if not 1.0 <= supersample <= 4.0:
        raise ValueError(f"supersample must be between 1 and 4 (got {supersample})")
    out_size = (width, height)
    width, height = int(round(width * supersample)), int(round(height * supersample))
    items = _items(meshes)
    lights, ambient = lighting_preset(lighting) if isinstance(lighting, str) else lighting
    if camera is None:
        camera = fit_camera(_points(items), width / height)
    items = [_back_to_front(m, camera) for m in items]
    visibility, baked = [None] * len(items), frozenset()
    if shadows and any(s.shadow and s.kind == "spot" for s in lights) and _wants_baked_shadows(items):
        visibility = _baked_visibility(items, lights, camera)
        lights, baked = _discs_as_suns(lights)
    parts = [_as_part(m, v) for m, v in zip(items, visibility)]
    scene = pyrender.Scene(bg_color=[*map(float, background), 1.0], ambient_light=[ambient] * 3)
    counter = [0]
    for p in parts:
        _add(scene, counter, mesh=p)
    dist = camera.distance
    cam = pyrender.PerspectiveCamera(yfov=math.radians(camera.yfov_deg), aspectRatio=width / height,
                                     znear=max(dist * 0.05, 1e-4), zfar=dist * 20)
    _add(scene, counter, camera.pose(), camera=cam)
    flags = _add_lights(scene, lights, camera, counter, _points(parts), shadows=shadows, baked=baked)
    with scene_defines(key_shadow_defines(scene)):
        color, depth = _renderer(width, height).render(scene, flags=flags)
    color = downsample(np.ascontiguousarray(color[..., :3], dtype=np.uint8), *out_size)
    if return_depth:
        depth = np.asarray(depth, dtype=np.float32)
        if depth.shape != (out_size[1], out_size[0]):
            from PIL import Image

            depth = np.asarray(Image.fromarray(depth).resize(out_size, Image.NEAREST), np.float32)
        return color, depth
    return color


def _srgb_tables() -> tuple[np.ndarray, np.ndarray]:
    """Linear light of each sRGB byte, and the sRGB byte of linear light in 65536 steps (finer
    than a byte's step of sRGB at every level)."""
    c = np.arange(256) / 255.0
    decode = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)
    lin = np.linspace(0.0, 1.0, 65536)
    encode = np.where(lin <= 0.0031308, lin * 12.92, 1.055 * lin ** (1 / 2.4) - 0.055)
    return decode, np.rint(255 * encode).astype(np.uint8)


_SRGB_TO_LINEAR, _LINEAR_TO_SRGB = _srgb_tables()


def downsample(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """An sRGB uint8 ``image`` reduced to ``width`` x ``height`` by averaging each output pixel's
    area (a box filter, fractional at the edges) in linear light, as a camera's sensor sums
    light (averaged in sRGB, a bright edge against a dark one came out too dark); the image
    itself where it has that size already."""
    from PIL import Image

    if image.shape[:2] == (height, width):
        return image
    linear = _SRGB_TO_LINEAR[image]
    chans = [np.asarray(Image.fromarray(np.ascontiguousarray(linear[..., c], np.float32)).resize((width, height), Image.BOX))
             for c in range(image.shape[2])]
    # a box filter's weights are positive and sum to 1: the averages stay within 0..1
    return _LINEAR_TO_SRGB[(np.stack(chans, axis=-1) * (len(_LINEAR_TO_SRGB) - 1) + 0.5).astype(np.uint16)]
