"""Phone camera: a perspective camera looking down on the table, slightly tilted and rolled."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.shot import Shot


@dataclass(frozen=True)
class PhoneCameraCfg(Config):
    """A perspective camera like a phone held over the table: its field of view, a tilt off
    vertical and a roll; it stands as high as makes the working area fill the frame."""

    fov_deg: tuple[float, float] = param((50.0, 70.0), gt=0, lt=120,
                                         help="uniform range of the field of view across the "
                                         "image (a phone's main camera: ~65)")
    tilt_deg: float = param(5.0, ge=0, le=30, help="max tilt off vertical (uniform in angle, "
                            "uniform direction)")
    roll_deg: float = param(5.0, ge=0, le=180, help="max roll about the view axis (uniform)")
    fill: tuple[float, float] = param((0.95, 1.05), gt=0,
                                      help="uniform range of the working area's size against "
                                      "the frame (1: the clean view's extent)")


@dataclass(frozen=True)
class PhoneCamera(ConfiguredEffect):
    """A perspective camera of random field of view, tilt and roll."""

    name: ClassVar[str] = "phone_camera"
    stage: ClassVar[str] = "image"
    cfg: PhoneCameraCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        c = self.cfg
        fov = np.radians(rng.uniform(*c.fov_deg))
        tilt = np.radians(rng.uniform(0.0, c.tilt_deg))
        azimuth = rng.uniform(0.0, 2 * np.pi)
        roll = np.radians(rng.uniform(-c.roll_deg, c.roll_deg))
        fill = rng.uniform(*c.fill)
        cam = shot.camera
        camera = replace(cam, scale=cam.scale / float(fill), tilt=cam.tilt + float(tilt),
                         tilt_azimuth=float(azimuth) if cam.tilt == 0 else cam.tilt_azimuth,
                         roll=cam.roll + float(roll), fovy=float(fov))
        return replace(shot, camera=camera)


register_effect("phone_camera", lambda cfg: [PhoneCamera(cfg)], cfg=PhoneCameraCfg)
