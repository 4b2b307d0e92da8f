"""The ``skin`` shading of the fast tier: scattering-softened skin and a filmic tone curve in pyrender.

:func:`skin_fragment_shader` patches pyrender's metallic-roughness fragment shader with two
switches a material turns on through its ``appeal_defines`` (see
:mod:`stimulus_engine.render._pyrender`):

``SKIN_SCATTER`` (the skin part)
    Light scattered under the skin softens the terminator and reddens it (the look of
    pre-integrated skin shading, Penner & Borshukov 2011, without its curvature lookup): the
    diffuse term uses a per-channel *wrapped* cosine ``clamp((n·l + w) / (1 + w), 0, 1)`` with
    wraps :data:`SCATTER_WRAP` (red reaches furthest past the terminator, blue least); lit
    areas are unchanged, the specular lobe keeps the true cosine.
``VISIBILITY_IN_COLOR0`` (every part of a rig render, in any shading)
    The vertex colour carries baked visibility instead of a tint (pyrender multiplies the whole
    colour by it): its red channel the ambient visibility baked by
    :func:`~stimulus_engine.render.occlusion.vertex_occlusion`, its green channel a soft
    light's baked shadow (:mod:`.light_shadows`, :mod:`.baked_shadows`).
``OCCLUDED_AMBIENT`` (the ``skin`` shading)
    The ambient light is multiplied by that red channel; direct light keeps its shadows.
``EYE_GLINT`` (the eyeballs, ``pbr`` and ``skin`` shadings)
    The eye reflects the lights as one glint: each light gives only its diffuse term, and the
    lights on the camera's side are seen in the cornea as one window about their
    intensity-weighted mean direction, a small rectangle the larger the more they spread
    (:data:`GLINT_WIDTH`, :data:`GLINT_HEIGHT`; spread ``sqrt(1 − |Σ I l| / Σ I)``). A dome of a
    dozen lights (``gi_soft``) had put a ring of sharp dots around every pupil, and then one
    round spot a third of the iris wide, where a photograph shows a small window.
``HAIR_KAJIYA`` (hair, ``pbr`` and ``skin`` shadings; per-vertex tangents along the strands, and a
flat normal map, without which pyrender does not pass the tangents on)
    Kajiya-Kay hair shading as game engines draw hair cards (Scheuermann 2004): the diffuse term
    is the sine of the angle between strand and light, softened by the card's normal; the
    specular term two highlights about the strand direction tilted along the normal by
    :data:`HAIR_SHIFTS` (a white one, and one tinted by the hair's colour), each
    ``sin(t, h) ** exponent`` (:data:`HAIR_EXPONENTS`, :data:`HAIR_SPECULAR`): bands of sheen
    across the strands, where the isotropic lobe put round patches on the cards.
``TOON_CEL`` (every part of a ``toon`` render)
    Cel shading: the light a fragment receives, all lights and the ambient together (its colour
    over its albedo's, in luminance), is posterised in steps of :data:`TOON_STOPS` photographic
    stops, each band's edge a soft ramp :data:`TOON_EDGE` of a step wide, and the colour scaled
    to the band's light (hue kept). Posterising the sum rather than each light keeps two or three
    broad tones under a dome of a dozen lights (``gi_soft``), as an animated film paints a face:
    a lit side, a shadow side, a darker crease. Applied before the tone curve.
``TONEMAP_FILMIC`` (every part of a ``skin`` or ``toon`` render)
    The linear colour goes through the ACES filmic curve (Narkowicz 2015 fit, exposure
    :data:`EXPOSURE`) and the exact sRGB encoding instead of pyrender's clipped ``pow(1/2.2)``:
    highlights roll off instead of burning out.
"""

from __future__ import annotations

__all__ = ["SCATTER_WRAP", "EXPOSURE", "GLINT_WIDTH", "GLINT_HEIGHT", "GLINT_EDGE", "GLINT_LEVEL", "HAIR_EXPONENTS",
           "HAIR_SHIFTS", "HAIR_SPECULAR", "HUE_KEEP",
           "TOON_EDGE", "TOON_STOPS", "skin_fragment_shader"]

#: Per-channel wrap of the diffuse cosine (R, G, B): how far light reaches past the terminator.
SCATTER_WRAP = (0.45, 0.18, 0.10)

#: Exposure before the ACES curve (0.8 keeps an 18 % grey at about 18 % after the curve).
EXPOSURE = 0.8

