"""The one place that imports :mod:`pyrender`.

pyrender needs an OpenGL platform chosen *before* PyOpenGL is first imported, and it still
uses ``np.infty`` (removed in numpy 2). Both are handled here, once, together with a fix of
pyrender's shader cache under OSMesa (:func:`_context_key`) and of its unusable
specular-glossiness ("Phong") material (:func:`phong_fragment_shader`; the
``glossinessFactor`` getter recursed forever); everything else in the project imports ``pyrender`` as ``from stimulus_engine.render._pyrender import pyrender``.

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

__all__ = ["pyrender", "phong_fragment_shader", "platform"]


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
        if fragment_shader == "mesh.frag" and "USE_GLOSSY_MATERIAL" in defines:
            fs = _phong_shader_path(self.shader_dir)  # pyrender's own has no glossy branch
        self._program_cache[key] = _sp.ShaderProgram(vertex_shader=vs, fragment_shader=fs, geometry_shader=gs,
                                                     defines=defines)
    return self._program_cache[key]


_GLOSSY_SETUP = """#ifdef USE_GLOSSY_MATERIAL

    // Blinn-Phong (specular-glossiness): diffuse colour, specular colour, glossiness -> exponent
    vec4 base_color = material.diffuse_factor;
#ifdef HAS_DIFFUSE_TEX
    base_color = base_color * srgb_to_linear(texture(material.diffuse_texture, uv_0));
#endif
    vec3 f0 = material.specular_factor;
    float glossiness = material.glossiness_factor;
#ifdef HAS_SPECULAR_GLOSSINESS_TEX
    vec4 sg = texture(material.specular_glossiness_texture, uv_0);
    f0 = f0 * sg.rgb;
    glossiness = glossiness * sg.a;
#endif
    float roughness = exp2(1.0 + 10.0 * clamp(glossiness, 0.0, 1.0));  // the Phong exponent
    float metallic = 0.0;
    vec3 c_diff = base_color.rgb;

"""

_PHONG_BRDF = """vec3 compute_phong(vec3 n, vec3 v, vec3 l,
                   float exponent, float unused,
                   vec3 spec, vec3 c_diff, vec3 albedo,
                   vec3 radiance)
{
        vec3 h = normalize(l + v);
        float nl = clamp(dot(n, l), 0.0, 1.0);
        float nh = clamp(dot(n, h), 0.0, 1.0);
        float norm = (exponent + 8.0) / (8.0 * PI);  // energy-normalised Blinn-Phong lobe
        return nl * radiance * (c_diff / PI + spec * norm * pow(nh, exponent));
}

"""


def _once(text: str, anchor: str) -> int:
    if text.count(anchor) != 1:
        raise RuntimeError(f"pyrender's mesh.frag changed (anchor {anchor!r} found {text.count(anchor)} times); "
                           "the Phong shader patch was written for pyrender 0.1.45")
    return text.index(anchor)


def phong_fragment_shader(text: str) -> str:
    """pyrender 0.1.45's ``mesh.frag`` with its missing specular-glossiness branch filled in.

    pyrender accepts a ``SpecularGlossinessMaterial`` but its shader only has
    ``// TODO GLOSSY MATERIAL BRDF`` there (nothing is written to the pixel) and names the
    specular-glossiness sampler differently from what the renderer binds. The patched shader
    runs the same light loops (directional and spot lights with shadow maps, point lights,
    ambient, normal map via the same ``get_normal``) with an energy-normalised Blinn-Phong BRDF:
    diffuse ``c_diff / π`` and specular ``F0 · (e + 8) / 8π · (n·h)^e`` with exponent
    ``e = 2^(1 + 10 g)`` from the glossiness ``g``. The metallic-roughness path is untouched.
    """
    sampler = "    sampler2D specular_glossiness;\n"
    i = _once(text, sampler)
    text = text[:i] + "    sampler2D specular_glossiness_texture;\n" + text[i + len(sampler):]
    i = _once(text, "float texture2DCompare(")
    text = text[:i] + _PHONG_BRDF + text[i:]
    start = _once(text, "#ifdef USE_METALLIC_MATERIAL\n\n    // Compute metallic/roughness factors")
    normal = text.index("    // Compute normal", start)
    todo = "#else\n    // TODO GLOSSY MATERIAL BRDF\n#endif\n"
    end = _once(text, todo)
    loops = text[normal:end].replace("compute_brdf(", "compute_phong(")
    return text[:end] + "#endif\n" + _GLOSSY_SETUP + loops + "#endif\n" + text[end + len(todo):]


def _phong_shader_path(shader_dir: str) -> str:
    """The patched ``mesh.frag`` (see :func:`phong_fragment_shader`), written once to a temp file
    named by its content hash (pyrender's shader programs load their sources from files)."""
    import hashlib
    import tempfile

    with open(os.path.join(shader_dir, "mesh.frag")) as f:
        text = phong_fragment_shader(f.read())
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    path = os.path.join(tempfile.gettempdir(), f"appeal-pyrender-mesh-phong-{digest}.frag")
    if not os.path.exists(path):
        tmp = f"{path}.{os.getpid()}.tmp"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    return path


_sp.ShaderProgramCache.get_program = _get_program
# pyrender 0.1.45's getter returns ``self.glossinessFactor`` (infinite recursion)
pyrender.material.SpecularGlossinessMaterial.glossinessFactor = property(
    lambda self: self._glossinessFactor, pyrender.material.SpecularGlossinessMaterial.glossinessFactor.fset)


def platform() -> str:
    """The OpenGL platform pyrender renders with (``osmesa``, ``egl`` or ``pyglet``)."""
    return os.environ.get("PYOPENGL_PLATFORM", "osmesa")
