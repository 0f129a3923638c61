"""Blur: defocus (Gaussian) and motion (a line) of the phone's frame, per configuration."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.shot import Finish, Shot


@dataclass(frozen=True)
class BlurCfg(Config):
    """Defocus and motion blur of the phone's frame."""

    defocus_px: tuple[float, float] = param((0.0, 1.0), ge=0, le=20,
                                            help="uniform range of the defocus sigma, px "
                                            "(below 0.3: sharp)")
    motion_px: tuple[float, float] = param((0.0, 3.0), ge=0, le=50,
                                           help="uniform range of the motion blur's length, px "
                                           "(below 1: none)")


@dataclass(frozen=True)
class Blur(ConfiguredEffect):
    """Defocus and motion blur."""

    name: ClassVar[str] = "blur"
    stage: ClassVar[str] = "image"
    cfg: BlurCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        c = self.cfg
        defocus = float(rng.uniform(*c.defocus_px))
        length, angle = float(rng.uniform(*c.motion_px)), float(rng.uniform(0.0, np.pi))
        finish = replace(shot.finish or Finish(), defocus=defocus if defocus >= 0.3 else 0.0,
                         motion=(length if length >= 1.0 else 0.0, angle))
        return replace(shot, finish=finish)


register_effect("blur", lambda cfg: [Blur(cfg)], cfg=BlurCfg)
