"""Lighting: a directional key light of random direction and intensity per configuration."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.view import Light, View


@dataclass
class LightingCfg(Config):
    """A directional key light of random direction and intensity instead of the plain headlight.

    The headlight keeps only its ambient part; the key light adds diffuse and specular light.
    """

    elevation_deg: tuple[float, float] = param((35.0, 80.0), ge=0, le=90, help="uniform range above the "
                                               "table plane")
    azimuth_deg: tuple[float, float] = param((0.0, 360.0), help="uniform range, from world +x "
                                             "towards +y")
    intensity: tuple[float, float] = param((0.4, 0.8), ge=0, le=10, help="uniform range of the key light's "
                                           "diffuse")
    ambient: tuple[float, float] = param((0.3, 0.55), ge=0, le=1, help="uniform range of the ambient light")
    specular: float = param(0.2, ge=0, le=1, help="key light's specular")


@dataclass(frozen=True)
class Lighting(ConfiguredEffect):
    """A directional key light of random direction and intensity."""

    name: ClassVar[str] = "lighting"
    stage: ClassVar[str] = "image"
    cfg: LightingCfg

    def __call__(self, view: View, rng: np.random.Generator) -> View:
        c = self.cfg
        el, az, diffuse, ambient = (rng.uniform(*r) for r in (
            c.elevation_deg, c.azimuth_deg, c.intensity, c.ambient))
        return replace(view, light=Light(float(np.radians(el)), float(np.radians(az)),
                                         float(diffuse), float(ambient), c.specular))


register_effect("lighting", lambda cfg: [Lighting(cfg)], cfg=LightingCfg)
