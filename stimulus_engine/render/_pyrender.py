"""The one place that imports :mod:`pyrender`.

pyrender needs an OpenGL platform chosen *before* PyOpenGL is first imported, and it still
uses ``np.infty`` (removed in numpy 2). Both are handled here, once, together with a fix of
pyrender's shader cache under OSMesa (:func:`_context_key`), its shadow-map lookup
(:func:`shadow_fragment_shader`), its limit of 4 lights per type without shadows, and of its unusable
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

import contextlib  # noqa: E402
import ctypes  # noqa: E402
import threading  # noqa: E402
from collections.abc import Iterator  # noqa: E402

import OpenGL.contextdata  # noqa: E402
import pyrender  # noqa: E402
import pyrender.shader_program as _sp  # noqa: E402

from stimulus_engine.render.light_shadows import (  # noqa: E402
    SHADOW_KEY,
    SHADOW_MAP,
    SHADOW_NONE,
    casts_shadow_map,
    light_shadow_fragment_shader,
)

__all__ = ["pyrender", "alpha_test_fragment_shader", "phong_fragment_shader", "platform", "scene_defines",
           "shadow_fragment_shader"]


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


#: The ``appeal_defines`` of the material whose program is being looked up (set around pyrender's
#: ``_get_primitive_program``): how a material turns on a shader switch (e.g. the skin shading).
_MATERIAL = threading.local()
#: Defines the scene being rendered asks of every mesh program (:func:`scene_defines`).
_SCENE = threading.local()


@contextlib.contextmanager
def scene_defines(defines: dict | None) -> Iterator[None]:
    """Compile (and look up) every mesh program drawn inside with these extra ``#define`` s: a
    switch the whole scene needs (the key light's shadow lookup, :mod:`.light_shadows`)."""
    _SCENE.defines = defines
    try:
        yield
    finally:
        _SCENE.defines = None


def _get_program(self, vertex_shader, fragment_shader, geometry_shader=None, defines=None):  # type: ignore[no-untyped-def]
    """pyrender's ``ShaderProgramCache.get_program`` with a stable context key (see above), the
    patched ``mesh.frag`` (:func:`shadow_fragment_shader`, :func:`phong_fragment_shader`,
    :func:`~stimulus_engine.render.skin_shader.skin_fragment_shader`) and the defines the
    material asks for (its ``appeal_defines``) and the scene (:func:`scene_defines`)."""
    defines = {**(defines or {}), **(getattr(_MATERIAL, "defines", None) or {})}
    if fragment_shader == "mesh.frag":
        defines.update(getattr(_SCENE, "defines", None) or {})
    files = [x for x in (vertex_shader, fragment_shader, geometry_shader) if x is not None]
    key = tuple([_context_key()] + sorted([(os.path.split(f)[1], 1) for f in files] + list(defines.items())))
    if key not in self._program_cache:
        paths = [os.path.join(self.shader_dir, f) for f in files] + [None] * (3 - len(files))
        vs, fs, gs = paths
        if fragment_shader == "mesh.frag":
            fs = _mesh_shader_path(self.shader_dir, glossy="USE_GLOSSY_MATERIAL" in defines)
        self._program_cache[key] = _sp.ShaderProgram(vertex_shader=vs, fragment_shader=fs, geometry_shader=gs,
                                                     defines=defines)
    return self._program_cache[key]


_GLOSSY_SETUP = """#ifdef USE_GLOSSY_MATERIAL

    // Blinn-Phong (specular-glossiness): diffuse colour, specular colour, glossiness -> exponent
    vec4 base_color = material.diffuse_factor;
#ifdef HAS_DIFFUSE_TEX
    base_color = base_color * srgb_to_linear(texture(material.diffuse_texture, uv_0));
#endif
    if (base_color.a < ALPHA_CUTOFF) discard;
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


#: Alpha below which a fragment is not drawn (alpha-tested cards: hair, whose texture's alpha is 0
#: or 1; blended cards, lashes, keep their soft edges above it; opaque parts have alpha 1). Low, so
#: that mipmapped strands far away fade rather than vanish.
ALPHA_CUTOFF = 0.1


def alpha_test_fragment_shader(text: str) -> str:
    """pyrender 0.1.45's ``mesh.frag`` with an alpha test: fragments whose base colour's alpha
    is below :data:`ALPHA_CUTOFF` are discarded (pyrender only blends, unsorted, so hair cards
    drawn with blending show the cards behind them in the wrong order)."""
    anchor = "    base_color = base_color * srgb_to_linear(texture(material.base_color_texture, uv_0));\n#endif\n"
    i = _once(text, anchor) + len(anchor)
    text = text[:i] + "    if (base_color.a < ALPHA_CUTOFF) discard;\n" + text[i:]
    i = _once(text, "float texture2DCompare(")
    return text[:i] + f"const float ALPHA_CUTOFF = {ALPHA_CUTOFF};\n\n" + text[i:]


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


#: The classic 16-point Poisson-disk kernel (unit disc) of the PCF below.
_POISSON_16 = ((-0.94201624, -0.39906216), (0.94558609, -0.76890725), (-0.09418410, -0.92938870),
               (0.34495938, 0.29387760), (-0.91588581, 0.45771432), (-0.81544232, -0.87912464),
               (-0.38277543, 0.27676845), (0.97484398, 0.75648379), (0.44323325, -0.97511554),
               (0.53742981, -0.47373420), (-0.26496911, -0.41893023), (0.79197514, 0.19090188),
               (-0.24188840, 0.99706507), (-0.81409955, 0.91437590), (0.19984126, 0.78641367),
               (0.14383161, -0.14100790))

#: Radius of the PCF kernel in shadow-map texels (the penumbra of a "hard" shadow is about twice this).
PCF_RADIUS_TEXELS = 1.5
#: One shadow-map texel's width in units of the map's depth range, for the scene-fitted shadow
#: cameras of :mod:`stimulus_engine.render.renderer` (2048 texels across about the depth range).
TEXEL_DEPTH = 1.0 / 2048
#: Constant depth bias, in texel widths (curvature within the filter's footprint).
BIAS_TEXELS = 0.5
#: Normal offset of the shadow lookup, in texel widths (grazing light, concave triangle edges).
NORMAL_OFFSET_TEXELS = 1.5
#: Largest receiver-plane slope, in texel widths of depth per texel (a surface about 80 degrees
#: from facing the light); steeper surfaces get this slope.
MAX_SLOPE_TEXELS = 6.0

_SHADOW_CODE = """float shadow_compare(sampler2D depths, vec2 texel, float depth) {
    // 1.0 where the shadow map texel (integer coordinates) is closer to the light than depth
    return depth > texelFetch(depths, ivec2(texel), 0).r ? 1.0 : 0.0;
}

float shadow_bilinear(sampler2D depths, vec2 size, vec2 uv, float z, vec2 dz_duv, float bias) {
    // bilinearly weighted comparisons of the four texels around uv, each against the receiver
    // plane's depth at that texel's centre (so a tilted surface never shadows itself)
    vec2 p = uv * size - 0.5;
    vec2 base = floor(p);
    vec2 f = p - base;
    float s[4];
    for (int k = 0; k < 4; k++) {
        vec2 t = base + vec2(k & 1, k >> 1);
        vec2 tc = clamp(t, vec2(0.0), size - 1.0);
        float zt = z + dot(dz_duv, t + 0.5 - uv * size) - bias;
        s[k] = shadow_compare(depths, tc, zt);
    }
    return mix(mix(s[0], s[1], f.x), mix(s[2], s[3], f.x), f.y);
}

const vec2 POISSON_DISK[16] = vec2[16](POISSON_POINTS);

struct ShadowLookup {
    vec2 size;     // of the map, in texels
    vec3 lc;       // the (normal-offset) point in the map: texture coordinates and depth
    vec2 dz_duv;   // receiver plane: depth change per texel
    float bias;
};

ShadowLookup shadow_setup(mat4 light_matrix, sampler2D shadow_map)
{
    // screen-space derivatives: call in uniform control flow (shadow_filter may be branched)
    ShadowLookup s;
    s.size = vec2(textureSize(shadow_map, 0));
    // Normal offset: look up a point a little above this triangle (its geometric normal, on the
    // side the camera sees), by a number of shadow-map texel widths at this distance from the light
    vec3 ng = normalize(cross(dFdx(frag_position), dFdy(frag_position)));
    ng *= sign(dot(ng, cam_pos - frag_position) + 1e-12);
    vec4 here = light_matrix * vec4(frag_position.xyz, 1.0);
    float texel_world = 2.0 * here.w / (s.size.x * length(vec3(light_matrix[0][0], light_matrix[1][0], light_matrix[2][0])));
    // Light-space position of that point: texture coordinates and depth in 0..1
    vec4 proj_coords = light_matrix * vec4(frag_position.xyz + ng * (NORMAL_OFFSET * texel_world), 1.0);
    s.lc = (proj_coords.xyz / proj_coords.w) * 0.5 + 0.5;
    // Receiver plane (this triangle, from screen-space derivatives): depth change per texel
    vec3 dx = dFdx(s.lc);
    vec3 dy = dFdy(s.lc);
    vec2 ux = dx.xy * s.size;
    vec2 uy = dy.xy * s.size;
    float det = ux.x * uy.y - ux.y * uy.x;
    s.dz_duv = vec2(0.0);
    if (abs(det) > 1e-12) {
        s.dz_duv = vec2(uy.y * dx.z - ux.y * dy.z, ux.x * dy.z - uy.x * dx.z) / det;
    }
    float slope = length(s.dz_duv);
    if (slope > MAX_SLOPE) {
        s.dz_duv *= MAX_SLOPE / slope;  // grazing angles: keep the bias bounded
    }
    // constant bias: depth quantisation plus the part of a texel the plane does not model
    s.bias = BIAS_TEXELS * TEXEL_DEPTH + 0.5 * min(slope, MAX_SLOPE);
    return s;
}

float shadow_filter(ShadowLookup s, sampler2D shadow_map)
{
    if (s.lc.z > 1.0) {
        return 0.0;
    }
    float shadow = 0.0;
    for (int i = 0; i < 16; i++) {
        vec2 off = POISSON_DISK[i] * PCF_RADIUS;  // in texels
        shadow += shadow_bilinear(shadow_map, s.size, s.lc.xy + off / s.size, s.lc.z + dot(s.dz_duv, off), s.dz_duv, s.bias);
    }
    return shadow / 16.0;
}

float shadow_tap(ShadowLookup s, sampler2D shadow_map)
{
    // one bilinear tap, for a map whose texels are smaller than a pixel (the key light's)
    return s.lc.z > 1.0 ? 0.0 : shadow_bilinear(shadow_map, s.size, s.lc.xy, s.lc.z, s.dz_duv, s.bias);
}

float shadow_calc(mat4 light_matrix, sampler2D shadow_map, float nl)
{
    return shadow_filter(shadow_setup(light_matrix, shadow_map), shadow_map);
}

"""


def shadow_fragment_shader(text: str) -> str:
    """pyrender 0.1.45's ``mesh.frag`` with soft, artefact-free shadow-map lookups.

    pyrender compares the fragment's light-space depth with a fixed bias against a 3 × 3 block
    of shadow-map texels. On a surface tilted towards the light, the neighbouring texels of that
    block lie closer to the light than the fragment by more than the bias, so lit skin shadows
    itself in patches that follow the mesh's triangles (the "staircase" blocks on cheeks and
    around the eyes), and shadow edges step from texel to texel.

    The replacement filters with percentage-closer filtering over a 16-point Poisson disk of
    radius :data:`PCF_RADIUS_TEXELS` (each tap a bilinear blend of four comparisons), and
    compares every texel against the *receiver plane*, the fragment's own triangle extended in
    light space (its depth slope per texel from screen-space derivatives, clamped at grazing
    angles), plus a small slope-scaled bias: no self-shadowing, smooth penumbrae. Directional
    and spot lights use the same code (``SHADOWS_ALL`` is never requested; point-light shadows
    are not implemented by pyrender).
    """
    start = _once(text, "float PCF(sampler2D depths, vec2 size, vec2 uv, float compare){")
    end = _once(text, "///////////////////////////////////////////////////////////////////////////////\n// MAIN")
    if "float shadow_calc(mat4 light_matrix, sampler2D shadow_map, float nl)" not in text[start:end]:
        raise RuntimeError("pyrender's mesh.frag changed (shadow_calc not after PCF); "
                           "the shadow patch was written for pyrender 0.1.45")
    points = ", ".join(f"vec2({x:.8f}, {y:.8f})" for x, y in _POISSON_16)
    code = (_SHADOW_CODE.replace("POISSON_POINTS", points).replace("PCF_RADIUS", f"{PCF_RADIUS_TEXELS:.4f}")
            .replace("NORMAL_OFFSET", f"{NORMAL_OFFSET_TEXELS:.4f}").replace("MAX_SLOPE", f"{MAX_SLOPE_TEXELS * TEXEL_DEPTH:.6g}")
            .replace("BIAS_TEXELS * TEXEL_DEPTH", f"{BIAS_TEXELS * TEXEL_DEPTH:.6g}"))
    return text[:start] + code + text[end:]


def _mesh_shader_path(shader_dir: str, glossy: bool) -> str:
    """The patched ``mesh.frag`` (:func:`shadow_fragment_shader`, and for specular-glossiness
    materials :func:`phong_fragment_shader`), written once to a temp file named by its content
    hash (pyrender's shader programs load their sources from files)."""
    import hashlib
    import tempfile

    from stimulus_engine.render.skin_shader import skin_fragment_shader

    with open(os.path.join(shader_dir, "mesh.frag")) as f:
        text = alpha_test_fragment_shader(shadow_fragment_shader(f.read()))
    if glossy:
        text = phong_fragment_shader(text)
    text = skin_fragment_shader(text)  # its switches are off unless a material turns them on
    text = light_shadow_fragment_shader(text)
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    path = os.path.join(tempfile.gettempdir(), f"appeal-pyrender-mesh-{digest}.frag")
    if not os.path.exists(path):
        tmp = f"{path}.{os.getpid()}.tmp"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    return path


_sp.ShaderProgramCache.get_program = _get_program
_get_primitive_program = pyrender.renderer.Renderer._get_primitive_program


def _get_primitive_program_with_material_defines(self, primitive, flags, program_flags):  # type: ignore[no-untyped-def]
    _MATERIAL.defines = getattr(primitive.material, "appeal_defines", None)
    try:
        return _get_primitive_program(self, primitive, flags, program_flags)
    finally:
        _MATERIAL.defines = None


pyrender.renderer.Renderer._get_primitive_program = _get_primitive_program_with_material_defines
# Without shadow maps pyrender draws at most MAX_N_LIGHTS (4) lights of each type per mesh, the 4
# nearest to that mesh: gi_soft's dome of 12 directional lights plus 2 rims was drawn with 4 of
# them, not necessarily the same 4 for the skin and the eyes. With shadow maps the limit is the
# free texture units (13 per light type here). 16 covers every preset.
pyrender.renderer.MAX_N_LIGHTS = 16
_shadow_mapping_pass = pyrender.renderer.Renderer._shadow_mapping_pass


def _see_through(material) -> bool:  # type: ignore[no-untyped-def]
    """A blended material whose RGBA texture has see-through texels (pyrender's own
    ``Texture.is_transparent`` starts at False and never looks)."""
    tex = getattr(material, "baseColorTexture", None)
    return (getattr(material, "alphaMode", "OPAQUE") == "BLEND" and tex is not None
            and tex.source_channels == "RGBA" and bool(np.any(np.asarray(tex.source)[..., 3] < 255)))


def _shadow_pass_without_blended(self, scene, light_node, flags):  # type: ignore[no-untyped-def]
    """pyrender's shadow-map pass without alpha-blended meshes (lashes): the depth pass ignores
    alpha, so a card casts the shadow of its whole rectangle (a dark band over the eyeball));
    lights that cast no shadow map (:mod:`.light_shadows`) are skipped."""
    if not casts_shadow_map(light_node.light):
        return None
    visible = [n.mesh for n in scene.mesh_nodes if n.mesh.is_visible]
    hidden = [m for m in visible if m.primitives and all(_see_through(p.material) for p in m.primitives)]
    if len(hidden) == len(visible):  # pyrender's pass needs one mesh to draw
        hidden = []
    for m in hidden:
        m.is_visible = False
    try:
        return _shadow_mapping_pass(self, scene, light_node, flags)
    finally:
        for m in hidden:
            m.is_visible = True


pyrender.renderer.Renderer._shadow_mapping_pass = _shadow_pass_without_blended
_bind_lighting = pyrender.renderer.Renderer._bind_lighting


def _bind_lighting_and_shadows(self, scene, program, node, flags):  # type: ignore[no-untyped-def]
    """pyrender's light uniforms, plus each light's shadow kind (``appeal_shadow``,
    :mod:`.light_shadows`) and the key light's map.

    Walks the lights in the order and with the per-type limits pyrender used, so index ``k`` of
    each type is the same light. A light without ``appeal_shadow`` (made elsewhere) keeps
    pyrender's behaviour: a shadow map when its type's flag is on.
    """
    _bind_lighting(self, scene, program, node, flags)
    max_n = self._compute_max_n_lights(flags)
    nodes = scene.light_nodes
    if (len(scene.directional_light_nodes) > max_n[0] or len(scene.spot_light_nodes) > max_n[1]
            or len(scene.point_light_nodes) > max_n[2]):
        nodes = self._sorted_nodes_by_distance(scene, scene.light_nodes, node)
    count = {"directional_lights": 0, "spot_lights": 0}
    flag_on = {"directional_lights": bool(flags & pyrender.RenderFlags.SHADOWS_DIRECTIONAL),
               "spot_lights": bool(flags & pyrender.RenderFlags.SHADOWS_SPOT)}
    for n in nodes:
        if isinstance(n.light, pyrender.PointLight):
            continue
        kind = "spot_lights" if isinstance(n.light, pyrender.SpotLight) else "directional_lights"
        k = count[kind]
        if k == max_n[0 if kind == "directional_lights" else 1]:
            continue
        count[kind] += 1
        mode = getattr(n.light, "appeal_shadow", SHADOW_MAP if flag_on[kind] else SHADOW_NONE)
        if mode == SHADOW_MAP and not flag_on[kind]:
            mode = SHADOW_NONE
        program.set_uniform(f"{kind}[{k}].appeal_shadow", float(mode))
        if mode == SHADOW_KEY:
            self._bind_texture(n.light.shadow_texture, "appeal_key_map", program)
            view, proj = self._get_light_cam_matrices(scene, n, flags)
            program.set_uniform("appeal_key_matrix", proj.dot(view))


pyrender.renderer.Renderer._bind_lighting = _bind_lighting_and_shadows
_update_context = pyrender.renderer.Renderer._update_context


def _update_context_and_key_shadow(self, scene, flags):  # type: ignore[no-untyped-def]
    """pyrender's context update, then the key light's shadow map (:mod:`.light_shadows`):
    ``render`` calls it right before its own shadow passes (which render only the maps of the
    light types whose flag is on; with the directional flag on they render the key's too) and
    the forward pass."""
    _update_context(self, scene, flags)
    if flags & (pyrender.RenderFlags.DEPTH_ONLY | pyrender.RenderFlags.SEG | pyrender.RenderFlags.SHADOWS_DIRECTIONAL):
        return
    for n in scene.light_nodes:
        if getattr(n.light, "appeal_shadow", None) == SHADOW_KEY and n.light.shadow_texture is not None:
            self._shadow_mapping_pass(scene, n, flags)


pyrender.renderer.Renderer._update_context = _update_context_and_key_shadow
# pyrender 0.1.45's getter returns ``self.glossinessFactor`` (infinite recursion)
pyrender.material.SpecularGlossinessMaterial.glossinessFactor = property(
    lambda self: self._glossinessFactor, pyrender.material.SpecularGlossinessMaterial.glossinessFactor.fset)


def platform() -> str:
    """The OpenGL platform pyrender renders with (``osmesa``, ``egl`` or ``pyglet``)."""
    return os.environ.get("PYOPENGL_PLATFORM", "osmesa")
