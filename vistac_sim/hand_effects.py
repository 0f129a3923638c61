"""Effects of a hand pressed by an operator: sideways finger pull, placement error per repeat."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from vistac_sim.config import FingerPullCfg, PlacementErrorCfg
from vistac_sim.effects import Effect
from vistac_sim.errors import UserError
from vistac_sim.geometry import unit
from vistac_sim.grasp import Grasp
from vistac_sim.scene import FINGERS


@dataclass(frozen=True)
class FingerPull(Effect):
    """A sideways force on the pad: ``F_y += fraction * |F_z|`` in each listed finger's frame.

    ``fraction = mean + config_spread * a + spread * b`` with a drawn once per configuration and
    finger and b once per press and finger (standard normal). The study saw +y where the surface
    normal predicts -y: a positive `mean` reproduces that bias.
    """

    name: ClassVar[str] = "finger_pull"
    stage: ClassVar[str] = "force"
    mean: float = 0.15
    spread: float = 0.05
    config_spread: float = 0.05
    fingers: tuple[str, ...] = FINGERS

    @classmethod
    def from_cfg(cls, cfg: FingerPullCfg) -> FingerPull:
        """Check and build.

        Raises:
            UserError: negative spreads or an unknown finger name.
        """
        unknown = set(cfg.fingers) - set(FINGERS)
        if unknown or cfg.spread < 0 or cfg.config_spread < 0:
            raise UserError(f"finger_pull: spreads must not be negative and fingers must be in "
                            f"{FINGERS} (got {sorted(unknown) or list(cfg.fingers)})")
        return cls(cfg.mean, cfg.spread, cfg.config_spread, tuple(cfg.fingers))

    def __call__(self, forces: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        k = len(forces)
        fraction = (self.mean + self.config_spread * rng.standard_normal(2)
                    + self.spread * rng.standard_normal((k, 2)))
        mask = np.array([f in self.fingers for f in FINGERS], float)
        out = forces.copy()
        out[..., 1] += mask * fraction * np.abs(forces[..., 2])
        return out


@dataclass(frozen=True)
class PlacementError(Effect):
    """The finger lands off its target: per repeat, each target moves by a Gaussian world-xy
    shift (std `position_std` m) and each approach direction turns by a Gaussian angle (std
    `angle_std_deg`). A scene effect: every repeat gets its own physics solve.
    """

    name: ClassVar[str] = "placement_error"
    stage: ClassVar[str] = "scene"
    position_std: float = 0.001
    angle_std_deg: float = 3.0

    @classmethod
    def from_cfg(cls, cfg: PlacementErrorCfg) -> PlacementError:
        """Check and build.

        Raises:
            UserError: a negative std.
        """
        if cfg.position_std < 0 or cfg.angle_std_deg < 0:
            raise UserError("placement_error: position_std and angle_std_deg must not be negative")
        return cls(cfg.position_std, cfg.angle_std_deg)

    def __call__(self, grasp: Grasp, rng: np.random.Generator) -> Grasp:
        shift = self.position_std * rng.standard_normal((2, 2))
        ang = np.radians(self.angle_std_deg) * rng.standard_normal(2)
        c, s = np.cos(ang), np.sin(ang)
        a = grasp.approach
        turned = np.c_[c * a[:, 0] - s * a[:, 1], s * a[:, 0] + c * a[:, 1]]
        return grasp.moved(target=grasp.target + shift, approach=unit(turned))
