"""How different two stimuli look: structural dissimilarity of their luminance inside the face.

The stylisation continuum is spaced and reported by one image distance (docs/stimuli.md,
"Even steps"): ``1 - SSIM`` (Wang et al. 2004: 11-tap Gaussian window, sigma 1.5, K1 0.01,
K2 0.03) of the images' luma, averaged over the oval around the framed face
(:func:`stimulus_engine.render.vignette.face_oval`, where every level of a grid puts the face:
the eyes are framed within 2 px). SSIM compares local means, contrasts and structure, so it
sees pores, stubble and shading detail go (which the mean colour does not) and a flat albedo's
lost gradients; inside the oval it ignores the garment and the background. scikit-image's
``structural_similarity`` computes it (agreeing with the MATLAB reference implementation).
"""

from __future__ import annotations

import numpy as np

__all__ = ["face_mask", "luma", "ssim_distance"]


def luma(image: np.ndarray) -> np.ndarray:
    """Rec. 601 luma (0..255 float) of an sRGB image (H, W, 3 uint8), the channel SSIM is defined on."""
    rgb = np.asarray(image, np.float64)[..., :3]
    return rgb @ np.array([0.299, 0.587, 0.114])


def face_mask(width: int, height: int, eye_row: float, face_fraction: float) -> np.ndarray:
    """(height, width) bool: inside the oval around a face framed with its eyes ``eye_row`` of
    the height from the top and its length ``face_fraction`` of it."""
    from stimulus_engine.render.vignette import face_oval

    cx, cy, rx, ry, _ = face_oval(width, height, eye_row, face_fraction)
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    return np.hypot((x + 0.5 - cx) / rx, (y + 0.5 - cy) / ry) < 1.0


def ssim_distance(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """``1 - SSIM`` of two images' luma, the SSIM map averaged over ``mask`` (default: all).

    Parameters
    ----------
    a, b : (H, W, 3) uint8 arrays
        Two renders of the same size.
    mask : (H, W) bool array, optional
        Where to average (:func:`face_mask`).

    Returns
    -------
    float
        0 for identical images; about 0.01 for a just-visible change of skin detail at stimulus
        size, up to 1 for unrelated ones.
    """
    from skimage.metrics import structural_similarity

    if np.shape(a) != np.shape(b):
        raise ValueError(f"images differ in size: {np.shape(a)} and {np.shape(b)}")
    _, smap = structural_similarity(luma(a), luma(b), data_range=255.0, gaussian_weights=True, sigma=1.5,
                                    use_sample_covariance=False, full=True)
    return float(1.0 - (smap[mask].mean() if mask is not None else smap.mean()))
