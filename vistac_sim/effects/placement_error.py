"""Placement error: the finger lands off its target on each repeat (one physics solve each)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.geometry import unit
from vistac_sim.hand.grasp import Grasp


@dataclass(frozen=True)
class PlacementErrorCfg(Config):
    """The finger lands a little off its target on each repeat (one physics solve per repeat)."""

    position_std: float = param(0.001, ge=0, help="m, std of the target shift per axis (world xy)")
    angle_std_deg: float = param(3.0, ge=0, help="std of the approach direction's rotation")


@dataclass(frozen=True)
class PlacementError(ConfiguredEffect):
    """The finger lands off its target: per repeat, each target moves by a Gaussian world-xy
    shift (std `position_std` m) and each approach direction turns by a Gaussian angle (std
    `angle_std_deg`). A grasp effect: every repeat gets its own physics solve.
    """

    name: ClassVar[str] = "placement_error"
    stage: ClassVar[str] = "grasp"
    cfg: PlacementErrorCfg

    def __call__(self, grasp: Grasp, rng: np.random.Generator) -> Grasp:
        shift = self.cfg.position_std * rng.standard_normal((2, 2))
        ang = np.radians(self.cfg.angle_std_deg) * rng.standard_normal(2)
        c, s = np.cos(ang), np.sin(ang)
        def turn(a):
            return unit(np.c_[c * a[:, 0] - s * a[:, 1], s * a[:, 0] + c * a[:, 1]])

        return grasp.moved(target=grasp.target + shift, approach=turn(grasp.approach),
                           push=None if grasp.push is None else turn(grasp.push))


register_effect("placement_error", lambda cfg: [PlacementError(cfg)], cfg=PlacementErrorCfg)
