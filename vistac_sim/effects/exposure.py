"""Exposure and white balance: the phone's gain per channel, drawn per configuration."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.shot import Finish, Shot


@dataclass(frozen=True)
class ExposureCfg(Config):
    """Exposure (a gain on every channel) and white balance (a gain on red and blue against
    green) of the phone's frame."""

    ev: tuple[float, float] = param((-0.4, 0.4), ge=-4, le=4,
                                    help="uniform range of the exposure error in stops")
    balance: float = param(0.08, ge=0, le=1,
                           help="std of the red and blue gains' log against green (white "
                           "balance error)")


@dataclass(frozen=True)
class Exposure(ConfiguredEffect):
    """A gain per channel: exposure times white balance."""

    name: ClassVar[str] = "exposure"
    stage: ClassVar[str] = "image"
    cfg: ExposureCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        c = self.cfg
        gain = 2.0 ** rng.uniform(*c.ev)
        rb = np.exp(rng.normal(0.0, c.balance, 2))
        finish = replace(shot.finish or Finish(), gain=(float(gain * rb[0]), float(gain),
                                                         float(gain * rb[1])))
        return replace(shot, finish=finish)


register_effect("exposure", lambda cfg: [Exposure(cfg)], cfg=ExposureCfg)
