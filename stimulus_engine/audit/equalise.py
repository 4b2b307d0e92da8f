"""SHINE-style equalisation of a stimulus set's luminance (Willenbockel et al., 2010).

The SHINE toolbox for MATLAB equalises low-level image properties across a set of stimuli so
that differences in, e.g., rated appeal cannot be put down to brightness, contrast or spatial
frequency content. This module offers its three main operations as pure functions on a list of
same-size ``uint8`` RGB images with boolean face masks (``True`` on the face):

* :func:`match_luminance` (SHINE ``lumMatch``): mean and standard deviation inside each mask;
* :func:`match_histogram` (SHINE ``histMatch``): exact histogram specification inside each mask;
* :func:`match_spectrum` (SHINE ``specMatch``): the Fourier amplitude spectrum of the whole image.

Colour handling
---------------
SHINE works on greyscale images. Here every image is converted to CIE L*a*b* (sRGB, D65;
:func:`skimage.color.rgb2lab`) and only the lightness L* (0 black .. 100 white) is equalised;
a* and b* are kept, the result is converted back (:func:`skimage.color.lab2rgb`, which clips
colours outside the sRGB gamut), scaled by 255, clipped to 0..255 and rounded to the nearest
integer (:func:`numpy.rint`, halves to even).

The luminance levels of the 8-bit output are the L* values of the 256 sRGB greys
(:func:`grey_levels`): a pixel's *level* is the grey whose L* is nearest its own
(:func:`level_codes`). With ``grey=True`` the output is grey (R = G = B = that level), so the
L* of every output pixel is exactly one of the 256 levels and the histogram specification is
exact on the written 8-bit files (up to apportioning each image's pixel count, see
:func:`match_histogram`). In colour the a*/b* of a pixel change the 8-bit RGB that encodes a
given L*, and rounding the three channels (plus gamut clipping) moves a few pixels to a
neighbouring level: the colour histograms agree only approximately (measure it with
:func:`histogram_mismatch`).

Background
----------
Outside the masks the pixels are set to a grey background (``background``, a fraction of full
scale: 0.5, the protocol's 50 % grey, is 8-bit 128) or, with ``background=None``, left as they
were. Both are written exactly (no colour round trip).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from appeal.errors import AppealInputError

__all__ = [
    "DEFAULT_BACKGROUND", "SPECTRUM_TOLERANCE", "check_set", "lab_of", "lightness", "grey_levels", "level_codes",
    "encode", "match_luminance", "match_histogram", "match_spectrum", "rotational_average",
    "spectrum_agreement", "histogram_mismatch", "masked_stats", "ssim_lightness", "equalise", "METHODS",
]

#: The protocols' background: 50 % grey (8-bit 128).
DEFAULT_BACKGROUND = 0.5
#: How far (relative) each image's rotational-average amplitude spectrum may lie from the set's
#: mean after :func:`match_spectrum`; it iterates until the 8-bit output is within it.
SPECTRUM_TOLERANCE = 0.01
METHODS = ("luminance", "histogram", "spectrum")


# ------------------------------------------------------------------------------ input checks
def check_set(images: Sequence[np.ndarray], masks: Sequence[np.ndarray], names: Sequence[str] | None = None) -> None:
    """Raise a one-line :class:`~appeal.errors.AppealInputError` unless ``images`` is a set of at
    least two ``uint8`` RGB images of one size with a non-empty boolean mask each.

    Parameters
    ----------
    images : sequence of (H, W, 3) uint8 arrays
    masks : sequence of (H, W) bool arrays
    names : sequence of str, optional
        How to name the images in messages (file names; default ``image 1``, ``image 2``, ...).
    """
    names = list(names) if names is not None else [f"image {i + 1}" for i in range(len(images))]
    if len(images) < 2:
        raise AppealInputError(f"{len(images)} image(s): equalising needs a set of at least 2 images")
    if len(masks) != len(images):
        raise AppealInputError(f"{len(masks)} masks for {len(images)} images: expected one mask per image")
    h0, w0 = np.shape(images[0])[:2]
    for name, im, mask in zip(names, images, masks):
        im = np.asarray(im)
        if im.ndim != 3 or im.shape[2] != 3 or im.dtype != np.uint8:
            raise AppealInputError(f"{name}: expected an 8-bit RGB image, got an array {im.dtype} {im.shape}")
        h, w = im.shape[:2]
        if (h, w) != (h0, w0):
            raise AppealInputError(f"{name}: {w} x {h}, expected {w0} x {h0} like {names[0]}")
        if np.shape(mask) != (h, w):
            raise AppealInputError(f"{name}: mask is {np.shape(mask)}, expected {(h, w)} like the image")
        if not np.any(mask):
            raise AppealInputError(f"{name}: the face mask is empty (no pixel to equalise)")


# ------------------------------------------------------------------------------ colour <-> L*
def lab_of(image: np.ndarray) -> np.ndarray:
    """CIE L*a*b* (D65) of an 8-bit sRGB image: ``rgb2lab(image / 255)``, shape (H, W, 3)."""
    from skimage.color import rgb2lab

    return rgb2lab(np.asarray(image, np.float64) / 255.0)


def lightness(image: np.ndarray) -> np.ndarray:
    """L* (0..100) of an 8-bit sRGB image, shape (H, W)."""
    return lab_of(image)[..., 0]


@lru_cache(maxsize=1)
def grey_levels() -> np.ndarray:
    """L* of the 256 sRGB greys ``g = 0..255`` (strictly increasing, 0 to 100).

    For the linear light :math:`Y = ((g/255 + 0.055)/1.055)^{2.4}` (:math:`g/255/12.92` below
    0.04045), :math:`L^* = 116\\,Y^{1/3} - 16` (:math:`903.3\\,Y` below 0.008856).

    >>> lv = grey_levels(); round(float(lv[0]), 3), round(float(lv[128]), 2), round(float(lv[255]), 2)
    (0.0, 53.59, 100.0)
    """
    g = np.arange(256, dtype=np.uint8)
    lv = lightness(np.repeat(g[:, None], 3, axis=1)[None])[0]
    lv.setflags(write=False)
    return lv


def level_codes(lstar: np.ndarray) -> np.ndarray:
    """The 8-bit grey (0..255) whose L* (:func:`grey_levels`) is nearest each value of ``lstar``."""
    lv = grey_levels()
    mid = (lv[1:] + lv[:-1]) / 2
    return np.searchsorted(mid, np.asarray(lstar, np.float64), side="right").astype(np.uint8)


def encode(lstar: np.ndarray, original: np.ndarray, mask: np.ndarray, *, grey: bool,
           background: float | None) -> np.ndarray:
    """The 8-bit RGB image with lightness ``lstar`` inside ``mask``.

    Inside the mask: in colour ``lab2rgb(L*, a*, b*)`` with the original a*, b*; in grey the
    grey of nearest L* (:func:`level_codes`). Then :math:`\\mathrm{rint}(\\mathrm{clip}(255\\,x, 0, 255))`.
    Outside: the background grey :math:`\\mathrm{rint}(255\\,b)` or, for ``background=None``,
    the original pixels.
    """
    from skimage.color import lab2rgb

    if grey:
        out = np.repeat(level_codes(lstar)[..., None], 3, axis=2)
    else:
        lab = lab_of(original)
        lab[..., 0] = np.clip(lstar, 0.0, 100.0)
        out = np.rint(np.clip(lab2rgb(lab) * 255.0, 0, 255)).astype(np.uint8)
    if background is None:
        out[~mask] = original[~mask]
    else:
        out[~mask] = _background_code(background)
    return out


def _background_code(background: float) -> int:
    """The 8-bit grey of a background fraction (0.5 -> 128)."""
    if not 0.0 <= background <= 1.0:
        raise AppealInputError(f"background {background}: expected a grey fraction from 0 (black) to 1 (white)")
    return int(np.rint(background * 255))


def masked_stats(image: np.ndarray, mask: np.ndarray) -> tuple[float, float]:
    """Mean and (population) standard deviation of the L* of the 8-bit ``image`` inside ``mask``."""
    v = lightness(image)[mask]
    return float(v.mean()), float(v.std())


# ------------------------------------------------------------------------------ lumMatch
def match_luminance(images: Sequence[np.ndarray], masks: Sequence[np.ndarray],
                    target: tuple[float, float] | None = None, *, grey: bool = False,
                    background: float | None = DEFAULT_BACKGROUND) -> list[np.ndarray]:
    """Set the mean and standard deviation of L* inside every mask to one target (SHINE lumMatch).

    Each image's masked lightness :math:`L` with mean :math:`m_i` and standard deviation
    :math:`s_i` becomes

    .. math:: L' = \\mathrm{clip}\\big(M + S\\,(L - m_i)/s_i,\\; 0,\\; 100\\big)

    where :math:`(M, S)` is ``target`` or, by default, the set's averages
    :math:`M = \\overline{m_i}`, :math:`S = \\overline{s_i}`. A flat image (:math:`s_i = 0`)
    only gets its mean moved. Clipping at black and white and the 8-bit rounding keep the
    result from being exact; inside ordinary stimuli it is within a few hundredths of L*.

    Parameters
    ----------
    images : sequence of (H, W, 3) uint8 arrays
        The set, one size.
    masks : sequence of (H, W) bool arrays
        The face of each image.
    target : (mean, sd) in L*, optional
        Instead of the set's averages.
    grey : bool
        Grey output (see the module notes).
    background : float or None
        Grey fraction outside the masks (0.5: 8-bit 128), or None to keep the original pixels.

    Returns
    -------
    list of (H, W, 3) uint8 arrays
    """
    check_set(images, masks)
    lstars = [lightness(im) for im in images]
    stats = [(float(l[m].mean()), float(l[m].std())) for l, m in zip(lstars, masks)]
    big_m, big_s = target if target is not None else (float(np.mean([s[0] for s in stats])),
                                                      float(np.mean([s[1] for s in stats])))
    out = []
    for im, l, m, (mi, si) in zip(images, lstars, masks, stats):
        l = l.copy()
        l[m] = big_m + (l[m] - mi) * (big_s / si if si > 0 else 1.0)
        out.append(encode(np.clip(l, 0, 100), im, m, grey=grey, background=background))
    return out


# ------------------------------------------------------------------------------ histMatch
def _apportion(n: int, p: np.ndarray) -> np.ndarray:
    """Integer counts summing to ``n`` closest to ``n * p`` (largest remainders; ties to the lower level)."""
    exact = n * p / p.sum()
    counts = np.floor(exact).astype(np.int64)
    short = n - int(counts.sum())
    if short:
        order = np.argsort(-(exact - counts), kind="stable")
        counts[order[:short]] += 1
    return counts


def _rank_order(lstar: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Flat indices of the masked pixels from darkest to lightest.

    Equal L* values are ordered by the mean L* of their 3 x 3 neighbourhood (the first of the
    local-mean filters of Coltuc, Bolon & Chassery, 2006, which SHINE's exact histMatch uses),
    remaining ties by raster order (a stable sort).
    """
    from scipy.ndimage import uniform_filter

    local = uniform_filter(lstar, size=3, mode="nearest")
    idx = np.flatnonzero(mask)
    order = np.lexsort((idx, local.ravel()[idx], lstar.ravel()[idx]))
    return idx[order]


