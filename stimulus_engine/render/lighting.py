"""Lighting presets (thesis §6.3.2): a key light plus rim lights, with hard, soft or no shadows.

Every preset is a list of :class:`LightSpec` in *camera-relative* directions, so a face lit
with a preset looks the same whatever the camera framing is. Directions point from the light
towards the subject; ``x`` is image right, ``y`` image up, ``z`` towards the viewer.

Presets
-------
``direct_hard``
    One directional key light from upper left-front with a hard shadow map, two rim lights
    from behind, a weak fill. (Thesis: "direct light with hard shadows".)
``direct_soft``
    The same key split into a small disc of shadow-casting spot lights (an area light made of
    point samples, fixed pattern, so renders stay deterministic): soft shadow edges.
``gi_soft``
    A "global-illumination-like" soft light: a dome of weak directional lights from the
    front hemisphere without shadows plus ambient, and the rim lights. (Thesis: "soft GI".)
``flat``
    Ambient and a frontal light only, no shadows (for diagnostics and fast previews).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LIGHTING_PRESETS", "Disc", "LightSpec", "group_discs", "lighting_preset"]


@dataclass(frozen=True)
class LightSpec:
    """One light, in camera-relative coordinates.

    Attributes
    ----------
    kind : {"directional", "spot"}
        Directional lights are at infinity; spot lights sit ``distance`` scene units away from
        the framing target, along ``-direction``.
    direction : tuple of float
        Direction the light travels (from the light towards the face), camera frame.
    intensity : float
        Directional: lux-like pyrender intensity; spot: candela-like, scaled by ``distance**2``.
    color : tuple of float
        Linear RGB.
    shadow : bool
        Cast a shadow map (directional or spot shadow flags; ``SHADOWS_ALL`` is never used
        because it fails on Mesa llvmpipe).
    offset : tuple of float
        For spot lights: offset perpendicular to the direction, in units of ``distance``
        (samples of an area light).
    """

    kind: str
    direction: tuple[float, float, float]
    intensity: float
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    shadow: bool = False
    offset: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class Disc:
    """An area light: the spot samples of one disc (same direction, different offsets) taken together.

    Attributes
    ----------
    direction : tuple of float
        Direction the light travels, camera frame.
    intensity : float
        The samples' summed intensity.
    color : tuple of float
    shadow : bool
    radius : float
        Angular radius: the largest offset, as a fraction of the distance.
    """

    direction: tuple[float, float, float]
    intensity: float
    color: tuple[float, float, float]
    shadow: bool
    radius: float


def group_discs(lights: list[LightSpec]) -> list[LightSpec | Disc]:
    """``lights`` with the spot samples of each disc (``direct_soft``'s area light) as one
    :class:`Disc`, placed where its first sample was; other lights as they are."""
    out: list[LightSpec | Disc] = []
    where: dict[tuple, int] = {}
    for spec in lights:
        if spec.kind != "spot":
            out.append(spec)
            continue
        key = tuple(np.round(spec.direction, 6))
        radius = float(np.hypot(*spec.offset))
        if key not in where:
            where[key] = len(out)
            out.append(Disc(spec.direction, spec.intensity, spec.color, spec.shadow, radius))
        else:
            d = out[where[key]]
            out[where[key]] = Disc(d.direction, d.intensity + spec.intensity, d.color, d.shadow or spec.shadow,
                                   max(d.radius, radius))
    return out


_KEY = (0.55, -0.45, -0.7)  # from upper left-front (viewer's left), pointing at the face
_RIM_L = (0.7, -0.2, 0.7)  # from behind left
_RIM_R = (-0.7, -0.2, 0.7)  # from behind right


def _rims(intensity: float) -> list[LightSpec]:
    return [LightSpec("directional", _RIM_L, intensity), LightSpec("directional", _RIM_R, intensity)]


def _disc_offsets(n: int, radius: float) -> list[tuple[float, float]]:
    """A fixed sunflower pattern of ``n`` points in a disc (deterministic area-light samples)."""
    golden = np.pi * (3.0 - np.sqrt(5.0))
    pts = []
    for i in range(n):
        r = radius * np.sqrt((i + 0.5) / n)
        a = i * golden
        pts.append((float(r * np.cos(a)), float(r * np.sin(a))))
    return pts


def _dome(n_theta: int = 2, n_phi: int = 6, intensity: float = 0.30) -> list[LightSpec]:
    """Weak directional lights over the front hemisphere (light travels towards -z).

    The intensity makes a face as bright on average as under the direct presets (mean red of the
    procedural head's skin 160 vs 161 for ``direct_hard``); before all 12 lights were drawn
    (pyrender's 4-lights-per-type limit, lifted in :mod:`._pyrender`) it was 0.55 and gi_soft
    faces came out about 17 % darker than direct ones.
    """
    lights = []
    for i in range(n_theta):
        theta = (i + 0.5) / n_theta * (np.pi / 2.6)
        for j in range(n_phi):
            phi = 2 * np.pi * (j + 0.5 * i) / n_phi
            d = (-np.sin(theta) * np.cos(phi), -np.sin(theta) * np.sin(phi) - 0.15, -np.cos(theta))
            lights.append(LightSpec("directional", tuple(float(v) for v in d), intensity / (n_theta * n_phi) * 6))
    return lights


def _presets() -> dict[str, tuple[list[LightSpec], float]]:
    soft_n = 6
    return {
        "direct_hard": (
            [LightSpec("directional", _KEY, 3.2, shadow=True), LightSpec("directional", (-0.4, -0.1, -0.9), 0.6),
             *_rims(1.4)],
            0.12,
        ),
        "direct_soft": (
            [*(LightSpec("spot", _KEY, 3.2 / soft_n, shadow=True, offset=o) for o in _disc_offsets(soft_n, 0.18)),
             LightSpec("directional", (-0.4, -0.1, -0.9), 0.6), *_rims(1.4)],
            0.12,
        ),
        "gi_soft": ([*_dome(), *_rims(1.0)], 0.35),
        "flat": ([LightSpec("directional", (0.0, -0.2, -1.0), 2.5)], 0.4),
    }


#: Names of the lighting presets.
LIGHTING_PRESETS: tuple[str, ...] = tuple(_presets())


def lighting_preset(name: str) -> tuple[list[LightSpec], float]:
    """The lights and the ambient level of preset ``name``.

    Parameters
    ----------
    name : str
        One of :data:`LIGHTING_PRESETS`.

    Returns
    -------
    lights : list of LightSpec
    ambient : float
        Ambient light level (grey, linear).

    Raises
    ------
    ValueError
        For an unknown preset name (the message lists the known ones).
    """
    presets = _presets()
    if name not in presets:
        raise ValueError(f"unknown lighting preset '{name}' (expected one of: {', '.join(presets)})")
    return presets[name]
