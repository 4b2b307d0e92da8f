"""Rendering one grid image (runs in worker processes: one OpenGL context each).

A :class:`RenderItem` names files and settings only (it is pickled to the workers); the
worker reads the prepared inputs from the cache and hands them to a render engine of
:data:`ENGINES` by the item's ``engine``: ``pyrender`` (OpenGL) or ``cycles`` (Blender's path
tracer, in its own Python), both drawing the same parts from the same camera. A clip's frame is
an item whose ``geometry_npy`` holds every frame and whose ``frame`` names one
(:func:`stimulus_engine.grid.animation.render_clip` renders all of a clip's in one call).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from stimulus_engine.grid.cache import load_rig

__all__ = ["ENGINES", "RenderItem", "item_scene", "place_photo", "render_image", "render_item"]


@dataclass(frozen=True)
class RenderItem:
    """Everything a worker needs to render one image (paths and settings; picklable)."""

    file: str
    out_dir: str
    rig_npz: str
    geometry_npy: str
    albedo_png: str
    lighting: str
    shading: str
    camera: tuple
    width: int
    height: int
    shadows: bool
    background: tuple
    normal_png: str = ""
    specular_png: str = ""
    engine: str = "pyrender"
    samples: int = 16
    seed: int = 0
    vignette: tuple = ()
    supersample: float = 1.0
    eye_style: tuple = ()  # (iris scale, paint) of stylised eyes, lashes and hair (stimulus_engine.stylisation); () as modelled
    #: -1: ``geometry_npy`` is one (N, 3) geometry; k >= 0: it is a clip's (frames, N, 3) and this draws frame k
    frame: int = -1
    #: a photo character's surround stylised with the material ("": none, or the rig's own)
    surround_png: str = ""
    #: a clip frame's ambient occlusion: () baked for the frame; (apex,) blended between frame 0's and
    #: frame ``apex``'s (:func:`blended_occlusion`; ``animation.occlusion: blend``)
    occlusion_blend: tuple = ()

    def outputs(self) -> list[str]:
        """The files the render writes, relative to ``out_dir``."""
        return [self.file]

    def geometry(self) -> np.ndarray:
        """The drawn vertices (float64): the still's, or frame ``frame`` of a clip's."""
        if self.frame < 0:
            return np.load(self.geometry_npy).astype(np.float64)
        return np.asarray(np.load(self.geometry_npy, mmap_mode="r")[self.frame], np.float64)

    def geometry_key(self) -> str:
        """The path the geometry's baked ambient visibility is kept beside (one per clip frame)."""
        if self.frame < 0:
            return self.geometry_npy
        return str(Path(self.geometry_npy).with_suffix(f".f{self.frame:05d}.npy"))


@functools.lru_cache(maxsize=16)
def _image(path: str) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


@functools.lru_cache(maxsize=16)
def _grey(path: str) -> np.ndarray:
    return np.ascontiguousarray(_image(path)[..., 0])


@functools.lru_cache(maxsize=8)
def _eye_textures(rig_npz: str, iris_scale: float, paint: float) -> dict[str, np.ndarray]:
    """The rig's eye and lash textures stylised (:mod:`stimulus_engine.stylisation.eyes`; one
    array per style: the renderer keeps it on the GPU)."""
    from stimulus_engine.stylisation.eyes import bold_lash_texture, stylised_eye_texture

    own = load_rig(rig_npz).part_textures
    out = {"eye": stylised_eye_texture(own["eye"], iris_scale, paint)} if "eye" in own else {}
    if "lashes" in own:
        out["lashes"] = bold_lash_texture(own["lashes"], paint)
    return out


#: From this paint on, a painted level's hair is drawn as masses in the path tracer too (its
#: cards, no strand curves: :attr:`stimulus_engine.parts.hair.Hair.massed`).
MASSED_FROM = 0.5


@functools.lru_cache(maxsize=8)
def _hair(rig_npz: str, paint: float):
    """The rig's hair with its texture simplified into masses by ``paint`` (None without hair)."""
    from stimulus_engine.stylisation.hair import hair_mass_texture

    hair = load_rig(rig_npz).hair
    if hair is None or paint == 0.0:
        return hair
    return dataclasses.replace(hair, texture=hair_mass_texture(hair.texture, paint), massed=paint >= MASSED_FROM)


