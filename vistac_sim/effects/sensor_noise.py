"""Sensor noise: read noise and shot noise (growing with brightness) of the phone's frame."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.finish import NOISE_MARGIN
from vistac_sim.render.shot import Finish, Shot


@dataclass(frozen=True)
class SensorNoiseCfg(Config):
    """Per-pixel sensor noise: a pixel of value I (0-255) gets a Gaussian of std
    sqrt(read^2 + shot * I), read and shot drawn per configuration."""

    read: tuple[float, float] = param((0.5, 3.0), ge=0, le=100,
                                      help="uniform range of the read noise std, grey levels")
    shot: tuple[float, float] = param((0.0, 0.15), ge=0, le=10,
                                      help="uniform range of the shot noise factor (variance "
                                      "per grey level)")


@dataclass(frozen=True)
class SensorNoise(ConfiguredEffect):
    """Read and shot noise per pixel."""

    name: ClassVar[str] = "sensor_noise"
    stage: ClassVar[str] = "image"
    cfg: SensorNoiseCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        c = self.cfg
        noise = (float(rng.uniform(*c.read)), float(rng.uniform(*c.shot)))
        at = tuple(int(v) for v in rng.integers(0, NOISE_MARGIN, 2))
        return replace(shot, finish=replace(shot.finish or Finish(), noise=noise, noise_at=at))


register_effect("sensor_noise", lambda cfg: [SensorNoise(cfg)], cfg=SensorNoiseCfg)
