"""The generation config: a tree of small dataclasses, every knob declared once.

Each sub-tree lives next to the code that uses it (`HandCfg` in `vistac_sim.hand`, `PhysicsCfg`
in `vistac_sim.physics`, ...); this module assembles them. The whole tree is written into
`manifest.json` (``to_dict``) so that a dataset states exactly how it was made, and `--resume`
can refuse to continue a run made with other settings.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from vistac.config import Config, ConfigError, param, to_dict
from vistac.dataset import SplitCfg
from vistac_sim.effects import EffectsCfg
from vistac_sim.effects.presets import resolve_sections
from vistac_sim.generate.grasp_config import GraspCfg
from vistac_sim.hand.config import HandCfg
from vistac_sim.objects.config import ObjectsCfg
from vistac_sim.physics.config import PhysicsCfg
from vistac_sim.recording.config import RecordingCfg
from vistac_sim.render.config import RenderCfg

MIN_TIP_PIXELS = 3  # a fingertip drawn narrower cannot be told from noise by the tip locator


@dataclass(frozen=True)
class GenerateCfg(Config):
    """Everything `vistac generate` needs. Sub-trees default to their own defaults.

    Frozen: a preset or scene file is resolved where the config is made (`from_preset`,
    `from_file`); change a copy with `dataclasses.replace` or `vistac.config.apply`."""

    n: int = param(200, ge=1, le=10_000_000, help="number of grasp configurations")
    seed: int = param(0, ge=0, lt=2**32, help="seed of everything the run draws")
    repeats: int = param(6, ge=1, le=10_000, help="presses per configuration")
    chunk_size: int = param(50, ge=1, help="configurations per shard (unit of work and of resume)")
    hand: HandCfg = field(default_factory=HandCfg)
    objects: ObjectsCfg = field(default_factory=ObjectsCfg)
    grasp: GraspCfg = field(default_factory=GraspCfg)
    physics: PhysicsCfg = field(default_factory=PhysicsCfg)
    render: RenderCfg = field(default_factory=RenderCfg)
    effects: EffectsCfg = field(default_factory=EffectsCfg)
    recording: RecordingCfg = field(default_factory=RecordingCfg)
    split: SplitCfg = field(default_factory=SplitCfg)

    def __post_init__(self) -> None:
        super().__post_init__()
        # both fingertips in view, for procedural objects and meshes alike (a mesh is scaled to
        # the footprint); a configuration whose fingertip still leaves the view is redrawn
        room = self.render.view_extent - 4 * self.hand.tip_radius
        if self.objects.footprint[1] > room:
            raise ConfigError("objects.footprint", (
                f"MAX {self.objects.footprint[1]:g} m does not fit the view: with both "
                f"fingertips it must be <= {room:.4g} m (view_extent {self.render.view_extent:g}"
                f" m - 4 x tip_radius)"))

        tip_px = 2 * self.hand.tip_radius / self.render.view_extent * self.render.image_size
        if tip_px < MIN_TIP_PIXELS:
            need = math.ceil(MIN_TIP_PIXELS * self.render.view_extent / (2 * self.hand.tip_radius))
            raise ConfigError("render.image_size", (
                f"{self.render.image_size} px draws a fingertip {tip_px:.1f} px across; the "
                f"overlay needs >= {MIN_TIP_PIXELS} px to be found: use >= {need} px (or a "
                f"smaller view_extent)"))

    @classmethod
    def from_preset(cls, preset: str | None = None, *, scene: str | Path | None = None,
                    noise: float | None = None, recordings: bool = False,
                    **fields: Any) -> GenerateCfg:
        """A complete config from a named effect preset (``clean``, ``photo``, ``lab``, ``harsh``).

        Args:
            preset: The preset; None takes the scene file's ``preset``, else ``clean``.
            scene: A YAML or TOML scene file merged over the preset (see `from_file`).
            noise: Relative per-press force noise; wins over the scene file's ``effects.noise``.
            recordings: Also write the RH8D/FTS-3 recording CSVs.
            **fields: Any other field of the config, e.g. ``n=200, seed=1`` or
                ``physics=PhysicsCfg(friction=0.5)``.

        Raises:
            UserError: an unknown preset, an unreadable scene file, a value a field refuses.
        """
        sections = resolve_sections(preset, scene, noise)
        recording = sections["recording"]
        if recordings and not recording.write:
            recording = dataclasses.replace(recording, write=True)
        fields.setdefault("physics", sections["physics"])  # a physics= argument wins
        fields.setdefault("grasp", sections["grasp"])
        return cls(effects=sections["effects"], recording=recording, **fields)

    @classmethod
    def from_file(cls, path: str | Path, *, preset: str | None = None,
                  noise: float | None = None, recordings: bool = False,
                  **fields: Any) -> GenerateCfg:
        """A complete config from a scene file (its ``preset``, ``effects``, ``recording``,
        ``physics``, ``grasp``).

        `preset` and `noise`, when given, win over the file's; see `from_preset`.
        """
        return cls.from_preset(preset, scene=path, noise=noise, recordings=recordings, **fields)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able dict of the whole tree (tuples become lists)."""
        return to_dict(self)
