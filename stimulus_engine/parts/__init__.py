"""The parts a character wears, each fitted to any head: eyeballs, eyelashes, hair, and a
neck with shoulders in a garment. Imports only ``geometry`` and the shipped ``data``.

Public API
----------
eyeball_asset, eyeball_uv, eye_texture, photographic_eye_texture, tint_iris, fit_sphere
    Eyeballs: MakeHuman's photographic CC0 eyeball, or a procedural iris, on any sphere
    (module ``eyes``).
lash_strip, lash_texture
    Eyelashes as a textured strip along a lid contour (module ``eyelashes``).
Hair, fit_hair, hair_asset, HAIR_STYLES
    Card hair fitted to a head by its landmarks (module ``hair``; MakeHuman's CC0 ``short02``).
Body, fit_body, bust_asset, under_garment
    A neck, shoulders and a crew-neck garment joined under any head's neck (module ``body``;
    MakeHuman's CC0 base mesh).
Surround, surround_view
    A photograph's head and shoulders on a plane behind a character made from it (module
    ``surround``).
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["body", "eyelashes", "eyes", "hair", "stored", "surround"],
    submod_attrs={
        "body": ["Body", "bust_asset", "fit_body", "under_garment"],
        "eyelashes": ["lash_strip", "lash_texture"],
        "eyes": ["eye_texture", "eyeball_asset", "eyeball_uv", "fit_sphere", "photographic_eye_texture", "tint_iris"],
        "hair": ["HAIR_STYLES", "Hair", "fit_hair", "hair_asset"],
        "surround": ["Surround", "surround_view"],
    },
)

__all__ = [
    "HAIR_STYLES",
    "Body",
    "Hair",
    "Surround",
    "bust_asset",
    "eye_texture",
    "eyeball_asset",
    "eyeball_uv",
    "fit_body",
    "fit_hair",
    "fit_sphere",
    "hair_asset",
    "lash_strip",
    "lash_texture",
    "photographic_eye_texture",
    "surround_view",
    "tint_iris",
    "under_garment",
]
