"""The orthographic top view's settings."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from vistac.config import Config, param
from vistac.dataset.schema import FINGER_RGB, TABLE_RGB


@dataclass(frozen=True)
class RenderCfg(Config):
    """The top view: image size, the clean view's extent and colours, masks, textures."""

    image_size: int = param(227, ge=16, le=4096, help="image side, pixels")
    view_extent: float = param(0.16, gt=0, help="m of table across the image")
    table_rgb: tuple[float, float, float] = param(TABLE_RGB, ge=0, le=1,
                                                  help="table colour in [0, 1]")
    index_rgb: tuple[float, float, float] = param(FINGER_RGB["index"], ge=0, le=1,
                                                  help="colour the index finger is drawn in")
    thumb_rgb: tuple[float, float, float] = param(FINGER_RGB["thumb"], ge=0, le=1,
                                                  help="colour the thumb is drawn in")
    masks: bool = param(False, help="also write masks/NNNNNN.png per configuration (0 table, "
                        "1 object, 2 index overlay, 3 thumb overlay), aligned with the image")
    textures: str | None = param(None, metavar="DIR",
                                 help="folder of your own images (PNG, JPEG, ...), added to the "
                                 "photographs of the object and table textures (needs an "
                                 "effect that uses them, e.g. --preset photo)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.textures is not None:  # absolute: a manifest names the same folder anywhere
            object.__setattr__(self, "textures", str(Path(self.textures).expanduser().resolve()))
