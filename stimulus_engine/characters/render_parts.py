"""A character as pyrender render parts: the pyrender engine's side of materials.

:func:`rig_render_parts` splits a posed rig into parts (skin with its stylised albedo and
maps, eyes, teeth, mouth, lashes) with pyrender materials for a shading model of
:data:`SHADINGS`; :func:`hair_render_part` does the same for its hair. The textures and maps
themselves are arrays (:mod:`stimulus_engine.characters.skin_maps`, stylised by
:mod:`stimulus_engine.stylisation.materials`); another render engine translates the same arrays
its own way.

Shaders: ``pbr`` (metallic-roughness, pyrender's shader) and ``phong`` (specular-glossiness
with an energy-normalised Blinn-Phong BRDF: a sharper, brighter highlight; pyrender 0.1.45 has
no shader for it, see :func:`stimulus_engine.render._pyrender.phong_fragment_shader`). A
specular map ``s`` sets, with ``pbr``, the roughness ``r = r_skin · (1.4 − 0.8 s)`` (0.87 … 0.37
for skin; a metallic-roughness texture); with ``phong`` the specular level ``0.16 s`` and the
glossiness ``g_skin + 0.3 (s − 0.5)``.
"""

from __future__ import annotations

import numpy as np
import trimesh

from stimulus_engine.characters.rig import FaceRig
from stimulus_engine.parts.body import Body
from stimulus_engine.parts.hair import Hair
from stimulus_engine.parts.surround import Surround

__all__ = ["INSIDE_PARTS", "SHADINGS", "SKIN_LIKE", "body_render_parts", "hair_render_part", "surround_render_part", "rig_occlusion", "rig_render_parts"]

#: Shading models: ``pbr`` (metallic-roughness), ``phong`` (specular-glossiness, Blinn-Phong: the
#: thesis's contrast to PBR), ``skin`` (PBR with scattering-softened skin, wet eyes and a filmic
#: tone curve: :mod:`stimulus_engine.render.skin_shader`) and ``toon`` (``skin``'s eyes, hair and
#: tone curve, the light falling on every part in cel-shaded bands instead of the scattering:
#: the ``TOON_CEL`` switch of :mod:`~stimulus_engine.render.skin_shader`).
SHADINGS: tuple[str, ...] = ("pbr", "phong", "skin", "toon")
#: The shadings drawn with the ``skin`` shader's parts (occluded ambient, wet eyes, tone curve).
SKIN_LIKE: tuple[str, ...] = ("skin", "toon")

#: Colours of the untextured parts (linear RGB, alpha). ``mouth`` is the mouth socket (dark, it
#: is mostly in shadow inside a real mouth), ``tongue`` gums and tongue.
_PART_COLOURS = {
    "sclera": (0.85, 0.83, 0.80, 1.0), "iris": (0.18, 0.22, 0.30, 1.0), "teeth": (0.56, 0.50, 0.40, 1.0),
    "mouth": (0.05, 0.012, 0.015, 1.0), "socket": (0.09, 0.045, 0.04, 1.0), "tongue": (0.40, 0.12, 0.12, 1.0), "lashes": (0.05, 0.04, 0.04, 1.0),
    "skin": (0.8, 0.62, 0.52, 1.0), "eye": (0.9, 0.88, 0.85, 1.0),
    "margin": (0.36, 0.16, 0.14, 1.0),  # a scan's lid margins: wet line and caruncle, mucosa pink
}
#: The parts inside the mouth: every light reaches them only as far as their baked ambient
#: visibility lets it (the ``OCCLUDED_LIGHTS`` switch), in every shading, so an open mouth is a
#: dark cavity with shaded teeth. Teeth are ivory, not white (linear albedo about 0.5: enamel
#: over dentine), and the tongue a muted pink.
INSIDE_PARTS: tuple[str, ...] = ("mouth", "teeth", "tongue")
#: Specular level of the ``phong`` shader (Blinn-Phong without Fresnel: a skin-like sheen; the
#: 0.22 first chosen here made ICT faces look like wet plastic).
_PHONG_SPECULAR = 0.08
#: PBR roughness per part (wet eyes and teeth are glossy; the default is the skin's).
_PART_ROUGHNESS = {"eye": 0.12, "socket": 0.3, "margin": 0.3, "sclera": 0.25, "iris": 0.3, "teeth": 0.35, "tongue": 0.6, "mouth": 0.8,
                   "eye_shadow": 1.0}