def match_histogram(images: Sequence[np.ndarray], masks: Sequence[np.ndarray], *, grey: bool = False,
                    background: float | None = DEFAULT_BACKGROUND) -> list[np.ndarray]:
    """Exact histogram specification of the masked L* to the set's average histogram (SHINE histMatch).

    The histogram has one bin per 8-bit grey level (:func:`grey_levels`, :func:`level_codes`).
    The target is the average of the images' normalised histograms,
    :math:`p_k = \\frac{1}{N}\\sum_i h_{ik}/n_i` (:math:`n_i` pixels in mask :math:`i`). Image
    :math:`i` gets the integer counts :math:`c_{ik}` nearest :math:`n_i p_k` that sum to
    :math:`n_i` (largest remainders, so :math:`|c_{ik} - n_i p_k| < 1`); its masked pixels are
    sorted by L* (ties by the 3 x 3 local mean, then raster order, :func:`_rank_order`) and
    the first :math:`c_{i0}` get level 0, the next :math:`c_{i1}` level 1, and so on.

    With ``grey=True`` the written 8-bit histograms are these counts exactly: two images' normalised
    histograms differ by less than :math:`1/n_i + 1/n_j` in every bin (equal when the masks hold
    the same number of pixels and :math:`n p_k` are integers). In colour, rounding and gamut
    clipping move some pixels to a neighbouring level (:func:`histogram_mismatch`).

    Parameters and returns as :func:`match_luminance` (no ``target``).
    """
    check_set(images, masks)
    lstars = [lightness(im) for im in images]
    lv = grey_levels()
    p = np.mean([np.bincount(level_codes(l[m]), minlength=256) / m.sum() for l, m in zip(lstars, masks)], axis=0)
    out = []
    for im, l, m in zip(images, lstars, masks):
        counts = _apportion(int(m.sum()), p)
        new = l.copy().ravel()
        new[_rank_order(l, m)] = np.repeat(lv, counts)
        out.append(encode(new.reshape(l.shape), im, m, grey=grey, background=background))
    return out


