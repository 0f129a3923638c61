"""Drawn overlay: the fingers drawn into the photograph by hand, in a style drawn per
configuration (colour, width, outline, anti-aliasing, capsule or tapered shape)."""

from __future__ import annotations

import colorsys
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.shot import DrawnStyle, Shot


@dataclass(frozen=True)
class DrawnOverlayCfg(Config):
    """Fingers drawn by a person in 2D over the photograph instead of rendered: hue, saturation
    and value around green (index) and red (thumb), width, outline, anti-aliasing and shape.

    Where they are drawn stays the true fingers' place unless overlay_error moves them too.
    """

    index_hue_deg: tuple[float, float] = param((100.0, 140.0), ge=-360, le=360,
                                               help="uniform range of the index finger's hue")
    thumb_hue_deg: tuple[float, float] = param((-12.0, 12.0), ge=-360, le=360,
                                               help="uniform range of the thumb's hue")
    saturation: tuple[float, float] = param((0.75, 1.0), ge=0, le=1,
                                            help="uniform range of the saturation")
    value: tuple[float, float] = param((0.7, 1.0), ge=0, le=1,
                                       help="uniform range of the value (brightness)")
    width: tuple[float, float] = param((0.8, 1.2), gt=0, le=3,
                                       help="uniform range of the drawn width against the "
                                       "finger's")
    outline: float = param(0.5, ge=0, le=1, help="probability of an outline")
    outline_px: tuple[float, float] = param((1.0, 2.5), ge=0, le=20,
                                            help="uniform range of the outline's thickness, px")
    antialias: float = param(0.5, ge=0, le=1, help="probability of anti-aliased edges")
    tapered: float = param(0.5, ge=0, le=1,
                           help="probability of one tapered shape instead of the capsules")
    taper: tuple[float, float] = param((0.5, 0.9), gt=0, lt=1,
                                       help="uniform range of a tapered shape's far width "
                                       "against the tip's")


@dataclass(frozen=True)
class DrawnOverlay(ConfiguredEffect):
    """Fingers drawn by hand in 2D, in a drawn style."""

    name: ClassVar[str] = "drawn_overlay"
    stage: ClassVar[str] = "image"
    cfg: DrawnOverlayCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        c = self.cfg
        colours = []
        for hues in (c.index_hue_deg, c.thumb_hue_deg):
            h = (rng.uniform(*hues) % 360.0) / 360.0
            rgb = colorsys.hsv_to_rgb(float(h), float(rng.uniform(*c.saturation)),
                                      float(rng.uniform(*c.value)))
            colours.append(tuple(float(v) for v in rgb))
        width = tuple(float(w) for w in rng.uniform(*c.width, 2))
        outline = float(rng.uniform(*c.outline_px)) if rng.random() < c.outline else 0.0
        grey = float(rng.uniform(0.0, 0.25))
        antialias = bool(rng.random() < c.antialias)
        taper = float(rng.uniform(*c.taper)) if rng.random() < c.tapered else 1.0
        style = DrawnStyle((colours[0], colours[1]), width, outline, (grey, grey, grey),
                           antialias, taper)
        return replace(shot, drawn=style)


register_effect("drawn_overlay", lambda cfg: [DrawnOverlay(cfg)], cfg=DrawnOverlayCfg)
