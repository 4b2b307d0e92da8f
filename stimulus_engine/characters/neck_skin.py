"""The skin of the bust's neck: its colour with a photograph's grain where the face has one.

The bust (:mod:`stimulus_engine.parts.body`) takes its neck's colour from the skin just above the
character's lower border, one colour per angle around the neck. Drawn as it is, that colour is
flat: below james's stubble in the whole-head ERP framing his neck read as painted plastic.
:func:`neck_texture` multiplies it by the skin-detail mottle
(:func:`~stimulus_engine.characters.skin_detail.skin_mottle`, :func:`neck_mottle`) as strong as
the fine detail of the albedo's skin where the colour is taken (:func:`ring_detail`): a
photograph's neck gets a photograph's grain, a painted level's flat paint a flat neck.
"""

from __future__ import annotations

import functools

import numpy as np

from stimulus_engine.parts.body import NECK_SPAN_IOD, NECK_TEXTURE_SIZE, Body, texel_index

__all__ = ["NECK_MOTTLE_FINEST", "RING_DETAIL_SIGMA", "neck_mottle", "neck_texture", "ring_detail"]

#: The neck's mottle leaves out octaves finer than this (iod): at a texel to a cell, the finest
#: (0.4 mm) aliased into a diagonal lattice drawn as streaks along the neck, and it lies under a
#: pixel of any stimulus (eyes 150 px apart: 0.4 mm a pixel).
NECK_MOTTLE_FINEST = 1.0 / 100.0
#: The finest detail of the albedo's skin above the ring is the high-pass of its log luminance over
#: this blur (texels); the neck's mottle is as strong, up to
#: :data:`~stimulus_engine.characters.skin_detail.DETAIL_TARGET`.
RING_DETAIL_SIGMA = 2.0


@functools.lru_cache(maxsize=1)
def neck_mottle() -> np.ndarray:
    """(:data:`~stimulus_engine.parts.body.NECK_TEXTURE_SIZE`) array: the skin mottle (its octaves
    from :data:`NECK_MOTTLE_FINEST` up) on a plane :data:`~stimulus_engine.parts.body.NECK_SPAN_IOD`
    square (the neck texture's texels), less its blur over
    :data:`~stimulus_engine.characters.skin_detail.DETAIL_SCALE`, scaled to unit RMS: the same for
    every neck (read-only)."""
    from stimulus_engine.characters.skin_detail import DETAIL_SCALE, _high_pass, skin_mottle

    rows, cols = NECK_TEXTURE_SIZE
    x = (np.arange(cols) + 0.5) / cols * NECK_SPAN_IOD
    y = -(np.arange(rows) + 0.5) / rows * NECK_SPAN_IOD
    pts = np.stack(np.broadcast_arrays(x[None], y[:, None], np.zeros(1)[None]), axis=-1)
    field = skin_mottle(pts.reshape(-1, 3), 1.0, finest=NECK_MOTTLE_FINEST).reshape(rows, cols)
    field = _high_pass(field, np.ones_like(field), DETAIL_SCALE / (NECK_SPAN_IOD / rows))
    field /= float(np.sqrt(np.mean(field ** 2)))
    field.setflags(write=False)
    return field


def ring_detail(albedo: np.ndarray, ring_uv: np.ndarray) -> float:
    """How much fine detail ``albedo``'s skin has where the neck takes its colour (``ring_uv``,
    OBJ convention): the RMS of its log luminance less its blur over :data:`RING_DETAIL_SIGMA`
    texels at those texels, at most :data:`~stimulus_engine.characters.skin_detail.DETAIL_TARGET`
    (0 without any)."""
    from stimulus_engine.characters.skin_detail import DETAIL_TARGET, _log_luminance

    if not len(ring_uv):
        return 0.0
    img = np.asarray(albedo)[..., :3]
    h, w = img.shape[:2]
    row, col = texel_index(img.shape, ring_uv)
    r = int(np.ceil(4 * RING_DETAIL_SIGMA))
    d = np.arange(-r, r + 1)
    kernel = np.exp(-(d[:, None] ** 2 + d[None] ** 2) / (2 * RING_DETAIL_SIGMA ** 2))
    # each ring texel's window only (the whole of a 4096-texel albedo took 5 s)
    window = img[np.clip(row[:, None, None] + d[None, :, None], 0, h - 1),
                 np.clip(col[:, None, None] + d[None, None, :], 0, w - 1)]
    lum = _log_luminance(window)
    hp = lum[:, r, r] - (lum * kernel).sum(axis=(1, 2)) / kernel.sum()
    return float(min(np.sqrt(np.mean(hp ** 2)), DETAIL_TARGET))


def neck_texture(body: Body, albedo: np.ndarray) -> np.ndarray:
    """(:data:`~stimulus_engine.parts.body.NECK_TEXTURE_SIZE`, 3) uint8: ``body``'s neck skin for
    a character wearing ``albedo``: its colour from the front
    (:meth:`~stimulus_engine.parts.body.Body.front_colours`) times ``exp`` of :func:`neck_mottle`
    scaled to :func:`ring_detail`, in linear light."""
    from stimulus_engine.faces2d.composite import linear_to_srgb, srgb_to_linear

    lin = srgb_to_linear(body.front_colours(albedo) / 255.0)
    amount = ring_detail(np.asarray(albedo), body.ring_uv)
    out = linear_to_srgb(lin[None] * np.exp(amount * neck_mottle())[..., None])
    return np.clip(np.rint(255.0 * np.asarray(out, np.float64)), 0, 255).astype(np.uint8)
