"""The module paths of the flat layout before the sub-packages, kept importable for one release.

``import stimulus_engine.mesh_io`` (or ``from stimulus_engine.materials import rig_albedo``)
still works, with a :class:`DeprecationWarning` naming the new path. A module that moved whole
is the new module itself; one that was split (``materials``, ``ict``, ``texture_transfer``)
looks its names up in the modules its parts went to, in order. Remove after the next release.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings

__all__ = ["MOVED", "install"]

_P = "stimulus_engine."

#: Old module → the module(s) its names now live in (the first is where it went).
MOVED: dict[str, tuple[str, ...]] = {_P + old: tuple(_P + n for n in new) for old, new in {
    "obj_format": ("geometry.obj_format",),
    "mesh_io": ("geometry.mesh_io",),
    "mesh_ops": ("geometry.mesh_ops",),
    "sampling": ("geometry.sampling",),
    "polyline2d": ("geometry.polyline2d",),
    "correspondence.closest": ("geometry.closest",),
    "correspondence.triangle_bvh": ("geometry.triangle_bvh",),
    "eyes": ("parts.eyes",),
    "eyelashes": ("parts.eyelashes",),
    "hair": ("parts.hair",),
    "rig": ("characters.rig",),
    "ict": ("characters.ict", "geometry.ict_topology"),
    "procedural_head": ("characters.procedural_head",),
    "expressions": ("characters.expressions",),
    "mesh_character": ("characters.mesh_character",),
    "scan_cut": ("characters.scan_cut",),
    "scan_eyes": ("characters.scan_eyes",),
    "scan_mouth": ("characters.scan_mouth",),
    "scan_regions": ("characters.scan_regions",),
    "scan_surface": ("characters.scan_surface",),
    "render.rig_parts": ("characters.render_parts",),
    "texture_transfer": ("correspondence.texture_transfer", "geometry.uv_raster"),
    "stylise": ("stylisation.shape",),
    "neoteny": ("stylisation.neoteny",),
    "materials": ("stylisation.materials", "characters.skin_maps", "characters.render_parts"),
    "morph": ("stylisation.morph",),
    "morph_regions": ("stylisation.morph_regions",),
    "gradient_blend": ("stylisation.gradient_blend",),
    "grid_schema": ("grid.schema",),
}.items()}


def _stacklevel() -> int:
    """The ``stacklevel`` that points a warning from ``exec_module`` at the importing code.

    :func:`warnings.warn` itself steps over the import system's bootstrap frames; this also steps
    over :func:`importlib.import_module`, so the warning names the line that asked for the module.
    """
    frame, level = sys._getframe(2), 2  # exec_module's caller
    while frame is not None:
        name = frame.f_code.co_filename
        bootstrap = "importlib" in name and "_bootstrap" in name
        if not (bootstrap or name == importlib.__file__):
            break
        level += 0 if bootstrap else 1
        frame = frame.f_back
    return level


class _Loader(importlib.abc.Loader):
    def create_module(self, spec):  # noqa: D102
        return None  # the default module: exec_module fills it or puts the new one in its place

    def exec_module(self, module: types.ModuleType) -> None:  # noqa: D102
        old = module.__name__
        targets = [importlib.import_module(t) for t in MOVED[old]]
        warnings.warn(f"{old} is now {MOVED[old][0]}" + (f" (with {', '.join(MOVED[old][1:])})" if len(targets) > 1 else "")
                      + "; the old path goes in the next release", DeprecationWarning, stacklevel=_stacklevel())
        if len(targets) == 1:
            sys.modules[old] = targets[0]  # the import system returns what sys.modules holds
            return

        def __getattr__(name: str):
            for t in targets:
                if hasattr(t, name):
                    return getattr(t, name)
            raise AttributeError(f"module {old!r} (now {MOVED[old][0]}) has no attribute {name!r}")

        module.__getattr__ = __getattr__
        module.__all__ = [n for t in targets for n in getattr(t, "__all__", ())]


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):  # noqa: D102
        if fullname in MOVED:
            return importlib.machinery.ModuleSpec(fullname, _LOADER)
        return None


_LOADER = _Loader()


def install() -> None:
    """Let the old paths import (once per process; the finder answers only the names of :data:`MOVED`)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())
