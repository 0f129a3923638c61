"""JPEG: the phone's frame is compressed at a quality drawn per configuration."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.shot import Finish, Shot


@dataclass(frozen=True)
class JpegCfg(Config):
    """JPEG compression of the phone's frame (before the fingers are drawn on it)."""

    quality: tuple[int, int] = param((60, 95), ge=1, le=100,
                                     help="uniform range of the JPEG quality (inclusive)")


@dataclass(frozen=True)
class Jpeg(ConfiguredEffect):
    """JPEG compression at a drawn quality."""

    name: ClassVar[str] = "jpeg"
    stage: ClassVar[str] = "image"
    cfg: JpegCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        lo, hi = self.cfg.quality
        quality = int(rng.integers(min(lo, hi), max(lo, hi) + 1))
        return replace(shot, finish=replace(shot.finish or Finish(), jpeg=quality))


register_effect("jpeg", lambda cfg: [Jpeg(cfg)], cfg=JpegCfg)