#: Share of the tone curve applied to the luminance (keeping the hue) instead of each channel.
HUE_KEEP = 0.5

#: The eye's catch-light: the lights seen in the cornea as one window, a rectangle of half-width
#: and half-height (sines of the reflected angle) about their mean direction, each times
#: ``1 + spread`` (``spread``: the square root of ``1 - |sum I l| / sum I``), its edge softened over
#: GLINT_EDGE of its size, as bright as GLINT_LEVEL times the lights' summed radiance. On an eyeball
#: of 12 mm radius under ``gi_soft`` the window is about 1.5 x 1.1 mm: a photograph's catch-light
#: of a window or softbox, where a specular lobe widened by the dome's spread had drawn a round
#: spot a third of the iris wide.
GLINT_WIDTH = 0.11
GLINT_HEIGHT = 0.08
GLINT_EDGE = 0.6
GLINT_LEVEL = 2.0

#: Kajiya-Kay hair: the two highlights' strand tilt along the normal, exponents and strengths
#: (the first white, the second times the hair's colour). With the white one at 0.12 under
#: ``gi_soft``'s dome of lights, Lee Perry-Smith's dark brown (#2b2118) hair came out grey, mean
#: sRGB (71, 66, 63) and median luminance 66, where the dark hair of a London photograph (001_03)
#: has 46; at 0.06, (60, 54, 50) and 53 (without any highlight (37, 30, 25): flat).
HAIR_SHIFTS = (0.08, -0.12)
HAIR_EXPONENTS = (80.0, 16.0)
HAIR_SPECULAR = (0.06, 0.5)

#: Cel shading: the width of a band of light in photographic stops, and the share of a band its
#: soft edge takes.
TOON_STOPS = 1.0
TOON_EDGE = 0.12

