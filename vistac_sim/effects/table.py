"""Table: the table's colour per configuration and a brightness pattern, or a texture of the
table bank (wood, cloth, paper, photographs), on it."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vistac.config import Config, param
from vistac_sim.effects.registry import ConfiguredEffect, register_effect
from vistac_sim.render.shot import Shot, Surface, TableTexture
from vistac_sim.render.textures import TABLE_KINDS


@dataclass(frozen=True)
class TableCfg(Config):
    """Table colour and texture per configuration."""

    rgb_std: float = param(0.05, ge=0, le=1,
                           help="std of the per-channel change of the table colour")
    texture: float = param(0.04, ge=0, le=1,
                           help="relative std of the table's brightness pattern (0: plain)")
    texture_scale: float = param(0.004, gt=0, help="m, grain size of the pattern")
    texture_octaves: int = param(3, ge=1, le=12, help="layers of halving grain size")
    kinds: tuple[str, ...] = param((), choices=TABLE_KINDS,
                                   help="texture kinds of the table bank drawn from, uniformly "
                                   "(empty: no bank texture); the colour is then a tint around "
                                   "white")
    repeat: tuple[float, float] = param((3.0, 8.0), gt=0,
                                        help="bank texture repeats per metre (log-uniform)")


@dataclass(frozen=True)
class Table(ConfiguredEffect):
    """Table colour per configuration and a brightness pattern (texture) on it."""

    name: ClassVar[str] = "table"
    stage: ClassVar[str] = "image"
    cfg: TableCfg

    def __call__(self, shot: Shot, rng: np.random.Generator) -> Shot:
        c = self.cfg
        base = np.asarray(shot.table_rgb) if not c.kinds else np.ones(3)
        rgb = np.clip(base + rng.normal(0.0, c.rgb_std, 3), 0.0, 1.0)
        seed = int(rng.integers(2**31))
        texture = TableTexture(seed, c.texture, c.texture_scale, c.texture_octaves) \
            if c.texture > 0 else None
        rgb = tuple(float(v) for v in rgb)
        look = None
        if c.kinds:
            kind = str(c.kinds[int(rng.integers(len(c.kinds)))])
            repeat = float(np.exp(rng.uniform(*np.log(c.repeat))))
            look = Surface(kind, float(rng.random()), rgb, repeat, specular=0.0, shininess=0.0)
        return replace(shot, table_rgb=rgb, texture=texture, table_look=look)


register_effect("table", lambda cfg: [Table(cfg)], cfg=TableCfg)
