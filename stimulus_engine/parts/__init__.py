"""The parts a character wears, each fitted to any head: eyeballs, eyelashes and hair (the
teeth, tongue and clothes to come). Imports only ``geometry`` and the shipped ``data``.

Public API
----------
eyeball_asset, eyeball_uv, eye_texture, photographic_eye_texture, tint_iris, fit_sphere
    Eyeballs: MakeHuman's photographic CC0 eyeball, or a procedural iris, on any sphere
    (module ``eyes``).
lash_strip, lash_texture
    Eyelashes as a textured strip along a lid contour (module ``eyelashes``).
Hair, fit_hair, hair_asset, HAIR_STYLES
    Card hair fitted to a head by its landmarks (module ``hair``; MakeHuman's CC0 ``short02``).
"""

from stimulus_engine.parts.eyelashes import lash_strip, lash_texture
from stimulus_engine.parts.eyes import (
    eye_texture,
    eyeball_asset,
    eyeball_uv,
    fit_sphere,
    photographic_eye_texture,
    tint_iris,
)
from stimulus_engine.parts.hair import HAIR_STYLES, Hair, fit_hair, hair_asset

__all__ = [
    "HAIR_STYLES",
    "Hair",
    "eye_texture",
    "eyeball_asset",
    "eyeball_uv",
    "fit_hair",
    "fit_sphere",
    "hair_asset",
    "lash_strip",
    "lash_texture",
    "photographic_eye_texture",
    "tint_iris",
]
