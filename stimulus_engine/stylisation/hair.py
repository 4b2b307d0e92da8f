"""Simplified hair masses: a painted level's hair drawn as a few solid locks, not strands.

An animated-film character's hair is modelled and painted as a few masses with soft gradients
(thesis ch. 5's stylised levels; issue 28), where a photograph shows thousands of strands. A
hair style's card texture (:class:`stimulus_engine.parts.hair.Hair`: grey strands, alpha 255
where there is hair) is simplified by a ``painted`` material's amount (``paint`` 0..1): its
alpha blurred across the strands and raised (:data:`MASS_BLUR` of the texture's width,
:data:`MASS_GAIN`), so neighbouring strands merge into solid locks with soft edges, and its grey
blended into its own blur (the strands' light and dark fibres gone, the locks' shading kept).
The worker draws it instead of the strands (:mod:`stimulus_engine.grid.worker`); Cycles then
draws the hair's cards, not strand curves (:mod:`stimulus_engine.render.scene_export`): a
painted mass, in both engines.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MASS_BLUR", "MASS_GAIN", "hair_mass_texture"]

#: The blur that merges strands into locks (a share of the texture's width) and the gain on the
#: blurred alpha (clipped at 1): where half the texels are hair, the lock is solid.
MASS_BLUR, MASS_GAIN = 0.006, 2.0


def hair_mass_texture(texture: np.ndarray, paint: float) -> np.ndarray:
    """A hair card texture (RGBA) simplified into masses by ``paint`` (module docstring); the
    texture itself at 0.

    Examples
    --------
    >>> t = np.zeros((64, 512, 4), np.uint8)
    >>> t[:, ::2] = (200, 200, 200, 255)              # one-texel strands, one texel apart
    >>> bool((hair_mass_texture(t, 1.0)[8:-8, 16:-16, 3] == 255).all())  # one solid lock
    True
    """
    import cv2

    if not 0.0 <= paint <= 1.0:
        raise ValueError(f"hair masses: paint must be within 0..1 (got {paint})")
    if paint == 0.0:
        return texture
    t = np.asarray(texture, np.float32)
    sigma = max(MASS_BLUR * t.shape[1], 0.5)
    alpha = t[..., 3] / 255.0
    soft = cv2.GaussianBlur(alpha, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    mass = np.clip(soft * MASS_GAIN, 0.0, 1.0)
    # the grey as the locks' shading: the premultiplied blur over the alpha's, where there is hair
    grey = cv2.GaussianBlur(t[..., :3] * alpha[..., None], (0, 0), 2 * sigma, borderType=cv2.BORDER_REFLECT)
    grey /= np.maximum(cv2.GaussianBlur(alpha, (0, 0), 2 * sigma, borderType=cv2.BORDER_REFLECT), 1e-3)[..., None]
    out = t.copy()
    out[..., :3] += paint * (grey - t[..., :3])
    out[..., 3] = 255.0 * (alpha + paint * (mass - alpha))
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