# ------------------------------------------------------------------------------ specMatch
def _rings(shape: tuple[int, int]) -> tuple[np.ndarray, int]:
    """Each Fourier coefficient's ring ``k = rint(f min(H, W))`` (``fftfreq`` order) and ``kmax = min(H, W) // 2``."""
    h, w = shape
    fy, fx = np.meshgrid(np.fft.fftfreq(h), np.fft.fftfreq(w), indexing="ij")
    return np.rint(np.hypot(fy, fx) * min(h, w)).astype(np.int64), min(h, w) // 2


def _ring_means(values: np.ndarray, rings: np.ndarray, kmax: int) -> np.ndarray:
    k = rings.ravel()
    keep = (k >= 1) & (k <= kmax)
    sums = np.bincount(k[keep], weights=values.ravel()[keep], minlength=kmax + 1)
    n = np.bincount(k[keep], minlength=kmax + 1)
    return sums[1:] / n[1:]


def rotational_average(lstar: np.ndarray) -> np.ndarray:
    """Rotational average of the Fourier amplitude spectrum :math:`|\\mathcal{F}(L)|`.

    The frequency of coefficient :math:`(u, v)` is :math:`f = \\sqrt{(u/H)^2 + (v/W)^2}` cycles
    per pixel (``numpy.fft.fftfreq``); bin :math:`k = \\mathrm{rint}(f \\min(H, W))` collects
    :math:`k = 1 .. \\min(H, W)/2` (cycles per shorter side, DC and the corners beyond it left
    out). Returns the mean amplitude of each bin, index ``k - 1``.
    """
    rings, kmax = _rings(lstar.shape)
    return _ring_means(np.abs(np.fft.fft2(lstar)), rings, kmax)


