"""Low-level image measures of one stimulus: pure functions on an RGB image and a boolean mask.

Every measure is defined once, here, with its formula; :mod:`stimulus_engine.audit.workflow`
applies them to a stimulus set.

Colour
    sRGB (8 bit, D65) is linearised with the sRGB transfer function, converted to CIE XYZ (D65,
    2° observer) and to CIE L*a*b* (:func:`skimage.color.rgb2lab`): ``L* = 116 f(Y/Yn) - 16``,
    ``f(t) = t^(1/3)`` above ``(6/29)^3``, linear below. :func:`colour_stats` gives the mean
    L*, a*, b* inside a mask and the RMS contrast ``std(L*/100)`` (population standard deviation,
    ``ddof=0``) inside the mask.
Spectrum
    The luminance channel is L* of the whole image, mean-subtracted and multiplied by a separable
    2-D Hann window (:func:`hann_window`) before the FFT. Spatial frequency is radial, in
    cycles/image along the image's *shorter* side: ``f = hypot(fx, fy) * min(H, W)`` with ``fx,
    fy`` in cycles/pixel. :func:`rotational_average` averages the amplitude ``|F|`` over rings
    one cycle/image wide; :func:`spectrum_slope` fits ``log10 A = a + slope log10 f`` by least
    squares over :data:`FIT_BAND` (4 .. 64 cycles/image, the top capped at 0.8 x Nyquist for
    small images); :func:`band_energy` splits the energy ``sum |F|^2`` into the shares below
    8, from 8 to 32 and from 32 cycles/image up (:data:`ENERGY_BANDS`).
Edges
    :func:`edge_density` is the fraction of mask pixels that are Canny edges
    (:func:`skimage.feature.canny` on ``L*/100`` with ``sigma`` = :data:`CANNY_SIGMA` pixels and
    skimage's default hysteresis thresholds, image border extended by ``nearest``).
Geometry
    :func:`face_area` is the mask's share of the image's pixels; :func:`eye_positions` the eye
    centres (mean of the 68 dlib landmarks 36-41 and 42-47) and the inter-ocular distance in pixels.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "CANNY_SIGMA", "ENERGY_BANDS", "FIT_BAND", "lab_image", "colour_stats", "hann_window", "radial_frequency",
    "amplitude_spectrum", "rotational_average", "spectrum_slope", "band_energy", "edge_density", "face_area",
    "eye_positions",
]

#: The band (cycles/image) over which the log-log slope of the amplitude spectrum is fitted.
FIT_BAND: tuple[float, float] = (4.0, 64.0)
#: Energy bands in cycles/image: low ``[0, 8)``, mid ``[8, 32)``, high ``[32, inf)`` (DC excluded).
ENERGY_BANDS: dict[str, tuple[float, float]] = {"low": (0.0, 8.0), "mid": (8.0, 32.0), "high": (32.0, np.inf)}
#: Gaussian width (pixels) of the Canny edge detector.
CANNY_SIGMA: float = 1.0


def lab_image(rgb: np.ndarray) -> np.ndarray:
    """CIE L*a*b* ``(H, W, 3)`` float of an sRGB image ``(H, W, 3)`` uint8 (D65, 2° observer).

    sRGB -> linear RGB (``((c + 0.055) / 1.055)^2.4``, ``c / 12.92`` below 0.04045) -> XYZ (D65)
    -> L*a*b*, as :func:`skimage.color.rgb2lab`. L* runs from 0 (black) to 100 (white).

    Examples
    --------
    >>> round(float(lab_image(np.full((2, 2, 3), 255, np.uint8))[0, 0, 0]), 3)
    100.0
    """
    from skimage.color import rgb2lab

    img = np.asarray(rgb)
    if img.ndim != 3 or img.shape[2] < 3:
        raise ValueError(f"expected an (H, W, 3) RGB image, got shape {img.shape}")
    return rgb2lab(img[..., :3].astype(np.float64) / 255.0)


def _check_mask(mask: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    m = np.asarray(mask, bool)
    if m.shape != tuple(shape[:2]):
        raise ValueError(f"mask shape {m.shape} does not match the image's {tuple(shape[:2])}")
    return m


def colour_stats(lab: np.ndarray, mask: np.ndarray) -> dict[str, float]:
    """Mean L*, a*, b* and the RMS contrast inside ``mask`` of an L*a*b* image.

    ``L_mean = mean(L*)``, ``a_mean``, ``b_mean`` likewise, and
    ``rms_contrast = sqrt(mean((L*/100 - mean(L*/100))^2))`` (the population standard deviation
    of L*/100: 0 for a uniform region, 0.5 for black and white halves). An empty mask gives NaN.

    Examples
    --------
    >>> lab = np.zeros((2, 2, 3)); lab[0, :, 0] = 100.0
    >>> colour_stats(lab, np.ones((2, 2), bool))["rms_contrast"]
    0.5
    """
    m = _check_mask(mask, lab.shape)
    if not m.any():
        return {"L_mean": np.nan, "a_mean": np.nan, "b_mean": np.nan, "rms_contrast": np.nan}
    px = lab[m]
    return {"L_mean": float(px[:, 0].mean()), "a_mean": float(px[:, 1].mean()), "b_mean": float(px[:, 2].mean()),
            "rms_contrast": float((px[:, 0] / 100.0).std())}


def hann_window(height: int, width: int) -> np.ndarray:
    """The separable 2-D Hann window ``w(y, x) = hann_H(y) hann_W(x)``, ``hann_N(n) = 0.5 - 0.5 cos(2 pi n / (N - 1))``."""
    return np.outer(np.hanning(height), np.hanning(width))


def radial_frequency(height: int, width: int) -> np.ndarray:
    """Radial frequency (cycles/image along the shorter side) of each FFT coefficient, unshifted.

    ``f = hypot(fx, fy) * min(H, W)``, ``fx, fy`` from :func:`numpy.fft.fftfreq` (cycles/pixel).
    """
    fy = np.fft.fftfreq(height)[:, None]
    fx = np.fft.fftfreq(width)[None, :]
    return np.hypot(fx, fy) * min(height, width)


def amplitude_spectrum(luminance: np.ndarray, window: bool = True) -> np.ndarray:
    """``|FFT(w * (I - mean I))|`` of a 2-D luminance image (unshifted, DC at ``[0, 0]``), ``w`` the
    Hann window (:func:`hann_window`) or 1 with ``window=False``."""
    img = np.asarray(luminance, np.float64)
    if img.ndim != 2:
        raise ValueError(f"expected a 2-D luminance image, got shape {img.shape}")
    img = img - img.mean()
    if window:
        img = img * hann_window(*img.shape)
    return np.abs(np.fft.fft2(img))


def rotational_average(amplitude: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotational average of an (unshifted) amplitude spectrum.

    Returns ``(f, A)``: ``f = 1, 2, ..., floor(min(H, W) / 2)`` cycles/image and ``A[k]`` the mean
    amplitude over the ring ``f - 0.5 <= r < f + 0.5`` (:func:`radial_frequency`).
    """
    h, w = amplitude.shape
    r = radial_frequency(h, w)
    ring = np.rint(r).astype(int)
    n = min(h, w) // 2
    sums = np.bincount(ring.ravel(), weights=amplitude.ravel(), minlength=n + 1)[: n + 1]
    counts = np.bincount(ring.ravel(), minlength=n + 1)[: n + 1]
    f = np.arange(1, n + 1, dtype=np.float64)
    return f, sums[1:] / np.maximum(counts[1:], 1)


