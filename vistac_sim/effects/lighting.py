"""Lighting: a directional key light of random direction and intensity per configuration."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.shot import Light, Shot


@dataclass(frozen=True)
class LightingCfg(Config):
    """A directional key light of random direction and intensity instead of the plain headlight.

    The headlight keeps only its ambient part; the key light adds diffuse and specular light.
    """

    elevation_deg: tuple[float, float] = param((35.0, 80.0), ge=0, le=90,
                                               help="uniform range above the "
                                               "table plane")
    azimuth_deg: tuple[float, float] = param((0.0, 360.0), help="uniform range, from world +x "
                                             "towards +y")
    intensity: tuple[float, float] = param((0.4, 0.8), ge=0, le=10,
                                           help="uniform range of the key light's "
                                           "diffuse")
    ambient: tuple[float, float] = param((0.3, 0.55), ge=0, le=1,
                                         help="uniform range of the ambient light")
    specular: float = param(0.2, ge=0, le=1, help="key light's specular")
    temperature_k: tuple[float, float] | None = param(
        None, ge=1000, le=40000, help="uniform range of the key light's colour temperature, "
        "kelvin (None: white light)")


@dataclass(frozen=True)
class Lighting(ConfiguredEffect):
    """A directional key light of random direction and intensity."""

    name: ClassVar[str] = "lighting"
    stage: ClassVar[str] = "image"
    cfg: LightingCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        c = self.cfg
        el, az, diffuse, ambient = (rng.uniform(*r) for r in (
            c.elevation_deg, c.azimuth_deg, c.intensity, c.ambient))
        rgb = (1.0, 1.0, 1.0)
        if c.temperature_k is not None:
            rgb = kelvin_rgb(float(rng.uniform(*c.temperature_k)))
        return replace(shot, light=Light(float(np.radians(el)), float(np.radians(az)),
                                         float(diffuse), float(ambient), c.specular, rgb))


def kelvin_rgb(kelvin: float) -> tuple[float, float, float]:
    """Colour of a black body at `kelvin` as RGB gains of unit luminance (Rec. 709 weights).

    Tanner Helland's fit of the Planckian locus in sRGB (1000-40000 K): about 6600 K is white,
    lower is warmer (redder), higher is cooler (bluer).
    """
    t = kelvin / 100.0
    if t <= 66:
        r = 255.0
        g = 99.4708025861 * np.log(t) - 161.1195681661
        b = 0.0 if t <= 19 else 138.5177312231 * np.log(t - 10) - 305.0447927307
    else:
        r = 329.698727446 * (t - 60) ** -0.1332047592
        g = 288.1221695283 * (t - 60) ** -0.0755148492
        b = 255.0
    rgb = np.clip([r, g, b], 0.0, 255.0) / 255.0
    rgb = rgb / (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2])
    return (float(rgb[0]), float(rgb[1]), float(rgb[2]))


register_effect("lighting", lambda cfg: [Lighting(cfg)], cfg=LightingCfg)
