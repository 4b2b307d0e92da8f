"""psignifit 4's default priors and parameter bounds (Schütt et al. 2016, §2.4), as pure functions.

Written from the published description; the test-suite checks the fits against the ``psignifit``
package where it is installed.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy import stats

__all__ = ["width_rescale", "threshold_prior", "width_prior", "beta_prior", "default_priors", "default_bounds"]

Prior = Callable[[NDArray], NDArray]


@functools.lru_cache(maxsize=64)
def width_rescale(alpha: float) -> float:
    """Factor turning a width at ``alpha`` into a 5 %–95 % width (1 for ``alpha = 0.05``; cached:
    the MAP search of a fit evaluates the width prior tens of thousands of times)."""
    z = stats.norm.ppf
    return float((z(0.95) - z(0.05)) / (z(1 - alpha) - z(alpha)))


def threshold_prior(x: NDArray, stimulus_range: tuple[float, float]) -> NDArray:
    """Uniform over the stimulus range, with cosine flanks falling to 0 over half its spread."""
    x = np.asarray(x, float)
    s0, s1 = stimulus_range
    sp = s1 - s0
    p = np.zeros_like(x)
    p[(s0 < x) & (x < s1)] = 1.0
    left = (s0 - sp / 2 <= x) & (x <= s0)
    p[left] = (1 + np.cos(2 * np.pi * (s0 - x[left]) / sp)) / 2
    right = (s1 <= x) & (x <= s1 + sp / 2)
    p[right] = (1 + np.cos(2 * np.pi * (x[right] - s1) / sp)) / 2
    return p


def width_prior(x: NDArray, wmin: float, wmax: float, alpha: float = 0.05) -> NDArray:
    """Uniform between twice the smallest level spacing and the stimulus spread, cosine flanks
    rising from the smallest spacing and falling to 0 at three times the spread."""
    y = np.asarray(x, float) * width_rescale(alpha)
    p = np.zeros_like(y)
    p[(2 * wmin < y) & (y < wmax)] = 1.0
    left = (wmin <= y) & (y <= 2 * wmin)
    p[left] = (1 - np.cos(np.pi * (y[left] - wmin) / wmin)) / 2
    right = (wmax <= y) & (y <= 3 * wmax)
    p[right] = (1 + np.cos(np.pi / 2 * (y[right] - wmax) / wmax)) / 2
    return p


def beta_prior(x: NDArray, b: float = 10.0) -> NDArray:
    """Beta(1, b) density (lapse, guess and overdispersion priors): ``b (1 - x)^(b - 1)`` on [0, 1]
    (closed form; scipy's ``beta.pdf`` costs ~50 µs a call in the MAP search)."""
    x = np.asarray(x, float)
    inside = (x >= 0) & (x <= 1)
    return np.where(inside, b * np.power(np.clip(1 - x, 0, 1), b - 1), 0.0)


def default_priors(stimulus_range: tuple[float, float], width_min: float, alpha: float = 0.05,
                   beta: float = 10.0) -> dict[str, Prior]:
    """psignifit 4's default prior densities (unnormalised), keyed by parameter name."""
    spread = stimulus_range[1] - stimulus_range[0]
    return {
        "threshold": lambda x: threshold_prior(x, stimulus_range),
        "width": lambda x: width_prior(x, width_min, spread, alpha),
        "lambda": lambda x: beta_prior(x, 10.0),
        "gamma": lambda x: beta_prior(x, 10.0),
        "eta": lambda x: beta_prior(x, beta),
    }


def default_bounds(stimulus_range: tuple[float, float], width_min: float, alpha: float = 0.05,
                   guess: float | None = None) -> dict[str, tuple[float, float]]:
    """Grid bounds: threshold over the range ± half its spread, width from the smallest spacing to
    three spreads, lapse (and a free guess rate) in [0, 0.5], overdispersion in [0, 1)."""
    s0, s1 = stimulus_range
    sp = s1 - s0
    b = {
        "threshold": (s0 - sp / 2, s1 + sp / 2),
        "width": (width_min, 3 * sp / width_rescale(alpha)),
        "lambda": (0.0, 0.5),
        "eta": (0.0, 1 - 1e-10),
    }
    b["gamma"] = (0.0, 0.5) if guess is None else (guess, guess)
    return b