def fit_band(height: int, width: int, band: tuple[float, float] = FIT_BAND) -> tuple[float, float]:
    """The fit band actually used: ``band`` with its top capped at ``0.8 * min(H, W) / 2`` (0.8 x Nyquist)."""
    return float(band[0]), float(min(band[1], 0.8 * min(height, width) / 2))


def spectrum_slope(luminance: np.ndarray, band: tuple[float, float] = FIT_BAND) -> float:
    """The log-log slope of the rotationally averaged amplitude spectrum over ``band``.

    Least squares ``log10 A(f) = a + slope * log10 f`` over the integer rings ``f`` (cycles/image)
    inside :func:`fit_band`; natural images give about -1 (amplitude ~ 1/f), smoother images
    a steeper (more negative) slope. NaN when fewer than 3 rings fall in the band or the image is flat.
    """
    img = np.asarray(luminance, np.float64)
    f, a = rotational_average(amplitude_spectrum(img))
    lo, hi = fit_band(*img.shape, band)
    keep = (f >= lo) & (f <= hi) & (a > 0)
    if keep.sum() < 3:
        return float("nan")
    slope, _ = np.polyfit(np.log10(f[keep]), np.log10(a[keep]), 1)
    return float(slope)


def band_energy(luminance: np.ndarray, bands: dict[str, tuple[float, float]] | None = None) -> dict[str, float]:
    """The share of spectral energy ``sum |F|^2`` in each band ``lo <= f < hi`` (cycles/image).

    ``F`` is the windowed, mean-subtracted spectrum of :func:`amplitude_spectrum`; the DC term is
    excluded, so with the default :data:`ENERGY_BANDS` the shares sum to 1. A flat image gives NaN.
    """
    bands = ENERGY_BANDS if bands is None else bands
    img = np.asarray(luminance, np.float64)
    power = amplitude_spectrum(img) ** 2
    r = radial_frequency(*img.shape)
    power[0, 0] = 0.0
    total = power.sum()
    if total <= 0:
        return {name: float("nan") for name in bands}
    return {name: float(power[(r >= lo) & (r < hi)].sum() / total) for name, (lo, hi) in bands.items()}


