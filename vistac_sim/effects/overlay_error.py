"""Overlay error: the drawn fingers miss where the fingers really were (image and boxes only)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.shot import Shot


@dataclass(frozen=True)
class OverlayErrorCfg(Config):
    """The drawn fingers are offset and rotated from where the fingers really were (image only).

    Per configuration and finger: a shift in the table plane and a rotation about the fingertip,
    each a fixed bias plus a Gaussian draw. The physics and force labels are untouched; the
    stored finger boxes follow the drawn fingers.
    """

    offset_std: float = param(0.002, ge=0, help="m, std of the shift per world axis")
    rotation_std_deg: float = param(3.0, ge=0, le=180,
                                    help="std of the rotation about the fingertip")
    offset: tuple[float, float] = param((0.0, 0.0), help="m, fixed shift (world x, y) added to "
                                        "the draw")
    rotation_deg: float = param(0.0, help="fixed rotation (counter-clockwise seen from above) "
                                "added")


@dataclass(frozen=True)
class OverlayError(ConfiguredEffect):
    """The drawn fingers miss where the fingers really were (image and boxes only)."""

    name: ClassVar[str] = "overlay_error"
    stage: ClassVar[str] = "image"
    cfg: OverlayErrorCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        c = self.cfg
        shift = np.asarray(c.offset, float) + rng.normal(0.0, 1.0, (2, 2)) * c.offset_std
        turn = np.radians(c.rotation_deg + rng.normal(0.0, 1.0, 2) * c.rotation_std_deg)
        overlay = tuple((float(d[0]), float(d[1]), float(a)) for d, a in zip(shift, turn,
                                                                              strict=True))
        return replace(shot, overlay=overlay)


register_effect("overlay_error", lambda cfg: [OverlayError(cfg)], cfg=OverlayErrorCfg)
