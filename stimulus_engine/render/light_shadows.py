"""Which lights cast shadows, and how: the key light's map, pyrender's maps, baked, or none.

pyrender turns shadows on per light *type* (``SHADOWS_DIRECTIONAL``, ``SHADOWS_SPOT``): every
directional light then renders a shadow map and every fragment filters it, rims and fill
included — four shadow lookups per pixel for ``direct_hard``, nine for ``direct_soft``, where
the preset asks for one light (or one disc of them) to cast a shadow. On the CPU (Mesa's
llvmpipe runs both sides of every branch, so a lookup costs every pixel of every part) that
made ``direct_hard`` 610 ms an image and ``direct_soft`` 1.3 s. Here each light carries
``appeal_shadow``:

:data:`SHADOW_NONE`
    No shadow (rims, fill, the dome of ``gi_soft``).
:data:`SHADOW_KEY`
    The scene's one hard shadow-casting directional light. Its map is rendered with pyrender's
    flags off (``_update_context_and_key_shadow`` in :mod:`._pyrender`) and bound outside
    pyrender's light structs (with a sampler and a matrix in every light struct, as pyrender's
    shadow defines have it, the shader ran 50 ms slower); it is looked up once per pixel,
    before the light loops, in programs compiled with ``KEY_SHADOW`` (:func:`key_shadow_defines`:
    in the loop every light of ``gi_soft``'s dome paid for it), with one bilinear tap of the
    receiver-plane lookup of :mod:`._pyrender` (``shadow_tap``): the 2048-texel map fitted to
    the head has texels of about 0.15 mm, a third of a pixel of a 1024 × 768 portrait, so a
    wider filter's penumbra would not show (inside the loop, 16 taps took 117 ms an image,
    4 taps 105 ms, one 88 ms; ICT head, ``skin``). At the terminator the shading's own falloff
    decides: the map would shadow the surface itself in a line as sharp as its one tap.
:data:`SHADOW_BAKED`
    The samples of a soft (disc) light: its visibility baked per vertex by ray casting
    (:mod:`.baked_shadows`) and read from the vertex colour's green channel by materials with
    the ``VISIBILITY_IN_COLOR0`` switch (a rig's parts, in every shading).
:data:`SHADOW_MAP`
    pyrender's own per-light map and the 16-tap filter (a soft light's samples on meshes that
    carry no baked visibility; lights made elsewhere, which keep pyrender's behaviour).

Materials with the ``OCCLUDED_LIGHTS`` switch (the inside of a mouth: socket, teeth, gums and
tongue) take every light times the vertex's baked ambient visibility (the vertex colour's red
channel): no light of ``gi_soft``'s dome casts a shadow, and without it the inside of an open
mouth was lit as brightly as the lips.

:func:`light_shadow_fragment_shader` patches ``mesh.frag``; :mod:`._pyrender` (where pyrender is
patched) sets the field of every bound light, binds the key light's map and renders it;
:func:`casts_shadow_map` tells the shadow passes which lights to skip.
"""

from __future__ import annotations

from typing import Any

__all__ = ["SHADOW_BAKED", "SHADOW_KEY", "SHADOW_MAP", "SHADOW_NONE", "casts_shadow_map", "key_shadow_defines",
           "light_shadow_fragment_shader"]

#: No shadow.
SHADOW_NONE = 0.0
#: pyrender's shadow map (its pass, its light structs) with the 16-tap lookup of :mod:`._pyrender`.
SHADOW_MAP = 1.0
#: The light's visibility baked per vertex, read from the vertex colour's green channel.
SHADOW_BAKED = 2.0
#: The key light's map, bound on its own and filtered with one bilinear tap.
SHADOW_KEY = 3.0

