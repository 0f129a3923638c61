"""`InspectCfg`: what `vistac inspect` shows and where the report goes."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from vistac.config import Config, param


@dataclass(frozen=True)
class InspectCfg(Config):
    """Settings of `vistac inspect` (a dataset or a run)."""

    out: str | None = param(None, help="report folder (default: PATH-inspect beside PATH)")
    per_group: int = param(3, ge=1, le=100, help="contact sheet: configurations per split and "
                           "object family")
    max_tiles: int = param(48, ge=1, le=1000, help="contact sheet: most configurations shown")
    columns: int = param(8, ge=1, le=50, help="contact sheet: tiles per row")
    tile: int = param(192, ge=32, le=1024, help="contact sheet: tile side (px)")
    seed: int = param(0, ge=0, lt=2**32, help="seed of the contact sheet's sample")
    max_pages: int = param(100, ge=0, le=100_000, help="recordings: most pages drawn (rejected "
                           "first)")
    worst: int = param(16, ge=1, le=1000, help="run: worst test configurations shown")
    split: str = param("test", choices=("train", "val", "test"),
                       help="run: the evaluated split to show")

    def out_dir(self, path: str | Path) -> Path:
        """The report folder for `path`, its default filled in."""
        if self.out:
            return Path(self.out)
        p = Path(path)
        return p.parent / f"{p.resolve().name}-inspect"
