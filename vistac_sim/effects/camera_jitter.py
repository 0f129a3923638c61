"""Camera jitter: small shift, scale, tilt and roll of the top camera per configuration."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.shot import Shot


@dataclass(frozen=True)
class CameraJitterCfg(Config):
    """Small changes of the top camera per configuration: shift, scale, tilt and roll."""

    shift_std: float = param(0.003, ge=0, help="m, std of the view centre's shift per world axis")
    scale_std: float = param(0.02, ge=0, lt=0.5,
                             help="relative std of the scale (pixels per metre)")
    tilt_std_deg: float = param(1.0, ge=0, le=45,
                                help="std of the view axis's lean off vertical, per "
                                "horizontal axis")
    roll_std_deg: float = param(1.0, ge=0, le=180, help="std of the rotation about the view axis")


@dataclass(frozen=True)
class CameraJitter(ConfiguredEffect):
    """Small shift, scale, tilt and roll of the top camera per configuration."""

    name: ClassVar[str] = "camera_jitter"
    stage: ClassVar[str] = "image"
    cfg: CameraJitterCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        c = self.cfg
        shift = rng.normal(0.0, c.shift_std, 2)
        scale = float(np.exp(rng.normal(0.0, c.scale_std)))
        tilt_xy = np.radians(rng.normal(0.0, c.tilt_std_deg, 2))  # per horizontal axis
        roll = float(np.radians(rng.normal(0.0, c.roll_std_deg)))
        cx, cy = shot.camera.center
        camera = replace(shot.camera, center=(cx + float(shift[0]), cy + float(shift[1])),
                         scale=shot.camera.scale * scale, tilt=float(np.hypot(*tilt_xy)),
                         tilt_azimuth=float(np.arctan2(tilt_xy[1], tilt_xy[0])),
                         roll=shot.camera.roll + roll)
        return replace(shot, camera=camera)


register_effect("camera_jitter", lambda cfg: [CameraJitter(cfg)], cfg=CameraJitterCfg)