_BLOCK = """#ifdef {TYPE}_LIGHT_SHADOWS
        float nl = clamp(dot(n,l), 0.0, 1.0);
        float shadow = shadow_calc(
            {lights}[i].light_matrix,
            {lights}[i].shadow_map,
            nl
        );
        res = res * (1.0 - shadow);
#endif
"""
_SWITCHED = """        float shadow_kind = {lights}[i].appeal_shadow;
#ifdef {TYPE}_LIGHT_SHADOWS
        if (shadow_kind == 1.0) {{
        float nl = clamp(dot(n,l), 0.0, 1.0);
        float shadow = shadow_calc(
            {lights}[i].light_matrix,
            {lights}[i].shadow_map,
            nl
        );
        res = res * (1.0 - shadow);
        }}
#endif
#ifdef VISIBILITY_IN_COLOR0
#ifdef COLOR_0_LOC
        if (shadow_kind == 2.0) res *= color_multiplier.g;
#endif
#endif
#ifdef OCCLUDED_LIGHTS
#ifdef COLOR_0_LOC
        res *= color_multiplier.r;
#endif
#endif
{KEY}"""
_KEY = """#ifdef KEY_SHADOW
        if (shadow_kind == 3.0) {
            // at the terminator the map shadows the surface itself, in a line as sharp as its one
            // tap: let the shading's own falloff (and the skin's scattering past it) decide there
            res *= mix(1.0, key_lit, smoothstep(0.0, 0.2, dot(n, l)));
        }
#endif
"""
# once per pixel, before the light loops (inside them llvmpipe would run it for every light)
_KEY_LOOKUP = """#ifdef KEY_SHADOW
    ShadowLookup key = shadow_setup(appeal_key_matrix, appeal_key_map);
    float key_lit = 1.0 - shadow_tap(key, appeal_key_map);
#endif
"""
_LOOPS = "    // Loop over lights\n"
_UNIFORMS = "uniform sampler2D appeal_key_map;\nuniform mat4 appeal_key_matrix;\n"
_STRUCTS = {"DIRECTIONAL": ("struct DirectionalLight {\n", "directional_lights"),
            "SPOT": ("struct SpotLight {\n", "spot_lights")}


def light_shadow_fragment_shader(text: str) -> str:
    """pyrender 0.1.45's ``mesh.frag`` (with or without the Phong branch, whose light loops
    repeat the shadow blocks; after :func:`~._pyrender.shadow_fragment_shader`) with a
    per-light ``appeal_shadow`` switch (see the module)."""
    if text.count("ShadowLookup shadow_setup(") != 1 or text.count("float shadow_tap(") != 1:
        raise RuntimeError("the light-shadow patch needs the shadow lookup of _pyrender.shadow_fragment_shader")
    for kind, (struct, lights) in _STRUCTS.items():
        block = _BLOCK.format(TYPE=kind, lights=lights)
        if text.count(struct) != 1 or text.count(block) < 1:
            raise RuntimeError("pyrender's mesh.frag changed: the light-shadow patch was written for pyrender 0.1.45")
        text = text.replace(struct, struct + "    float appeal_shadow;\n")
        text = text.replace(block, _SWITCHED.format(TYPE=kind, lights=lights, KEY=_KEY if kind == "DIRECTIONAL" else ""))
    if text.count(_LOOPS) < 1:
        raise RuntimeError("pyrender's mesh.frag changed: the light-shadow patch was written for pyrender 0.1.45")
    text = text.replace(_LOOPS, _KEY_LOOKUP + _LOOPS)
    i = text.index(_STRUCTS["SPOT"][0])
    return text[:i] + _UNIFORMS + text[i:]


def casts_shadow_map(light: Any) -> bool:
    """Whether a shadow pass must render this light's map (pyrender's or the key light's)."""
    return getattr(light, "appeal_shadow", SHADOW_MAP) in (SHADOW_MAP, SHADOW_KEY)


def key_shadow_defines(scene: Any) -> dict | None:
    """The program defines a scene needs: ``KEY_SHADOW`` when one of its lights is the key."""
    if any(getattr(n.light, "appeal_shadow", None) == SHADOW_KEY for n in scene.light_nodes):
        return {"KEY_SHADOW": 1}
    return None