def spectrum_agreement(images: Sequence[np.ndarray]) -> float:
    """Largest relative deviation of an image's rotational average (of the L* of its 8-bit RGB)
    from the set's mean: :math:`\\max_{i,k} |R_i(k)/\\bar R(k) - 1|`."""
    return _spread(_ring_averages([lightness(im) for im in images]))


def _ring_averages(lstars: Sequence[np.ndarray]) -> np.ndarray:
    """:func:`rotational_average` of each image, ``(n, kmax)``."""
    return np.array([rotational_average(l) for l in lstars])


def _spread(averages: np.ndarray) -> float:
    """:math:`\\max_{i,k} |R_i(k)/\\bar R(k) - 1|` of rotational averages ``(n, kmax)``."""
    return float(np.max(np.abs(averages / averages.mean(axis=0) - 1)))


def _spec_match(lstars: list[np.ndarray]) -> list[np.ndarray]:
    """Each image with the set's mean amplitude spectrum :math:`\\bar A = \\frac1N\\sum|F_i|` and its
    own phase: :math:`L_i' = \\mathrm{Re}\\,\\mathcal{F}^{-1}(\\bar A\\, e^{i \\arg F_i})`."""
    spectra = [np.fft.fft2(l) for l in lstars]
    mean_amp = np.mean([np.abs(f) for f in spectra], axis=0)
    return [np.real(np.fft.ifft2(mean_amp * np.exp(1j * np.angle(f)))) for f in spectra]


