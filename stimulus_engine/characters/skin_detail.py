"""Fine skin detail where a scan's photograph has too little of it: a detail layer in the albedo.

A photograph of a face shows pores, fine pigment and stubble down to the pixel; a scan's texture
often does not (Lee Perry-Smith's is a 1024-texel JPEG: rendered at stimulus size his cheeks carry
0.005 of :func:`~stimulus_engine.stylisation.image_distance.cheek_detail`, where London's neutral
photographs at the same face size carry 0.006-0.012, 10th-90th percentile, median 0.008; james's
scan 0.014). Film and game pipelines add such detail as a *detail map*; here it is an irregular
mottle (:func:`skin_mottle`: value noise from 0.4 to 1.6 mm, in 3D at every texel's point, so its
size does not follow the UV layout's stretch) multiplied into the albedo's skin as a relative
change of linear brightness.

How much is added depends on how much the texture already has: :func:`fine_detail` is the standard
deviation, over the skin, of the albedo's log luminance minus its blur over :data:`DETAIL_SCALE`
of the distance between the eyes; the layer brings it up to :data:`DETAIL_TARGET` (in quadrature), and adds
nothing to a texture that has as much (james's).
"""

from __future__ import annotations

import numpy as np

__all__ = ["DETAIL_SCALE", "DETAIL_TARGET", "MOTTLE_CELLS", "MOTTLE_WEIGHTS", "fine_detail", "skin_mottle",
           "with_skin_detail"]

#: The blur (a share of the distance between the eyes, 0.6 mm) below which detail counts as fine:
#: a pixel and a half of a face shown with its eyes 100 px apart, the scale
#: :func:`~stimulus_engine.stylisation.image_distance.cheek_detail` measures.
DETAIL_SCALE: float = 1.0 / 100.0
#: The mottle's octaves: lattice spacings (shares of the distance between the eyes: 0.4, 0.8 and
#: 1.6 mm) and weights.
MOTTLE_CELLS: tuple[float, ...] = (1.0 / 160.0, 1.0 / 80.0, 1.0 / 40.0)
MOTTLE_WEIGHTS: tuple[float, ...] = (1.0, 0.8, 0.6)
#: The albedo's fine detail a scan's skin is brought up to (std of log luminance, see :func:`fine_detail`).
DETAIL_TARGET: float = 0.06


def _log_luminance(albedo: np.ndarray) -> np.ndarray:
    from stimulus_engine.faces2d.composite import srgb_to_linear

    lin = srgb_to_linear(np.asarray(albedo)[..., :3] / 255.0).astype(np.float64)
    return np.log(np.maximum(lin @ np.array([0.2126, 0.7152, 0.0722]), 1e-4))


def _texel_size(pts: np.ndarray, valid: np.ndarray) -> float:
    """The median 3D distance between neighbouring valid texels."""
    step = np.linalg.norm(np.diff(pts, axis=1), axis=2)
    both = valid[:, 1:] & valid[:, :-1]
    return float(np.median(step[both])) if both.any() else 1.0


def _high_pass(values: np.ndarray, weight: np.ndarray, sigma: float) -> np.ndarray:
    """``values`` minus their ``weight``-normalised Gaussian blur (texels outside count nothing)."""
    from scipy.ndimage import gaussian_filter

    w = gaussian_filter(weight, sigma)
    blur = gaussian_filter(values * weight, sigma) / np.maximum(w, 1e-6)
    return values - blur


def skin_mottle(points: np.ndarray, iod: float, seed: int = 0, finest: float = 0.0) -> np.ndarray:
    """An irregular fine mottle at 3D ``points`` of a face whose eyes are ``iod`` apart: value noise
    in :data:`MOTTLE_CELLS` (shares of ``iod``; those at least ``finest``) weighted by
    :data:`MOTTLE_WEIGHTS`, each octave's lattice turned by its own random rotation (one lattice's
    grid shows as rows of dots)."""
    from scipy.spatial.transform import Rotation

    from stimulus_engine.characters.procedural_head import value_noise3

    rng = np.random.default_rng(seed)
    out = np.zeros(len(points))
    for k, (cell, weight) in enumerate(zip(MOTTLE_CELLS, MOTTLE_WEIGHTS)):
        turn = Rotation.random(random_state=rng).as_matrix()  # drawn for every octave: the others keep theirs
        if cell < finest:
            continue
        turned = np.asarray(points, np.float64) @ turn.T
        out += weight * (value_noise3(turned, cell * iod, seed + k) - 0.5)
    return out


def fine_detail(albedo: np.ndarray, pts: np.ndarray, valid: np.ndarray, skin: np.ndarray,
                iod: float) -> float:
    """The albedo's fine detail on the skin: the ``skin``-weighted standard deviation of its log
    luminance minus its blur over :data:`DETAIL_SCALE` of ``iod`` (the distance between the eyes'
    centres, in the units of ``pts``).

    Parameters
    ----------
    albedo : (H, W, 3) uint8 array
    pts, valid : (H, W, 3) and (H, W) arrays
        Every texel's 3D point and whether it lies on the surface
        (:func:`~stimulus_engine.characters.skin_maps.bake_surface_points`).
    skin : (H, W) array
        How much each texel is skin (0..1).
    iod : float
        The distance between the eyes' centres.
    """
    weight = np.where(valid, np.clip(skin, 0.0, 1.0), 0.0)
    sigma = DETAIL_SCALE * iod / _texel_size(pts, valid)
    hp = _high_pass(_log_luminance(albedo), weight, sigma)
    core = weight > 0.9
    return float(np.sqrt(np.average(hp[core] ** 2))) if core.sum() > 100 else float("nan")


def with_skin_detail(albedo: np.ndarray, pts: np.ndarray, valid: np.ndarray, skin: np.ndarray, iod: float,
                     seed: int = 0, target: float = DETAIL_TARGET) -> np.ndarray:
    """``albedo`` with :func:`skin_mottle` multiplied into its skin, so that its :func:`fine_detail`
    reaches ``target`` (unchanged where it already does).

    Returns
    -------
    (H, W, 3) uint8 array
    """
    own = fine_detail(albedo, pts, valid, skin, iod)
    if not np.isfinite(own) or own >= target:
        return np.asarray(albedo)
    weight = np.where(valid, np.clip(skin, 0.0, 1.0), 0.0)
    field = np.zeros(valid.shape)
    field[valid] = skin_mottle(pts[valid], iod, seed)
    sigma = DETAIL_SCALE * iod / _texel_size(pts, valid)
    field = _high_pass(field, np.where(valid, 1.0, 0.0), sigma)
    core = weight > 0.9
    field /= max(float(np.sqrt(np.mean(field[core] ** 2))), 1e-9)
    amount = np.sqrt(target ** 2 - own ** 2)
    from stimulus_engine.faces2d.composite import linear_to_srgb, srgb_to_linear

    lin = srgb_to_linear(np.asarray(albedo)[..., :3] / 255.0).astype(np.float64)
    out = linear_to_srgb(lin * np.exp(amount * weight * field)[..., None]).astype(np.float64)
    return np.clip(np.rint(out * 255.0), 0, 255).astype(np.uint8)
