"""Object material: a texture of the object bank, a tint and shine per configuration."""

from __future__ import annotations

import colorsys
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.shot import Shot, Surface
from vistac_sim.render.textures import OBJECT_KINDS


@dataclass(frozen=True)
class ObjectMaterialCfg(Config):
    """The object's look per configuration: a texture (photographs, wood grain, noise, stripes,
    printed labels) or a plain colour, a tint of random hue, and specular shine."""

    kinds: tuple[str, ...] = param(OBJECT_KINDS, choices=OBJECT_KINDS, distinct="kind",
                                   help="texture kinds drawn from, uniformly")
    plain: float = param(0.2, ge=0, le=1, help="probability of no texture (a plain colour)")
    saturation: tuple[float, float] = param((0.0, 0.7), ge=0, le=1,
                                            help="uniform range of the tint's saturation")
    value: tuple[float, float] = param((0.55, 1.0), ge=0, le=1,
                                       help="uniform range of the tint's brightness")
    textured_saturation: float = param(0.3, ge=0, le=1,
                                       help="cap of the tint's saturation on a texture")
    repeat: tuple[float, float] = param((8.0, 30.0), gt=0,
                                        help="texture repeats per metre (log-uniform range)")
    specular: tuple[float, float] = param((0.0, 0.8), ge=0, le=1,
                                          help="uniform range of the specular reflection")
    shininess: tuple[float, float] = param((0.1, 0.9), ge=0, le=1,
                                           help="uniform range of the shininess")


@dataclass(frozen=True)
class ObjectMaterial(ConfiguredEffect):
    """A texture of the object bank (or none), a tint and shine per configuration."""

    name: ClassVar[str] = "object_material"
    stage: ClassVar[str] = "image"
    cfg: ObjectMaterialCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        c = self.cfg
        plain = rng.random() < c.plain
        kind = "" if plain else str(c.kinds[int(rng.integers(len(c.kinds)))])
        pick = float(rng.random())
        sat = rng.uniform(*c.saturation)
        if not plain:
            sat = min(sat, c.textured_saturation)
        rgb = colorsys.hsv_to_rgb(float(rng.random()), float(sat), float(rng.uniform(*c.value)))
        repeat = float(np.exp(rng.uniform(*np.log(c.repeat))))
        look = Surface(kind, pick, tuple(float(v) for v in rgb), repeat,
                       float(rng.uniform(*c.specular)), float(rng.uniform(*c.shininess)))
        return replace(shot, object_look=look)


register_effect("object_material", lambda cfg: [ObjectMaterial(cfg)], cfg=ObjectMaterialCfg)