def _ring_step(lstar: np.ndarray, target: np.ndarray, rings: np.ndarray, kmax: int, power: float) -> np.ndarray:
    """SHINE's sfMatch step raised to ``power``: ring :math:`k` of the image's spectrum scaled by
    :math:`(T_k/R_k)^{p}` (:math:`p = 1`: sfMatch; :math:`p > 1` over-relaxes, which pays where the
    restored background holds most of each change back); DC and the corners beyond the last ring
    are left as they are."""
    spectrum = np.fft.fft2(lstar)
    now = _ring_means(np.abs(spectrum), rings, kmax)
    gain = np.ones(kmax + 2)
    gain[1:kmax + 1] = np.divide(target, now, out=np.ones_like(now), where=now > 0) ** power
    return np.real(np.fft.ifft2(spectrum * gain[np.minimum(rings, kmax + 1)]))


def _ring_counts(rings: np.ndarray, kmax: int) -> np.ndarray:
    """Coefficients per ring ``1 .. kmax``."""
    k = rings.ravel()
    return np.bincount(k[(k >= 1) & (k <= kmax)], minlength=kmax + 1)[1:]


def _per_coefficient(values: np.ndarray, rings: np.ndarray, kmax: int, outside: float) -> np.ndarray:
    """Ring values ``1 .. kmax`` spread onto the coefficients (DC and the corners get ``outside``)."""
    full = np.full(kmax + 2, outside)
    full[1:kmax + 1] = values
    return full[np.minimum(rings, kmax + 1)]


def _polish_spectrum(lstar: np.ndarray, mask: np.ndarray, target: np.ndarray, rings: np.ndarray, kmax: int,
                     tolerance: float, max_iterations: int) -> np.ndarray:
    r"""Move the L* inside ``mask`` until the rotational average is ``target`` (relative ``tolerance``).

    Minimises :math:`\sum_k \log^2(R_k / T_k)` over the pixels inside the mask (the background
    stays as it is) with L-BFGS, the gradient from the FFT
    (:math:`\partial|F_u|/\partial L = \mathrm{Re}\,\mathcal{F}(\bar F_u/|F_u|)`), in a
    preconditioned parameterisation: the change is :math:`M \cdot \mathcal{F}^{-1}(S \mathcal{F}(z))`
    with :math:`S` the target's ring amplitudes, so that a step moves every ring in proportion to
    its amplitude (without it the low rings, whose amplitudes are hundreds of times the high ones',
    barely moved: 300 L-BFGS iterations left London photographs 1.9 % apart; with it 60 iterations
    brought them within 0.3 % of the target). Runs in rounds of 20 iterations until the ring
    averages lie within ``tolerance`` of the target (or ``max_iterations``); L* is clipped to 0..100.
    """
    from scipy import optimize

    counts = _ring_counts(rings, kmax)
    shaping = _per_coefficient(target / target.mean(), rings, kmax, 1.0)
    m = mask.astype(float)

    def shaped(z: np.ndarray) -> np.ndarray:
        return np.real(np.fft.ifft2(np.fft.fft2(z) * shaping))

    def loss_grad(z: np.ndarray) -> tuple[float, np.ndarray]:
        f = np.fft.fft2(lstar + m * shaped(z.reshape(lstar.shape)))
        amp = np.abs(f)
        r = np.log(_ring_means(amp, rings, kmax) / target)
        # scaled by 1e4: L-BFGS's default tolerances stop a loss of this size at once
        d_amp = _per_coefficient(2e4 * r / (target * np.exp(r)) / counts, rings, kmax, 0.0)
        grad = np.real(np.fft.fft2(d_amp * np.conj(f) / np.where(amp > 0, amp, 1.0)))
        return 1e4 * float(np.sum(r ** 2)), shaped(m * grad).ravel()

    z, out, done = np.zeros(lstar.size), lstar, 0
    while done < max_iterations:
        res = optimize.minimize(loss_grad, z, jac=True, method="L-BFGS-B",
                                options={"maxiter": min(20, max_iterations - done), "gtol": 1e-14, "ftol": 1e-15})
        z, done = res.x, done + max(int(res.nit), 1)
        out = np.clip(lstar + m * shaped(z.reshape(lstar.shape)), 0, 100)
        if np.max(np.abs(_ring_means(np.abs(np.fft.fft2(out)), rings, kmax) / target - 1)) <= tolerance:
            break
    return out


