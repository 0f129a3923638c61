"""Shadows: the key light casts shadows (shadow mapping; only scenes that ask pay for it)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.shot import HEADLIGHT, Light, Shot


@dataclass(frozen=True)
class ShadowsCfg(Config):
    """Shadow mapping of the key light (the slower render path; only scenes that ask pay).

    Without the lighting effect a fixed key light of this direction casts the shadows.
    """

    map_size: int = param(2048, ge=64, le=16384,
                          help="texels of the shadow map (MuJoCo's `shadowsize`)")
    elevation_deg: float = param(55.0, gt=0, le=90,
                                 help="direction of the fixed key light (no lighting "
                                 "effect)")
    azimuth_deg: float = param(30.0, help="azimuth of the fixed key light")
    softness: float = param(0.0, ge=0, le=1,
                            help="m, size of the light's bulb: soft shadow edges (0: hard)")
    probability: float = param(1.0, ge=0, le=1,
                               help="share of the configurations with shadows (the shadow "
                               "pass is the costliest part of a render)")


@dataclass(frozen=True)
class Shadows(ConfiguredEffect):
    """The key light casts shadows (a fixed key light when the lighting effect is off).

    The fixed key light keeps the lit table as bright as under the plain headlight: ambient
    0.45, diffuse 0.55 / sin(elevation) (at most 1).
    """

    name: ClassVar[str] = "shadows"
    stage: ClassVar[str] = "image"
    cfg: ShadowsCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        light = shot.light
        if light is None:
            el = np.radians(self.cfg.elevation_deg)
            light = Light(float(el), float(np.radians(self.cfg.azimuth_deg)),
                          float(min(1.0, HEADLIGHT[1] / np.sin(el))), HEADLIGHT[0])
        if self.cfg.softness:
            light = replace(light, softness=self.cfg.softness)
        cast = self.cfg.probability >= 1.0 or rng.random() < self.cfg.probability
        return replace(shot, light=light, shadows=bool(cast))


def shadow_map_size(effects: Any) -> int:
    """Shadow map texels the renderer of an effects config needs: 0 unless shadows are on."""
    return int(effects.shadows.map_size) if effects.shadows is not None else 0


register_effect("shadows", lambda cfg: [Shadows(cfg)], cfg=ShadowsCfg)