def _map_image(path: str, kind: str) -> np.ndarray | None:
    """A prepared map from the cache (specular maps are stored as grey RGB), or None."""
    if not path:
        return None
    return _image(path) if kind == "normal" else _grey(path)


def _occlusion(rig, vertices: np.ndarray, geometry_npy: str, inside_only: bool = False) -> np.ndarray:
    """The geometry's baked ambient visibility, cached beside it (once per character, shape and
    expression: every lighting, material and shading of that geometry reuses it); with
    ``inside_only``, only the mouth's inside (the rest 1)."""
    from stimulus_engine.characters.render_parts import rig_occlusion
    from stimulus_engine.grid.cache import save_npy

    path = Path(geometry_npy).with_suffix(".inside.npy" if inside_only else ".occlusion.npy")
    if path.exists():
        return np.load(path)
    occ = rig_occlusion(rig, vertices, inside_only=inside_only)
    save_npy(path, occ)  # atomic: two workers baking the same geometry write the same bytes
    return occ


def blend_fraction(v: np.ndarray, v0: np.ndarray, apex: np.ndarray, floor: float = 1e-4) -> np.ndarray:
    """Per vertex, how far ``v`` has moved from ``v0`` towards ``apex``: ``|v - v0| / |apex - v0|``
    clipped to [0, 1] (1 where the apex does not move the vertex but ``v`` does; 0 where neither
    moves more than ``floor``).

    Examples
    --------
    >>> v0 = np.zeros((3, 3)); apex = np.array([[1.0, 0, 0], [0, 0, 0], [0, 2.0, 0]])
    >>> blend_fraction(np.array([[0.5, 0, 0], [0, 0.3, 0], [0, 3.0, 0]]), v0, apex).tolist()
    [0.5, 1.0, 1.0]
    """
    moved = np.linalg.norm(v - v0, axis=1)
    full = np.linalg.norm(apex - v0, axis=1)
    return np.where(moved <= floor, 0.0, np.clip(moved / np.maximum(full, floor), 0.0, 1.0))


def blended_occlusion(rig, item: RenderItem, inside_only: bool) -> np.ndarray:
    """A clip frame's ambient visibility blended from the baked visibility of the clip's first frame
    and of its apex (``item.occlusion_blend``), per vertex by :func:`blend_fraction`: a third of a
    frame's time saved where a clip's frames would each be baked (benchmarks/revcorr_clips.py
    measures the images' difference)."""
    from stimulus_engine.grid.cache import sha

    (apex,) = item.occlusion_blend
    ends = [dataclasses.replace(item, frame=k, occlusion_blend=()).geometry() for k in (0, apex)]
    folder = Path(item.geometry_npy).parent
    # kept by the geometry's content: the neutral first frame of every clip of a cell is baked once
    o0, oa = (_occlusion(rig, v, str(folder / f"{sha(v.tobytes())}.npy"), inside_only) for v in ends)
    a = blend_fraction(item.geometry(), *ends)
    return (o0 + (oa - o0) * a).astype(np.float32)


def item_scene(item: RenderItem) -> tuple[list, object]:
    """The render parts and the camera of ``item`` (the scene both engines draw)."""
    from stimulus_engine.characters.render_parts import (
        INSIDE_PARTS,
        SKIN_LIKE,
        rig_render_parts,
    )
    from stimulus_engine.render import CameraSpec

    rig = load_rig(item.rig_npz)
    if item.eye_style:  # stylised eyes, lashes and hair (stimulus_engine.stylisation.eyes, .hair)
        rig = dataclasses.replace(rig, part_textures={**rig.part_textures, **_eye_textures(item.rig_npz, *item.eye_style)},
                                  hair=_hair(item.rig_npz, item.eye_style[1]))
    v = item.geometry()
    # baked ambient visibility: skin (and toon) shading's ambient light, and a mouth's inside in every shading
    inside_only = item.shading not in SKIN_LIKE
    wanted = not inside_only or any(p in rig.part_names for p in INSIDE_PARTS)
    occlusion = None
    if wanted and item.engine == "pyrender":
        occlusion = (blended_occlusion(rig, item, inside_only) if item.occlusion_blend and item.frame >= 0
                     else _occlusion(rig, v, item.geometry_key(), inside_only))
    parts = rig_render_parts(rig, v, _image(item.albedo_png), shading=item.shading,
                             normal_map=_map_image(item.normal_png, "normal"),
                             specular_map=_map_image(item.specular_png, "specular"), occlusion=occlusion,
                             surround_image=_image(item.surround_png) if item.surround_png else None)
    pos, target, yfov, up = item.camera
    return parts, CameraSpec(tuple(pos), tuple(target), yfov, tuple(up))