def match_spectrum(images: Sequence[np.ndarray], masks: Sequence[np.ndarray], *, grey: bool = False,
                   background: float | None = DEFAULT_BACKGROUND, max_iterations: int = 30,
                   tolerance: float = SPECTRUM_TOLERANCE, polish_iterations: int = 200) -> list[np.ndarray]:
    """Give every image the set's average Fourier amplitude spectrum, keeping its phase (SHINE specMatch).

    The spectrum is that of the whole image's L* (as SHINE's specMatch): first
    :func:`_spec_match` replaces every amplitude spectrum by the set's mean. Restoring the
    background outside the masks afterwards changes the spectra again, so a ring-by-ring
    correction towards the set's mean rotational average (SHINE's sfMatch, :func:`_ring_step`)
    and the background restore then alternate. Plain sfMatch passes converge slowly where the
    face is a small part of the picture (the restored background holds most of each change back;
    measured on eight 1350 x 1350 London photographs with landmark masks: 5.4 % disagreement
    after 30 passes), so each pass over-relaxes: its gains are raised to the largest power (1,
    2, 4 ... 16, doubled after a pass that helped) that still lowers the disagreement.
    Each pass clips L* to 0..100 and restores the background (grey or original) outside the
    masks; when the unrounded results agree within half the tolerance they are encoded to 8 bit
    and the loop stops if the 8-bit results agree within ``tolerance``
    (:func:`spectrum_agreement`), else goes on (at most ``max_iterations`` passes; then the
    closest encoded pass is returned). Where the passes end above ``tolerance`` (photographs:
    3.5 % after 30 passes), each face is then moved to the set's mean rotational average by a
    preconditioned gradient search over its masked pixels (:func:`_polish_spectrum`; 8 London
    photographs: 0.75 %). The full 2-D amplitude spectra agree only approximately; their
    rotational averages are what is matched.

    Parameters and returns as :func:`match_luminance` (no ``target``), and

    max_iterations : int
        Passes at most.
    tolerance : float
        Relative agreement of the rotational averages to stop at (default 1 %).
    polish_iterations : int
        When the passes leave the set further apart than ``tolerance`` (photographs whose face
        masks are a tenth of the picture), each image's face is moved
        towards the set's mean rotational average by a preconditioned gradient search
        (:func:`_polish_spectrum`, at most this many L-BFGS iterations, to a quarter of the
        tolerance); the encoded result is kept if it agrees better.
    """
    check_set(images, masks)
    originals = [lightness(im) for im in images]
    outside = [orig if background is None else np.full_like(orig, grey_levels()[_background_code(background)])
               for orig in originals]
    restores = [lambda l, m=m, bg=bg: np.where(m, np.clip(l, 0, 100), bg) for m, bg in zip(masks, outside)]
    current = [r(l) for r, l in zip(restores, _spec_match(originals))]
    rings, kmax = _rings(originals[0].shape)
    averages = _ring_averages(current)
    power, now = 1.0, _spread(averages)
    best: tuple[float, list[np.ndarray]] | None = None
    passes = max(1, max_iterations)
    for i in range(passes + 1):
        if now <= tolerance / 2 or best is None or i == passes:
            out = [encode(l, im, m, grey=grey, background=background) for l, im, m in zip(current, images, masks)]
            agreement = spectrum_agreement(out)
            if best is None or agreement < best[0]:
                best = (agreement, out)
            if agreement <= tolerance or i == passes:
                break
        target = averages.mean(axis=0)
        while True:  # the largest power (up to 16) that lowers the disagreement; sfMatch's 1 at least
            trial = [r(_ring_step(l, target, rings, kmax, power)) for l, r in zip(current, restores)]
            trial_averages = _ring_averages(trial)
            score = _spread(trial_averages)
            if score < now or power <= 1.0:
                break
            power = max(1.0, power / 2)
        improved = score < now
        current, averages, now = trial, trial_averages, score
        power = min(16.0, power * 2) if improved else power
    if best[0] > tolerance and polish_iterations > 0:
        start = [lightness(im) for im in best[1]]
        target = _ring_averages(start).mean(axis=0)
        polished = [_polish_spectrum(l, m, target, rings, kmax, tolerance / 4, polish_iterations)
                    for l, m in zip(start, masks)]
        out = [encode(l, im, m, grey=grey, background=background) for l, im, m in zip(polished, images, masks)]
        agreement = spectrum_agreement(out)
        if agreement < best[0]:
            best = (agreement, out)
    return best[1]


