"""Rotations of the top view: how many samples of each configuration, at which angles.

``none``: one sample per configuration; ``fixed``: n samples at angles k * step (the study's
20 x 18 degrees); ``random``: n samples, each at an angle drawn anew every epoch.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from vistac.config import Config, param

ROTATION_MODES = ("fixed", "random", "none")


@dataclass(frozen=True)
class RotationCfg(Config):
    """How many samples of each configuration, at which angles of the top view."""

    mode: Literal["fixed", "random", "none"] = param("none", help="fixed, random or none")
    n: int = param(20, ge=1, le=360, help="samples per configuration (fixed and random)")
    step_deg: float = param(18.0, gt=0, le=360, help="step of the fixed angles, degrees "
                            "counter-clockwise in the image")

    @property
    def count(self) -> int:
        """Samples per configuration."""
        return 1 if self.mode == "none" else self.n
