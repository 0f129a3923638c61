"""Force noise (``--noise S``): per-press Gaussian noise relative to the force magnitude."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from vistac.config import param
from vistac.noise import relative_force_noise
from vistac_sim.effects.registry import Effect, register_effect


@dataclass(frozen=True)
class ForceNoise(Effect):
    """Per-press Gaussian measurement noise, relative to the force magnitude.

    Each component of each finger's force gets independent noise with standard deviation
    ``relative_std * |F|`` (the noise-free magnitude of that finger's force in that repeat);
    the model itself is `vistac.noise.relative_force_noise`.
    """

    name: ClassVar[str] = "force_noise"
    stage: ClassVar[str] = "force"
    relative_std: float = 0.05

    def __call__(self, forces: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return relative_force_noise(forces, self.relative_std, rng)


register_effect(
    "noise", lambda noise: [ForceNoise(relative_std=noise)] if noise > 0 else [],
    value=param(0.0, ge=0, le=10, help="relative std of the per-press force measurement noise "
                "(0 disables the effect)", why="beyond, the labels are noise alone"))