_FUNCTIONS = """
vec3 compute_skin(vec3 n, vec3 v, vec3 l, float roughness, float metalness, vec3 f0, vec3 c_diff, vec3 albedo,
                  vec3 radiance)
{
        vec3 h = normalize(l+v);
        float nl_raw = dot(n, l);
        float nl = clamp(nl_raw, 0.001, 1.0);
        float nv = clamp(abs(dot(n, v)), 0.001, 1.0);
        float nh = clamp(dot(n, h), 0.0, 1.0);
        float lh = clamp(dot(l, h), 0.0, 1.0);
        float vh = clamp(dot(v, h), 0.0, 1.0);
        PBRInfo info = PBRInfo(nl, nv, nh, lh, vh, roughness, metalness, f0, c_diff);
        vec3 F = specular_reflection(info);
        float G = geometric_occlusion(info);
        float D = microfacet_distribution(info);
        vec3 wrap = vec3(SCATTER_WRAP);
        vec3 nl_wrapped = clamp((vec3(nl_raw) + wrap) / (vec3(1.0) + wrap), 0.0, 1.0);
        vec3 diffuse_contrib = (1.0 - F) * c_diff / PI;
        vec3 spec_contrib = F * G * D / (4.0 * nl * nv + 0.001);
        return radiance * (nl_wrapped * diffuse_contrib + step(0.0, nl_raw) * nl * spec_contrib);
}

vec3 compute_eye(vec3 n, vec3 v, vec3 l, float roughness, float metalness, vec3 f0, vec3 c_diff, vec3 albedo,
                 vec3 radiance)
{
        // the diffuse term only: the eye's glint is one lobe for all the lights (EYE_GLINT)
        vec3 h = normalize(l+v);
        float nl = clamp(dot(n, l), 0.001, 1.0);
        float nv = clamp(abs(dot(n, v)), 0.001, 1.0);
        PBRInfo info = PBRInfo(nl, nv, clamp(dot(n, h), 0.0, 1.0), clamp(dot(l, h), 0.0, 1.0),
                               clamp(dot(v, h), 0.0, 1.0), roughness, metalness, f0, c_diff);
        return nl * radiance * (1.0 - specular_reflection(info)) * c_diff / PI;
}

vec3 eye_glint(vec3 n, vec3 v, float roughness, vec3 f0)
{
        vec3 sum_l = vec3(0.0);
        vec3 sum_radiance = vec3(0.0);
        float sum_i = 0.0;
        for (int i = 0; i < n_directional_lights; i++) {
            vec3 l = normalize(-1.0 * directional_lights[i].direction);
            float w = step(0.0, dot(l, v)) * directional_lights[i].intensity;  // lights on the camera's side
            sum_l += w * l;
            sum_radiance += w * directional_lights[i].color;
            sum_i += w;
        }
        if (sum_i <= 0.0) {
            return vec3(0.0);
        }
        float len_l = length(sum_l);
        vec3 l = sum_l / max(len_l, 1e-6);
        float spread = sqrt(max(1.0 - len_l / sum_i, 0.0));
        // the lights seen in the cornea as one window: a rectangle about their mean direction,
        // wider the more they spread, its edges softened over GLINT_EDGE of its size
        vec3 r = reflect(-v, n);
        vec3 across = cross(vec3(0.0, 1.0, 0.0), l);
        across = length(across) > 1e-3 ? normalize(across) : vec3(1.0, 0.0, 0.0);
        vec3 up = cross(l, across);
        float half_w = GLINT_WIDTH * (1.0 + spread);
        float half_h = GLINT_HEIGHT * (1.0 + spread);
        float inside = step(0.0, dot(r, l))
            * (1.0 - smoothstep(half_w * (1.0 - GLINT_EDGE), half_w, abs(dot(r, across))))
            * (1.0 - smoothstep(half_h * (1.0 - GLINT_EDGE), half_h, abs(dot(r, up))));
        return step(0.0, dot(n, v)) * inside * GLINT_LEVEL * sum_radiance;
}

// the strand direction: the vertex tangent, which reaches the fragment shader only as the TBN
// frame of a normal-mapped material (hair carries a flat normal map for it); pyrender evaluates
// each #ifdef itself, so the three conditions are nested around the function
vec3 strand_direction(vec3 n)
{
        vec3 t = normalize(cross(n, vec3(1.0, 0.0, 0.0)) + vec3(1e-4));
#ifdef HAS_NORMAL_TEX
#ifdef TANGENT_LOC
#ifdef NORMAL_LOC
        t = tbn[0];
#endif
#endif
#endif
        return normalize(t - n * dot(n, t));
}

float strand_highlight(vec3 t, vec3 n, vec3 h, float shift, float exponent)
{
        vec3 ts = normalize(t + shift * n);
        float th = dot(ts, h);
        return pow(sqrt(max(1.0 - th * th, 0.0)), exponent);
}

vec3 compute_hair(vec3 n, vec3 v, vec3 l, float roughness, float metalness, vec3 f0, vec3 c_diff, vec3 albedo,
                  vec3 radiance)
{
        vec3 t = strand_direction(n);
        vec3 h = normalize(l + v);
        float tl = dot(t, l);
        float facing = clamp(0.5 + 0.5 * dot(n, l), 0.0, 1.0);  // cards are drawn from both sides
        vec3 diffuse = c_diff / PI * sqrt(max(1.0 - tl * tl, 0.0)) * facing;
        vec3 spec = HAIR_SPECULAR_1 * vec3(strand_highlight(t, n, h, HAIR_SHIFT_1, HAIR_EXPONENT_1))
                    + HAIR_SPECULAR_2 * albedo * strand_highlight(t, n, h, HAIR_SHIFT_2, HAIR_EXPONENT_2);
        return radiance * (diffuse + spec * facing);
}

vec3 aces_curve(vec3 x)
{
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

vec3 aces_filmic(vec3 x)
{
    // the curve on each channel saturates (skin turns orange); on the luminance it keeps the
    // hue: half of each
    x *= EXPOSURE;
    float y = max(dot(x, vec3(0.2126, 0.7152, 0.0722)), 1e-6);
    vec3 by_luminance = x * (aces_curve(vec3(y)).x / y);
    return clamp(mix(aces_curve(x), by_luminance, HUE_KEEP), 0.0, 1.0);
}

vec3 cel_bands(vec3 c, vec3 albedo)
{
    // the light on the fragment in stops, posterised: flat bands with soft edges
    vec3 lum = vec3(0.2126, 0.7152, 0.0722);
    float light = max(dot(c, lum), 1e-5) / max(dot(albedo, lum), 0.02);
    float x = log2(light) / TOON_STOPS;
    float k = floor(x);
    float band = k + smoothstep(0.5 - TOON_EDGE, 0.5 + TOON_EDGE, x - k);
    return c * (exp2(band * TOON_STOPS) / light);
}

vec3 linear_to_srgb(vec3 c)
{
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

#ifdef SKIN_SCATTER
#define SHADE compute_skin
#else
#ifdef EYE_GLINT
#define SHADE compute_eye
#else
#ifdef HAIR_KAJIYA
#define SHADE compute_hair
#else
#define SHADE compute_brdf
#endif
#endif
#endif

"""