def _render_pyrender(item: RenderItem) -> np.ndarray:
    """The image of ``item`` rasterised by pyrender (OpenGL)."""
    from stimulus_engine.render import render_mesh

    parts, cam = item_scene(item)
    return render_mesh(parts, width=item.width, height=item.height, lighting=item.lighting, camera=cam,
                       background=item.background, shadows=item.shadows, supersample=item.supersample)


def export_item_scene(item: RenderItem, folder: str | Path) -> Path:
    """Export ``item``'s scene as the path tracer reads it (its parts, lighting, camera, size and
    background: :func:`stimulus_engine.render.scene_export.export_scene`) into ``folder``; the
    path of its ``scene.json``."""
    from stimulus_engine.render import lighting_preset
    from stimulus_engine.render.scene_export import export_scene

    parts, cam = item_scene(item)
    lights, ambient = lighting_preset(item.lighting) if isinstance(item.lighting, str) else item.lighting
    return export_scene(parts, lights, ambient, cam, folder, width=item.width, height=item.height,
                        background=item.background)


def _render_cycles(item: RenderItem) -> np.ndarray:
    """The image of ``item`` path-traced by Blender's Cycles (in its own Python)."""
    from stimulus_engine.render.cycles import render_cycles

    parts, cam = item_scene(item)
    return render_cycles(parts, width=item.width, height=item.height, lighting=item.lighting, camera=cam,
                         background=item.background, samples=item.samples, seed=item.seed)


#: Render engines: a :class:`RenderItem` -> its (H, W, 3) uint8 image.
ENGINES: dict[str, Callable[[RenderItem], np.ndarray]] = {"pyrender": _render_pyrender, "cycles": _render_cycles}


def render_image(item: RenderItem) -> np.ndarray:
    """The (H, W, 3) uint8 image of ``item`` (its engine, then its vignette), written nowhere."""
    image = ENGINES[item.engine](item)
    if item.vignette:
        from stimulus_engine.render.vignette import oval_vignette

        image = oval_vignette(image, item.vignette, item.background)
    return image


def render_item(item: RenderItem) -> float:
    """Render one grid image to ``item.out_dir/item.file``; returns the seconds it took."""
    from stimulus_engine.render import save_png

    t0 = time.perf_counter()
    save_png(render_image(item), Path(item.out_dir) / item.file)
    return time.perf_counter() - t0


def place_photo(src: str, dst: Path, width: int, height: int, background: tuple, like: str | None = None) -> None:
    """A photograph at the stimulus size on the grid's background: framed as the rendered image
    ``like`` (its eye centres and philtrum on the render's:
    :func:`~stimulus_engine.grid.photo_framing.photo_like_render`, so the photograph of a character
    lands where its renders put the face), else letterboxed."""
    from stimulus_engine.render import save_png

    if like is not None and Path(like).is_file():
        from appeal.errors import AppealInputError
        from stimulus_engine.grid.photo_framing import photo_like_render

        bg = tuple(int(round(b * 255)) for b in background)
        try:
            save_png(photo_like_render(_image(src), _image(like), bg, src), dst)
            return
        except AppealInputError:  # no face found in one of them: letterboxed as before
            pass
    with Image.open(src) as im:
        im = im.convert("RGB")
        scale = min(width / im.width, height / im.height)
        im = im.resize((max(1, round(im.width * scale)), max(1, round(im.height * scale))), Image.LANCZOS)
    canvas = Image.new("RGB", (width, height), tuple(int(round(b * 255)) for b in background))
    canvas.paste(im, ((width - im.width) // 2, (height - im.height) // 2))
    save_png(np.asarray(canvas), dst)
