"""The one place that imports :mod:`pyrender`.

pyrender needs an OpenGL platform chosen *before* PyOpenGL is first imported, and it still
uses ``np.infty`` (removed in numpy 2). Both are handled here, once, together with a fix of
pyrender's shader cache under OSMesa (:func:`_context_key`); everything else in the
project imports ``pyrender`` as ``from stimulus_engine.render._pyrender import pyrender``.

The platform defaults to OSMesa (pure CPU, no display); set ``PYOPENGL_PLATFORM=egl`` in the
environment before starting Python to use a GPU through EGL instead.
"""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")

import numpy as np  # noqa: E402

if not hasattr(np, "infty"):  # numpy >= 2 removed the alias pyrender still uses
    np.infty = np.inf  # type: ignore[attr-defined]

import ctypes  # noqa: E402

import OpenGL.contextdata  # noqa: E402
import pyrender  # noqa: E402
import pyrender.shader_program as _sp  # noqa: E402

__all__ = ["pyrender", "platform"]


def _context_key() -> object:
    """A stable key for the current OpenGL context.

    With OSMesa, ``OpenGL.contextdata.getContext()`` returns a *new* pointer wrapper on every
    call, so pyrender's shader cache (keyed by that object) missed on every frame: each render
    recompiled all shader programs and the cache grew without bound. The pointer's address is
    stable, so the cache is keyed by it instead.
    """
    cid = OpenGL.contextdata.getContext()
    try:
        return ctypes.cast(cid, ctypes.c_void_p).value
    except (TypeError, ctypes.ArgumentError):
        return cid


def _get_program(self, vertex_shader, fragment_shader, geometry_shader=None, defines=None):  # type: ignore[no-untyped-def]
    """pyrender's ``ShaderProgramCache.get_program`` with a stable context key (see above)."""
    defines = defines or {}
    files = [x for x in (vertex_shader, fragment_shader, geometry_shader) if x is not None]
    key = tuple([_context_key()] + sorted([(os.path.split(f)[1], 1) for f in files] + list(defines.items())))
    if key not in self._program_cache:
        paths = [os.path.join(self.shader_dir, f) for f in files] + [None] * (3 - len(files))
        vs, fs, gs = paths
        self._program_cache[key] = _sp.ShaderProgram(vertex_shader=vs, fragment_shader=fs, geometry_shader=gs,
                                                     defines=defines)
    return self._program_cache[key]


_sp.ShaderProgramCache.get_program = _get_program


def platform() -> str:
    """The OpenGL platform pyrender renders with (``osmesa``, ``egl`` or ``pyglet``)."""
    return os.environ.get("PYOPENGL_PLATFORM", "osmesa")