#: Under ``skin`` shading the eyes are wet: a sharp highlight of the key light on the cornea.
_SKIN_SHADING_ROUGHNESS = {"eye": 0.07, "sclera": 0.08, "iris": 0.07, "teeth": 0.25}


_MATERIALS: dict[tuple, tuple[tuple, object]] = {}


def _material(shading: str, colour: tuple[float, ...], texture: np.ndarray | None, roughness: float = 0.62,
              normal: np.ndarray | None = None, specular: np.ndarray | None = None, scatter: bool = False,
              inside: bool = False, glint: bool = False) -> object:
    """A pyrender material; cached per (shading, colour, texture array, roughness, scatter) in this process.

    ``scatter``: under ``skin`` shading, the subsurface-softened diffuse term (the skin part).
    ``inside``: a part inside the mouth (:data:`INSIDE_PARTS`), lit through its ambient visibility.
    ``glint``: an eyeball, whose lights reflect as one glint (``EYE_GLINT`` of :mod:`.skin_shader`;
    metallic-roughness shadings only).

    Reusing the same material (and so the same ``pyrender.Texture``) for every image that wears
    the same albedo lets the renderer keep the texture on the GPU (pyrender uploads a texture,
    and builds its mipmaps, only when it first appears in a scene): the texture upload was most
    of the per-image time on llvmpipe. The key holds the array's id and the entry the array
    itself, so a new array that reuses a freed id never hits a stale material.
    """
    def make() -> object:
        mat = _inside(_new_material(shading, colour, texture, roughness, normal, specular, scatter), inside)
        if glint and shading in ("pbr", *SKIN_LIKE):
            mat.appeal_defines["EYE_GLINT"] = 1
        return mat

    return _cached(("part", shading, tuple(colour), float(roughness), scatter, inside, glint),
                   (texture, normal, specular), make)


def _inside(material: object, inside: bool) -> object:
    """``material`` with the ``OCCLUDED_LIGHTS`` (and occluded ambient) switches of a part inside the mouth."""
    if inside:
        material.appeal_defines.update({"OCCLUDED_LIGHTS": 1, "OCCLUDED_AMBIENT": 1})
    return material


def _cached(key: tuple, arrays: tuple, make, store: dict | None = None) -> object:
    """``make()``'s material (or texture), kept in ``store`` (default: the materials) per ``key``
    and the identity of ``arrays`` (see :func:`_material`)."""
    store = _MATERIALS if store is None else store
    key = key + tuple(None if a is None else id(a) for a in arrays)
    hit = store.get(key)
    if hit is not None and all(x is a for x, a in zip(hit[0], arrays)):
        return hit[1]
    made = make()
    if len(store) > 32:
        store.clear()
    store[key] = (arrays, made)
    return made


def _shader_defines(material: object, shading: str, scatter: bool) -> object:
    """Turn on this material's shader switches (:mod:`.skin_shader`): baked visibility in the
    vertex colour for every shading (a soft light's shadow is baked per vertex,
    :mod:`.baked_shadows`), and the ``skin`` shading's occluded ambient light, scattering and
    tone curve."""
    material.appeal_defines = {"VISIBILITY_IN_COLOR0": 1}
    if shading in SKIN_LIKE:
        material.appeal_defines.update({"TONEMAP_FILMIC": 1, "OCCLUDED_AMBIENT": 1})
    if shading in SKIN_LIKE and scatter:  # toon: the scattering's warmth, then the bands
        material.appeal_defines["SKIN_SCATTER"] = 1
    if shading == "toon":
        material.appeal_defines["TOON_CEL"] = 1
    return material


