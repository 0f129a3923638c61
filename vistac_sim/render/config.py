"""The orthographic top view's settings."""

from __future__ import annotations

from dataclasses import dataclass

from vistac.config import Config, param
from vistac.dataset.schema import FINGER_RGB, TABLE_RGB


@dataclass
class RenderCfg(Config):
    """The orthographic top view."""

    image_size: int = param(227, help="image side, pixels")
    view_extent: float = param(0.16, help="m of table across the image")
    table_rgb: tuple[float, float, float] = param(TABLE_RGB, help="table colour in [0, 1]")
    index_rgb: tuple[float, float, float] = param(FINGER_RGB["index"],
                                                  help="colour the index finger is drawn in")
    thumb_rgb: tuple[float, float, float] = param(FINGER_RGB["thumb"],
                                                  help="colour the thumb is drawn in")
