"""The one bilinear image sampler: OpenCV's ``cv2.remap`` (linear, border replicated).

Used by the morph-PCA warps (:mod:`stimulus_engine.morphpca.flow`, the reconstructor) and by
texture transfer (:mod:`stimulus_engine.correspondence.texture_transfer`), which had a NumPy sampler of its
own (float64 gathers of the four neighbours). Measured in one process by
``benchmarks/sampler.py`` (2-core shared development machine, OpenCV 5.0):

* Accuracy: on a float32 image OpenCV interpolates with exact weights, not in 1/32-pixel
  fixed-point steps (a ramp sampled at 1,001 positions between two pixels gives 1,001 values,
  error 1e-7), and its replicated border equals the NumPy sampler's clamped coordinates. What
  remains is float32 rounding of positions and sums: 262,144 lookups in the 2400 x 1600 james
  texture (8-bit) differ from the float64 sampler by at most 0.023 of a level; after rounding
  to 8 bits 61 of them (0.02 %) by one level.
* Speed: 5-9x faster there (14-20 ms vs 103-122 ms), 29-44x on a 240 x 200 warp
  (0.16-0.20 ms vs 5.6-7.2 ms).

So texture-transfer outputs changed when it moved to this sampler: by one level in 64 of the
262,144 texels of the ICT -> james transfer at 512 x 512 (0.024 %); a MediaPipe mesh-character
grid (texture, normal and specular maps re-laid at 128 x 128) stayed byte-identical, images
and cache. The morph-PCA outputs did not change (the same ``cv2.remap`` call as before).
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["sample_bilinear", "sample_points", "uv_to_pixels"]

#: cv2.remap needs map sides below 32767; point lists are sampled as rows of this many points.
_ROW = 1024


def sample_bilinear(image: np.ndarray, positions: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Sample ``image`` at absolute pixel ``positions`` (``out(p) = image(positions(p))``).

    Parameters
    ----------
    image : (h, w) or (h, w, c) array
        Converted to float32 (no copy if it already is, contiguous).
    positions : (H, W, 2) array
        (x, y) in pixels, pixel centres at integers; outside the image the border is
        replicated.
    out : (H, W[, c]) float32 array, optional
        Written in place (saves an allocation in repeated calls).

    Returns
    -------
    (H, W) or (H, W, c) float32 array
    """
    pos = np.ascontiguousarray(positions, dtype=np.float32)  # one CV_32FC2 map: no x/y split
    return cv2.remap(np.ascontiguousarray(image, dtype=np.float32), pos, None, cv2.INTER_LINEAR, dst=out,
                     borderMode=cv2.BORDER_REPLICATE)


def sample_points(image: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """:func:`sample_bilinear` at K points ``xy`` (K, 2); returns (K, c) float32 (c = 1 for a
    2-D image)."""
    xy = np.asarray(xy, dtype=np.float32).reshape(-1, 2)
    k = len(xy)
    rows = -(-k // _ROW)
    pos = np.zeros((rows * _ROW, 2), dtype=np.float32)
    pos[:k] = xy
    vals = sample_bilinear(image, pos.reshape(rows, _ROW, 2))
    return vals.reshape(rows * _ROW, -1)[:k]


def uv_to_pixels(uv: np.ndarray, width: int, height: int) -> np.ndarray:
    """Texture coordinates (K, 2) (OBJ convention: (0, 0) the image's bottom-left corner,
    v up) to pixel positions (x, y) with pixel centres at integers."""
    uv = np.asarray(uv, dtype=np.float64)
    return np.stack([uv[:, 0] * width - 0.5, (1.0 - uv[:, 1]) * height - 0.5], axis=1)