def _new_material(shading: str, colour: tuple[float, ...], texture: np.ndarray | None, roughness: float,
                  normal: np.ndarray | None = None, specular: np.ndarray | None = None, scatter: bool = False) -> object:
    from stimulus_engine.render._pyrender import pyrender

    def tex(a: np.ndarray | None, channels: str = "RGB") -> object:
        return None if a is None else pyrender.Texture(source=np.ascontiguousarray(a), source_channels=channels)

    base = (1.0, 1.0, 1.0, 1.0) if texture is not None else colour
    if texture is not None and texture.shape[-1] == 4:  # cards (lashes): alpha-blended, both sides
        return _shader_defines(pyrender.MetallicRoughnessMaterial(
            baseColorFactor=base, baseColorTexture=tex(texture, "RGBA"), metallicFactor=0.0, roughnessFactor=roughness,
            alphaMode="BLEND", doubleSided=True), shading, scatter=False)
    s = None if specular is None else np.asarray(specular, np.float64) / 255.0
    if shading in ("pbr", *SKIN_LIKE):
        mr = None
        if s is not None:  # pyrender reads roughness from R and metallic from G (× the factors)
            r = np.rint(255 * np.clip(roughness * (1.4 - 0.8 * s), 0, 1))
            mr = np.stack([r, np.full_like(r, 255), np.zeros_like(r)], axis=-1).astype(np.uint8)
        return _shader_defines(pyrender.MetallicRoughnessMaterial(
            baseColorFactor=base, baseColorTexture=tex(texture), metallicFactor=0.0,
            roughnessFactor=1.0 if s is not None else roughness, normalTexture=tex(normal),
            metallicRoughnessTexture=tex(mr)), shading, scatter)
    if shading == "phong":
        gloss = min(0.95, 1.17 - roughness)
        sg, level = None, _PHONG_SPECULAR
        if s is not None:  # specular level 2 s × the default, glossiness g_skin ± 0.15 (mid-grey = no map)
            level = 2 * _PHONG_SPECULAR
            a = np.clip(gloss + 0.3 * (s - 0.5), 0, 1)
            sg = np.rint(255 * np.stack([s] * 3 + [a], axis=-1)).astype(np.uint8)
            gloss = 1.0
        return _shader_defines(pyrender.material.SpecularGlossinessMaterial(
            diffuseFactor=base, diffuseTexture=tex(texture), specularFactor=(level,) * 3, glossinessFactor=gloss,
            normalTexture=tex(normal), specularGlossinessTexture=tex(sg, "RGBA")), shading, scatter=False)
    raise ValueError(f"unknown shading '{shading}' (expected one of: {', '.join(SHADINGS)})")


_SPLITS: dict[tuple, tuple[object, list]] = {}


def _split_parts(rig: FaceRig, textured_skin: bool) -> list:
    """Per part: (name, (vertex, uv) index pairs, triangles, textured); cached per rig topology."""
    key = (id(rig.faces), id(rig.face_part), textured_skin, tuple(sorted(rig.part_textures)))
    hit = _SPLITS.get(key)
    if hit is not None and hit[0][0] is rig.faces and hit[0][1] is rig.face_part:
        return hit[1]
    out = []
    for k, name in enumerate(rig.part_names):
        sel = rig.face_part == k
        if name == "hidden" or not sel.any():
            continue
        f = rig.faces[sel]
        textured = (name == "skin" and textured_skin) or (name in rig.part_textures and rig.face_uv is not None)
        second = rig.face_uv[sel].ravel() if textured else np.zeros(f.size, np.int64)
        uniq, inv = np.unique(np.stack([f.ravel(), second], axis=1), axis=0, return_inverse=True)
        out.append((name, uniq, inv.reshape(-1, 3), textured))
    if len(_SPLITS) > 16:
        _SPLITS.clear()
    _SPLITS[key] = ((rig.faces, rig.face_part), out)
    return out


