"""Finger pull: the sideways (sensor y) force of a hand-pressed finger that is pulled or slides."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac.dataset import FINGERS
from vistac_sim.effects.registry import ConfiguredEffect, register_effect


@dataclass(frozen=True)
class FingerPullCfg(Config):
    """Sideways (sensor y) force of a finger that is pulled or slides while pressed.

    The added F_y is ``fraction * |F_z|`` with fraction = mean + per-configuration draw +
    per-press draw (Gaussian), in each listed finger's own sensor frame.
    """

    mean: float = param(0.15, ge=-10, le=10,
                        help="systematic part, fraction of |F_z| (+y as seen in the study)")
    spread: float = param(0.05, ge=0, help="per-press std of the fraction")
    config_spread: float = param(0.05, ge=0, help="per-configuration std of the fraction "
                                 "(shared by its presses)")
    fingers: tuple[str, ...] = param(FINGERS, choices=FINGERS, help="fingers that are pulled")


@dataclass(frozen=True)
class FingerPull(ConfiguredEffect):
    """A sideways force on the pad: ``F_y += fraction * |F_z|`` in each listed finger's frame.

    ``fraction = mean + config_spread * a + spread * b`` with a drawn once per configuration and
    finger and b once per press and finger (standard normal). The study saw +y where the surface
    normal predicts -y: a positive `mean` reproduces that bias.
    """

    name: ClassVar[str] = "finger_pull"
    stage: ClassVar[str] = "force"
    cfg: FingerPullCfg

    def __call__(self, forces: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        c, k = self.cfg, len(forces)
        fraction = (c.mean + c.config_spread * rng.standard_normal(2)
                    + c.spread * rng.standard_normal((k, 2)))
        mask = np.array([f in c.fingers for f in FINGERS], float)
        out = forces.copy()
        out[..., 1] += mask * fraction * np.abs(forces[..., 2])
        return out


register_effect("finger_pull", lambda cfg: [FingerPull(cfg)], cfg=FingerPullCfg)