_AMBIENT = "    color.xyz += base_color.xyz * ambient_light;\n"
# pyrender substitutes each define's value for its name, so ``defined(...)`` cannot be used: nested #ifdefs
_OCCLUDED_AMBIENT = """#ifdef OCCLUDED_AMBIENT
#ifdef COLOR_0_LOC
    color.xyz += base_color.xyz * ambient_light * color_multiplier.r;
#else
""" + _AMBIENT + """#endif
#else
""" + _AMBIENT + "#endif\n"
_MULTIPLY = "#ifdef COLOR_0_LOC\n    color *= color_multiplier;\n#endif\n"
_MULTIPLY_UNLESS_BAKED = "#ifdef COLOR_0_LOC\n#ifdef VISIBILITY_IN_COLOR0\n#else\n    color *= color_multiplier;\n#endif\n#endif\n"
_POINT_LOOP = "    for (int i = 0; i < n_point_lights; i++) {\n"
_GLINT = """#ifdef EYE_GLINT
    color.xyz += eye_glint(n, normalize(cam_pos - frag_position), roughness, f0);
#endif
""" + _POINT_LOOP
_OUTPUT = "    frag_color = clamp(vec4(pow(color.xyz, vec3(1.0/2.2)), color.a * base_color.a), 0.0, 1.0);\n"
_TONEMAPPED = """#ifdef TOON_CEL
    color.xyz = cel_bands(color.xyz, base_color.xyz);
#endif
#ifdef TONEMAP_FILMIC
    frag_color = vec4(linear_to_srgb(aces_filmic(color.xyz)), clamp(color.a * base_color.a, 0.0, 1.0));
#else
""" + _OUTPUT + "#endif\n"


def skin_fragment_shader(text: str) -> str:
    """pyrender 0.1.45's ``mesh.frag`` with the switches of the module docstring.

    Without either define the shader computes exactly what it did before (``SHADE`` is
    ``compute_brdf``, the output line is pyrender's).
    """
    call = "compute_brdf(n, v, l, roughness, metallic,"
    # after the Phong patch the output line appears again in the glossy branch: only the first
    # (metallic-roughness) one is switched
    if (text.count(call) != 3 or text.count(_OUTPUT) < 1 or text.count(_AMBIENT) < 1 or text.count(_MULTIPLY) < 1
            or text.count("float texture2DCompare(") != 1 or text.count(_POINT_LOOP) < 1):
        raise RuntimeError("pyrender's mesh.frag changed: the skin shader patch was written for pyrender 0.1.45")
    functions = (_FUNCTIONS.replace("SCATTER_WRAP", ", ".join(f"{w:.4f}" for w in SCATTER_WRAP))
                 .replace("EXPOSURE", f"{EXPOSURE:.4f}").replace("HUE_KEEP", f"{HUE_KEEP:.4f}")
                 .replace("GLINT_WIDTH", f"{GLINT_WIDTH:.4f}").replace("GLINT_HEIGHT", f"{GLINT_HEIGHT:.4f}")
                 .replace("GLINT_EDGE", f"{GLINT_EDGE:.4f}").replace("GLINT_LEVEL", f"{GLINT_LEVEL:.4f}")
                 .replace("TOON_STOPS", f"{TOON_STOPS:.4f}")
                 .replace("TOON_EDGE", f"{TOON_EDGE:.4f}"))
    for k in (0, 1):
        functions = (functions.replace(f"HAIR_SHIFT_{k + 1}", f"{HAIR_SHIFTS[k]:.4f}")
                     .replace(f"HAIR_EXPONENT_{k + 1}", f"{HAIR_EXPONENTS[k]:.4f}")
                     .replace(f"HAIR_SPECULAR_{k + 1}", f"{HAIR_SPECULAR[k]:.4f}"))
    i = text.index("float texture2DCompare(")
    text = text[:i] + functions + text[i:]
    return (text.replace(call, "SHADE(n, v, l, roughness, metallic,").replace(_OUTPUT, _TONEMAPPED, 1)
            .replace(_AMBIENT, _OCCLUDED_AMBIENT, 1).replace(_MULTIPLY, _MULTIPLY_UNLESS_BAKED)
            .replace(_POINT_LOOP, _GLINT, 1))