def rig_render_parts(rig: FaceRig, vertices: np.ndarray, albedo: np.ndarray | None, *,
                     shading: str = "pbr", normal_map: np.ndarray | None = None,
                     specular_map: np.ndarray | None = None, occlusion: np.ndarray | None = None,
                     surround_image: np.ndarray | None = None) -> list:
    """Render parts (skin with texture, eyes, teeth, mouth, lashes) for ``vertices`` of ``rig``.

    Skin vertices are split where the UV layout has seams (normals are computed on the welded
    mesh first, so the shading stays smooth across seams). Parts named ``hidden`` are left out.

    Parameters
    ----------
    rig : FaceRig
    vertices : (N, 3) array
        The shape to draw (expression and stylisation applied).
    albedo : (H, W, 3) uint8 array or None
        Skin texture (None = plain skin colour).
    shading : {"pbr", "phong"}
    normal_map : (H, W, 3) uint8 array, optional
        Tangent-space normal map of the skin (see :func:`check_map`).
    specular_map : (H, W) uint8 array, optional
        Specularity of the skin, white = shiny.
    occlusion : (N,) array, optional
        Ambient visibility per rig vertex (:func:`rig_occlusion`), used by ``skin`` shading for
        its ambient light, and in every shading for the parts inside the mouth (:data:`INSIDE_PARTS`).
    surround_image : (H, W, 3) uint8 array, optional
        The image drawn on the rig's surround (default its own photograph; a stylised copy at
        painted levels).
    """
    from stimulus_engine.render.renderer import RenderPart

    v = np.asarray(vertices, np.float64)
    maps = normal_map is not None or specular_map is not None
    if (albedo is not None or maps) and (rig.uv is None or rig.face_uv is None):
        raise ValueError(f"rig '{rig.name}' has no UVs but a texture was asked for")
    normals = trimesh.Trimesh(v, rig.faces, process=False).vertex_normals
    parts = []
    balls = None  # the eyeballs' spheres, fitted once for the eyes and their shadow
    for name, uniq, tri, textured in _split_parts(rig, albedo is not None or maps):
        if name in ("eye", "eye_shadow") and balls is None:
            balls = _eyeballs(rig, v)
        if name == "eye_shadow":  # laid on the eyeballs: seen where the lids open, under their skin elsewhere
            pos, out = _onto_eyeballs(v[uniq[:, 0]], *balls)
            mesh = trimesh.Trimesh(pos, tri, vertex_normals=out, process=False)
        elif name == "eye":  # shaded as the round ball the cornea makes it: the glint is a dot (an
            # ICT iris is a cone sunk into the ball, and reflected the lights as a ring round the pupil)
            mesh = trimesh.Trimesh(v[uniq[:, 0]], tri, vertex_normals=_radial(v[uniq[:, 0]], balls[0])[1], process=False)
        else:
            mesh = trimesh.Trimesh(v[uniq[:, 0]], tri, vertex_normals=normals[uniq[:, 0]], process=False)
        if textured:
            mesh.visual = trimesh.visual.TextureVisuals(uv=rig.uv[uniq[:, 1]])
        tex = (albedo if name == "skin" else rig.part_textures[name]) if textured else None
        skin = name == "skin" and textured
        rough = _SKIN_SHADING_ROUGHNESS.get(name) if shading in SKIN_LIKE else None
        rough = _PART_ROUGHNESS.get(name, 0.62) if rough is None else rough
        if name == "eye_shadow" and tex is None:
            continue  # without its texture the shell would cover the eye
        if name == "tear":
            mat = _tear_material(shading)
        else:  # the eye's shadow is an alpha-blended card on its RGBA texture, as the lashes are
            mat = _material(shading, _PART_COLOURS.get(name, (0.7, 0.7, 0.7, 1.0)), tex, rough,
                            normal_map if skin else None, specular_map if skin else None, scatter=name == "skin",
                            inside=name in INSIDE_PARTS and occlusion is not None, glint=name == "eye")
        occ = None if occlusion is None else np.asarray(occlusion)[uniq[:, 0]]
        parts.append(RenderPart(mesh, material=mat, smooth=True, name=name, occlusion=occ))
    if rig.body is not None:
        parts += body_render_parts(rig.body, v, albedo, shading=shading, normal_map=normal_map, specular_map=specular_map)
    if rig.hair is not None:
        parts.append(hair_render_part(rig.hair, v, shading))
    if rig.surround is not None:
        parts.append(surround_render_part(rig.surround, surround_image))
    return parts


def surround_render_part(surround: Surround, image: np.ndarray | None = None) -> object:
    """A photograph's head and shoulders (:mod:`stimulus_engine.parts.surround`) as an unlit
    plane: its colour is the photograph's (``image``: a stylised copy of it), whatever the
    lights and the shading."""
    from stimulus_engine.parts.surround import surround_mesh
    from stimulus_engine.render._pyrender import pyrender
    from stimulus_engine.render.renderer import RenderPart

    v, f, uv = surround_mesh(surround)
    mesh = trimesh.Trimesh(v, f, process=False)
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv)
    img = np.ascontiguousarray(surround.image if image is None else image)

    def make() -> object:  # RGBA: OpenGL reads rows in 4-byte steps, and an RGB row of odd width is skewed
        rgba = np.concatenate([img[..., :3], np.full((*img.shape[:2], 1), 255, np.uint8)], axis=2)
        return pyrender.MetallicRoughnessMaterial(
            baseColorFactor=(0.0, 0.0, 0.0, 1.0), metallicFactor=0.0, roughnessFactor=1.0,
            emissiveFactor=(1.0, 1.0, 1.0), emissiveTexture=pyrender.Texture(source=rgba, source_channels="RGBA"))

    mat = _cached(("surround",), (img,), make, _TEXTURES)
    return RenderPart(mesh, material=mat, smooth=True, name="surround")


