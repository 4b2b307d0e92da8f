"""How different two stimuli look (structural dissimilarity of their luminance inside the face), and how
much fine skin detail a face shows (:func:`cheek_detail`).

The stylisation continuum is spaced and reported by one image distance (docs/stimuli.md,
"Even steps"): ``1 - SSIM`` (Wang et al. 2004: 11-tap Gaussian window, sigma 1.5, K1 0.01,
K2 0.03) of the images' luma, averaged over the oval around the framed face
(:func:`stimulus_engine.render.vignette.face_oval`, where every level of a grid puts the face:
the eyes are framed within 2 px). SSIM compares local means, contrasts and structure, so it
sees pores, stubble and shading detail go (which the mean colour does not) and a flat albedo's
lost gradients; inside the oval it ignores the garment and the background. It is scikit-image's
``structural_similarity`` (which agrees with the MATLAB reference implementation; tested equal
to 1e-9), its five Gaussian filters run as OpenCV separable filters: a continuum's measurement
compares dozens of images, and scipy's filters were three quarters of a comparison's time.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CHEEK_POLYGONS", "CHEEK_SIGMA", "cheek_detail", "face_mask", "luma", "ssim_distance"]


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
    import cv2

    if np.shape(a) != np.shape(b):
        raise ValueError(f"images differ in size: {np.shape(a)} and {np.shape(b)}")
    x, y = luma(a), luma(b)
    k = np.exp(-0.5 * (np.arange(-5, 6) / 1.5) ** 2)  # scipy's sigma 1.5 truncated at 3.5 sigma, as skimage
    k /= k.sum()

    def mean(img: np.ndarray) -> np.ndarray:  # scipy's mode "reflect" is OpenCV's BORDER_REFLECT
        return cv2.sepFilter2D(img, cv2.CV_64F, k, k, borderType=cv2.BORDER_REFLECT)

    ux, uy = mean(x), mean(y)
    vx, vy, vxy = mean(x * x) - ux * ux, mean(y * y) - uy * uy, mean(x * y) - ux * uy
    c1, c2 = (0.01 * 255.0) ** 2, (0.03 * 255.0) ** 2
    smap = (2 * ux * uy + c1) * (2 * vxy + c2) / ((ux * ux + uy * uy + c1) * (vx + vy + c2))
    return float(1.0 - (smap[mask].mean() if mask is not None else smap.mean()))


#: The cheeks as polygons of the 68 dlib landmarks: the jaw line, the mouth corner, the nose's ala
#: and the lower lid (the person's right cheek on the image's left, then the left one).
CHEEK_POLYGONS: tuple[tuple[int, ...], ...] = ((2, 3, 4, 48, 31, 40, 41), (14, 13, 12, 54, 35, 47, 46))
#: The share of each polygon (about its centre) measured: its edges (lids, nostril, mouth corner, the
#: jaw's silhouette) are features, not skin detail.
CHEEK_SHRINK = 0.75
#: Width (pixels) of the Gaussian whose residual is a cheek's fine detail.
CHEEK_SIGMA = 1.5


def cheek_detail(rgb: np.ndarray, landmarks: np.ndarray, sigma: float = CHEEK_SIGMA) -> float:
    """Fine skin detail in the cheeks: the standard deviation of luminance's high-pass (the image's
    relative luminance minus its Gaussian blur of ``sigma`` px) inside :data:`CHEEK_POLYGONS` (each
    shrunk to :data:`CHEEK_SHRINK` about its centre).

    Pores, stubble and a photograph's blotches give a photograph of a face 0.008-0.013 at 768 px (London
    set); paint next to none (james 0.0011, Lee Perry-Smith 0.0012 at 1024 x 768).

    Parameters
    ----------
    rgb : (H, W, 3) uint8 array
    landmarks : (68, 2) array
        dlib's 68 landmarks of the face in the image (x, y pixels).
    sigma : float
        The high-pass's Gaussian width in pixels.
    """
    from PIL import Image, ImageDraw
    from scipy.ndimage import gaussian_filter

    from skimage.color import rgb2lab

    lum = rgb2lab(np.asarray(rgb)[..., :3].astype(np.float64) / 255.0)[..., 0] / 100.0
    detail = lum - gaussian_filter(lum, sigma)
    mask = Image.new("L", (rgb.shape[1], rgb.shape[0]), 0)
    draw = ImageDraw.Draw(mask)
    lm = np.asarray(landmarks, np.float64)
    for poly in CHEEK_POLYGONS:  # shrunk toward its centre: the lids, nostril, lips and jaw line stay out
        pts = lm[list(poly)]
        centre = pts.mean(axis=0)
        draw.polygon([tuple(centre + CHEEK_SHRINK * (p - centre)) for p in pts], fill=255)
    inside = np.asarray(mask) > 127
    return float(detail[inside].std()) if inside.sum() > 20 else float("nan")