# ------------------------------------------------------------------------------ measures
def histogram_mismatch(images: Sequence[np.ndarray], masks: Sequence[np.ndarray]) -> float:
    """Largest difference of two images' normalised 8-bit level histograms inside their masks, in
    units of one pixel: :math:`\\max_{i,j,k} |h_{ik}/n_i - h_{jk}/n_j| \\,/\\, (1/n_i + 1/n_j)`.

    Levels are :func:`level_codes` of the L* of the 8-bit RGB. Below 1 means equal up to the
    apportioning of whole pixels (:func:`match_histogram`).
    """
    hs = [np.bincount(level_codes(lightness(im)[m]), minlength=256) for im, m in zip(images, masks)]
    ns = [int(m.sum()) for m in masks]
    worst = 0.0
    for i in range(len(hs)):
        for j in range(i + 1, len(hs)):
            d = np.abs(hs[i] / ns[i] - hs[j] / ns[j]).max() / (1 / ns[i] + 1 / ns[j])
            worst = max(worst, float(d))
    return worst


def ssim_lightness(original: np.ndarray, result: np.ndarray) -> float:
    """SSIM (Wang et al., 2004; :func:`skimage.metrics.structural_similarity`, 7 x 7 window,
    data range 100) between the L* of two 8-bit images: 1 when identical, the cost of equalising."""
    from skimage.metrics import structural_similarity

    return float(structural_similarity(lightness(original), lightness(result), data_range=100.0))


def equalise(images: Sequence[np.ndarray], masks: Sequence[np.ndarray], method: str, *, grey: bool = False,
             background: float | None = DEFAULT_BACKGROUND,
             names: Sequence[str] | None = None) -> tuple[list[np.ndarray], list[float]]:
    """Run ``method`` (``luminance``, ``histogram`` or ``spectrum``) and the SSIM of each result to its original.

    Returns
    -------
    (list of uint8 images, list of float)
        The equalised images and :func:`ssim_lightness` of each.
    """
    if method not in METHODS:
        raise AppealInputError(f"--match {method}: expected one of {', '.join(METHODS)}")
    check_set(images, masks, names)
    if background is not None:
        _background_code(background)
    fn = {"luminance": match_luminance, "histogram": match_histogram, "spectrum": match_spectrum}[method]
    out = fn(images, masks, grey=grey, background=background)
    return out, [ssim_lightness(a, b) for a, b in zip(images, out)]