#: The lids' wet line (the rig's lacrimal fluid): a clear film, nearly colourless, that shows only
#: the highlights of the lights on its wet surface.
TEAR_COLOUR, TEAR_ROUGHNESS = (0.85, 0.8, 0.8, 0.18), 0.04


def _tear_material(shading: str) -> object:
    """The wet line's material: alpha-blended, glossy, both sides (one per shading)."""
    from stimulus_engine.render._pyrender import pyrender

    return _cached(("tear", shading), (), lambda: _shader_defines(pyrender.MetallicRoughnessMaterial(
        baseColorFactor=TEAR_COLOUR, metallicFactor=0.0, roughnessFactor=TEAR_ROUGHNESS, alphaMode="BLEND",
        doubleSided=True), shading, scatter=False))


#: The eye's shadow layer lies this much outside the eyeball (a fraction of its radius: 0.24 mm on
#: a 12 mm ball), so the lids' skin, in front of the ball, covers all of it but the eye's opening.
EYE_SHADOW_LIFT = 0.02


def _eyeballs(rig: FaceRig, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres (2, 3) and radii (2,) of the spheres fitted to the rig's drawn eyeballs at ``vertices``."""
    from stimulus_engine.parts.eyes import fit_sphere

    drawn = np.unique(rig.faces[rig.face_part == rig.part_names.index("eye")])
    side = vertices[drawn, 0] > vertices[drawn, 0].mean()  # the two balls lie either side of the face's middle
    spheres = [fit_sphere(vertices[drawn[side == s]]) for s in (False, True) if (side == s).sum() >= 4]
    return np.array([c for c, _ in spheres]), np.array([r for _, r in spheres])


def _radial(points: np.ndarray, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the nearest of ``centres`` for each point, and the unit direction from it."""
    k = np.argmin(np.linalg.norm(points[:, None, :] - centres[None], axis=2), axis=1)
    out = points - centres[k]
    return k, out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)


def _onto_eyeballs(points: np.ndarray, centres: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``points`` moved radially onto the nearer eyeball's sphere (:func:`_eyeballs`),
    :data:`EYE_SHADOW_LIFT` outside it, and their outward unit normals.

    A rig's eye-occlusion shell, fitted to one head, pokes out in front of another's lids (a dark
    arc on the lid's skin); on the ball it shows only through the opening the lids leave."""
    k, out = _radial(points, centres)
    return centres[k] + out * (radii[k] * (1 + EYE_SHADOW_LIFT))[:, None], out


#: Roughness of the garment (matte knit).
GARMENT_ROUGHNESS = 0.9
#: Textures made per albedo or colour (the neck's, the garment's), kept like the materials.
_TEXTURES: dict[tuple, tuple[tuple, np.ndarray]] = {}


def _garment_texture(body: Body) -> np.ndarray:
    """The body's grey knit times its colour, as an sRGB texture (one array per knit and colour)."""
    def make() -> np.ndarray:
        lin = (np.asarray(body.texture, np.float64) / 255.0) ** 2.2
        rgb = (lin[..., None] * np.asarray(body.colour)) ** (1 / 2.2)
        return np.rint(255 * np.clip(rgb, 0, 1)).astype(np.uint8)

    return _cached(("garment", tuple(body.colour)), (body.texture,), make, _TEXTURES)


def body_render_parts(body: Body, vertices: np.ndarray, albedo: np.ndarray | None, *, shading: str = "pbr",
                      normal_map: np.ndarray | None = None, specular_map: np.ndarray | None = None) -> list:
    """The bust under the head (:mod:`stimulus_engine.parts.body`), posed on ``vertices``: the
    neck (``neck``) in the colour of the skin above it (from ``albedo``), the garment
    (``garment``) in its knit."""
    from stimulus_engine.characters.neck_skin import neck_texture
    from stimulus_engine.render.renderer import RenderPart

    bv = body.pose(vertices)
    normals = trimesh.Trimesh(bv, body.faces, process=False).vertex_normals
    parts = []
    for k, name in enumerate(("neck", "garment")):
        f = body.faces[body.face_part == k]
        if not len(f):
            continue
        used, tri = np.unique(f, return_inverse=True)
        mesh = trimesh.Trimesh(bv[used], tri.reshape(-1, 3), vertex_normals=normals[used], process=False)
        if name == "neck":
            tex = None if albedo is None else _cached(("neck",), (body.ring_uv, albedo),
                                                      lambda: neck_texture(body, albedo), _TEXTURES)
            if tex is not None:
                mesh.visual = trimesh.visual.TextureVisuals(uv=body.neck_uv[used])
            mat = _material(shading, _PART_COLOURS["skin"], tex, _PART_ROUGHNESS.get("skin", 0.62), scatter=True)
        else:
            mesh.visual = trimesh.visual.TextureVisuals(uv=body.uv[used])
            mat = _material(shading, (1.0, 1.0, 1.0, 1.0), _garment_texture(body), GARMENT_ROUGHNESS)
            # both sides: through the collar's opening beside a narrow neck one sees the inside
            # of the garment's back, not the background behind it
            mat.doubleSided = True
        parts.append(RenderPart(mesh, material=mat, smooth=True, name=name))
    return parts


#: Roughness of hair (a soft sheen: the cards have no strand-level normals, and a sharper highlight
#: showed the mesh's facets as grey patches).
HAIR_ROUGHNESS = 0.8


def hair_render_part(hair: Hair, vertices: np.ndarray, shading: str = "pbr") -> object:
    """The rig's hair (:mod:`stimulus_engine.parts.hair`), posed on ``vertices``, as alpha-blended
    double-sided cards (the renderer draws a blended part's triangles back to front); its grey
    strand texture, its strands' edges softened (:data:`HAIR_ALPHA_SOFTEN`), is multiplied by the
    hair colour."""
    from stimulus_engine.render.renderer import RenderPart

    from stimulus_engine.render.hair_strands import strand_tangents

    mesh = trimesh.Trimesh(hair.pose(vertices), hair.faces, process=False)
    mesh.visual = trimesh.visual.TextureVisuals(uv=hair.uv)
    return RenderPart(mesh, material=_hair_material(shading, hair.colour, hair.texture, hair.massed), smooth=True,
                      name="hair", tangents=strand_tangents(mesh.vertices, mesh.faces))


def _hair_material(shading: str, colour: tuple[float, float, float], texture: np.ndarray, massed: bool = False) -> object:
    """A cached material per (shading, colour, texture) for the hair (see :func:`_material`);
    ``massed`` hair's carries the ``HAIR_MASS`` mark (no strand curves in the path tracer)."""
    def make() -> object:
        mat = _new_hair_material(shading, colour, texture)
        if massed:
            mat.appeal_defines["HAIR_MASS"] = 1  # read by the scene export only; no shader switch
        return mat

    return _cached(("hair", shading, tuple(colour), massed), (texture,), make)


#: The hair texture's strands (alpha 0 or 1) are softened by a Gaussian of this many texels and
#: the result scaled by :data:`HAIR_ALPHA_GAIN` (clipped at 1), so that blended, their edges and
#: tips fade over a texel or so instead of stepping (the fringe's staircase) while a strand's core
#: stays opaque (blurred alone, single-texel strands let the scalp show through at 40 %).
HAIR_ALPHA_SOFTEN, HAIR_ALPHA_GAIN = 0.8, 2.0


def _soft_alpha(texture: np.ndarray) -> np.ndarray:
    """``texture`` (RGBA) with its strands' alpha softened (:data:`HAIR_ALPHA_SOFTEN`)."""
    from scipy.ndimage import gaussian_filter

    out = np.array(texture, np.uint8, copy=True)
    soft = gaussian_filter(out[..., 3].astype(np.float64), HAIR_ALPHA_SOFTEN, mode="wrap") * HAIR_ALPHA_GAIN
    out[..., 3] = np.rint(np.clip(soft, 0, 255))
    return out


def _new_hair_material(shading: str, colour: tuple[float, float, float], texture: np.ndarray) -> object:
    from stimulus_engine.render._pyrender import pyrender

    tex = pyrender.Texture(source=np.ascontiguousarray(_soft_alpha(texture)), source_channels="RGBA")
    if shading == "phong":
        mat = pyrender.material.SpecularGlossinessMaterial(
            diffuseFactor=(*colour, 1.0), diffuseTexture=tex, specularFactor=(_PHONG_SPECULAR,) * 3,
            glossinessFactor=1.17 - HAIR_ROUGHNESS, alphaMode="BLEND", doubleSided=True)
    else:  # a flat normal map: pyrender hands the strand tangents to the shader only with one
        flat = pyrender.Texture(source=np.full((4, 4, 3), (128, 128, 255), np.uint8), source_channels="RGB")
        mat = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=(*colour, 1.0), baseColorTexture=tex, metallicFactor=0.0, roughnessFactor=HAIR_ROUGHNESS,
            alphaMode="BLEND", doubleSided=True, normalTexture=flat)
    mat = _shader_defines(mat, shading, scatter=False)
    if shading in ("pbr", *SKIN_LIKE):
        mat.appeal_defines["HAIR_KAJIYA"] = 1  # strand highlights along the tangents (render.skin_shader)
    return mat


def rig_occlusion(rig: FaceRig, vertices: np.ndarray, rays: int = 32, *, inside_only: bool = False,
                  floors: tuple[float, float] | None = None) -> np.ndarray:
    """Ambient visibility ``(N,)`` of every vertex of ``rig`` at ``vertices``, the whole head
    (every part, hidden ones too: the inside of the mouth) occluding (:mod:`.occlusion`).

    The parts inside the mouth (:data:`INSIDE_PARTS`) get their visibility of the front instead:
    the share of directions within :data:`FRONT_CONE_DEG` of +z (towards the camera, where the
    lighting presets' key and dome lights stand) that leave the mouth unblocked, among those
    their surface faces. The whole hemisphere's visibility (about 0.1 behind parted lips) made
    teeth seen through the opening, and lit through it, dark grey. Inside parts see at least
    ``floors`` (the mouth's and the teeth's; default :data:`INSIDE_FLOOR`, :data:`TEETH_FLOOR`):
    the light bounced in. With ``inside_only`` the rest is left at 1 (what shadings other than
    ``skin`` need: a third of the time).
    """
    from stimulus_engine.render.occlusion import cone_directions, light_visibility, vertex_occlusion

    v = np.asarray(vertices, np.float64)
    normals = trimesh.Trimesh(v, rig.faces, process=False).vertex_normals
    out = np.ones(len(v), np.float32) if inside_only else vertex_occlusion(v, rig.faces, normals, rays=rays)
    inside = [rig.part_names.index(p) for p in INSIDE_PARTS if p in rig.part_names]
    idx = np.unique(rig.faces[np.isin(rig.face_part, inside)]) if inside else np.zeros(0, np.int64)
    if len(idx):
        dirs = cone_directions(np.array([0.0, 0.0, 1.0]), np.radians(FRONT_CONE_DEG), 24)
        seen = light_visibility(v[idx], normals[idx], (v, rig.faces), dirs)  # unblocked and facing, of all
        facing = (normals[idx] @ dirs.T > 0).mean(axis=1)
        direct = np.where(facing > 0, seen / np.maximum(facing, 1e-9), 0.0)
        inside_floor, teeth_floor = (INSIDE_FLOOR, TEETH_FLOOR) if floors is None else floors
        out[idx] = np.maximum(direct, inside_floor).astype(np.float32)
        if "teeth" in rig.part_names:  # enamel carries light in from the lit front teeth
            teeth = np.unique(rig.faces[rig.face_part == rig.part_names.index("teeth")])
            out[teeth] = np.maximum(out[teeth], teeth_floor)
    return out


#: The least visibility of anything inside the mouth, and of a tooth: the light that reaches them
#: after bouncing off teeth, lips and cheeks, which the cone's direct visibility leaves out. Set so
#: that pyrender agrees with the path tracer on the same scenes (Exp. 2's surprise, gi_soft,
#: pbr; mean sRGB of each part's visible pixels): with 0 and 0.4 the tongue came out (6, 4, 4) for
#: Lee Perry-Smith and (49, 29, 29) for james where Cycles, with its four diffuse bounces, gives
#: (120, 68, 65) and (125, 69, 66) -- a black hole in every open mouth -- and the teeth (112, 105,
#: 95) against (142, 122, 110); with 0.55 and 0.7, (107, 64, 64), (108, 64, 64) and (143, 134, 121).
#: Enamel and dentine also carry light along each tooth (through barely parted lips, teeth lit only
#: through the gap came out black, like holes).
INSIDE_FLOOR, TEETH_FLOOR = 0.55, 0.7


#: Half-angle of the cone of directions, about the view axis, whose visibility lights the inside
#: of the mouth (``gi_soft``'s dome reaches 69° from the front).
FRONT_CONE_DEG = 60.0
