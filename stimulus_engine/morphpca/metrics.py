"""Image similarity: PSNR and SSIM of float [0, 1] RGB images (scikit-image)."""

from __future__ import annotations

import numpy as np

__all__ = ["psnr", "ssim"]


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB (data range 1); inf for identical images."""
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    """Mean structural similarity (scikit-image, Gaussian-free 7×7 window, colour channels averaged)."""
    from skimage.metrics import structural_similarity

    return float(structural_similarity(np.asarray(a, np.float32), np.asarray(b, np.float32), channel_axis=-1,
                                       data_range=1.0))