def edge_density(luminance: np.ndarray, mask: np.ndarray, sigma: float = CANNY_SIGMA) -> float:
    """The fraction of ``mask`` pixels that are Canny edges of ``luminance`` (0..1 scale, e.g. L*/100).

    ``mean(canny(luminance, sigma)[mask])`` with skimage's default hysteresis thresholds (10 % and
    20 % of the gradient scale of a 0..1 image) and ``mode='nearest'`` (no edge at the image's
    border). An empty mask gives NaN.
    """
    from skimage.feature import canny

    img = np.asarray(luminance, np.float64)
    m = _check_mask(mask, img.shape)
    if not m.any():
        return float("nan")
    edges = canny(img, sigma=sigma, mode="nearest")
    return float(edges[m].mean())


def face_area(mask: np.ndarray) -> float:
    """The mask's share of the image: ``count(mask) / (H * W)``."""
    m = np.asarray(mask, bool)
    return float(m.mean()) if m.size else float("nan")


def eye_positions(landmarks: np.ndarray) -> dict[str, float]:
    """Eye centres and inter-ocular distance (pixels) from the 68 dlib landmarks ``(68, 2)``.

    The eye on the image's left (the person's right eye, points 36-41) and on its right (42-47)
    are the means of their six points; ``iod_px`` is the distance between the two centres.

    Examples
    --------
    >>> lm = np.zeros((68, 2)); lm[36:42] = (10, 20); lm[42:48] = (40, 20)
    >>> eye_positions(lm)["iod_px"]
    30.0
    """
    lm = np.asarray(landmarks, np.float64)
    if lm.shape != (68, 2):
        raise ValueError(f"expected the 68 dlib landmarks (68, 2), got shape {lm.shape}")
    left, right = lm[36:42].mean(axis=0), lm[42:48].mean(axis=0)
    if left[0] > right[0]:
        left, right = right, left
    return {"eye_left_x": float(left[0]), "eye_left_y": float(left[1]), "eye_right_x": float(right[0]),
            "eye_right_y": float(right[1]), "iod_px": float(np.hypot(*(right - left)))}
