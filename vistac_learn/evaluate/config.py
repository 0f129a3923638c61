"""`EvaluateCfg`: what `vistac evaluate` (and `vistac.evaluate`) scores, on which split, and
where the results go; and `default_out_dir`, the one rule for the default output folder."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from vistac.config import Config, ConfigError, param
from vistac_learn.data.samples import FINGER_CHOICES, ROTATION_MODES, RotationCfg
from vistac_learn.data.tip_coverage import MAX_MISSING_PCT
from vistac_learn.train.config import DEVICES

# The output folder's suffix per test-time augmentation choice (`default_out_dir`).
TTA_SUFFIX = {"recipe": "", "on": "-tta", "off": "-no-tta"}


@dataclass(frozen=True)
class EvaluateCfg(Config):
    """What `vistac evaluate` scores, on which split, and where the results go.

    Either `run` (a run folder) or `baseline` with `data`. The output folder is `out`, else
    `default_out_dir` (`out_dir` gives the one in use).
    """

    run: str | None = param(None, help="run folder (from `vistac train`)")
    baseline: Literal["geometric", "pinch"] | None = param(
        None, help="score a baseline instead of a run: geometric (surface normal) or pinch "
        "(closing axis through the contact points, friction cone)")
    data: str | None = param(None, help="dataset (default: the run's; required with --baseline)")
    split: str = param("test", choices=("train", "val", "test"), help="split to score")
    tta: Literal["recipe", "on", "off"] = param(
        "recipe", help="test-time augmentation: recipe: as the run's recipe says (on for the "
        "default recipe, off for the study's protocol; off for a baseline); on: average each "
        "configuration's rotations and, for a run, its mirrored view; off: neither")
    checkpoint: Literal["best", "last"] = param("best", help="the run's checkpoint")
    out: str | None = param(None, help="output folder (default <run>/eval/<split>, "
                            "<split>-tta with --tta on, <split>-no-tta with --tta off; with "
                            "--baseline <data>/eval/<baseline>-<split>, the same suffixes)")
    finger: str = param("index", choices=FINGER_CHOICES, help="baseline only: fingers to predict")
    rotations: str = param(RotationCfg.mode, choices=ROTATION_MODES,
                           help="baseline only: rotation set")
    n_rotations: int = param(RotationCfg.n, ge=1, le=360,
                             help="baseline only: angles per configuration")
    no_plots: bool = param(False, help="skip the PNG figures")
    device: str | None = param(None, choices=DEVICES, help="override the run's device")
    cross_dataset: bool = param(False, help="score the run on a --data other than the one it "
                                "was trained on")
    max_missing_pct: float = param(MAX_MISSING_PCT, ge=0, le=100, help="refuse to score a "
                                   "split when the fingertips of more than this share (%%) of "
                                   "its configurations are not found in their images")
    no_references: bool = param(False, help="run only: skip the noise floor and the pinch "
                                "baseline scored beside the model on simulated data")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.baseline and self.run:
            raise ConfigError("baseline", "give either {run} or {baseline}, not both",
                              ("run", "baseline"))
        if self.baseline and not self.data:
            raise ConfigError("baseline", "needs {data} (the dataset to score)", ("data",))
        if not self.baseline and not self.run:
            raise ConfigError("run", "required, or {baseline} (geometric or pinch) with {data}",
                              ("baseline", "data"))
        if self.run and not (Path(self.run) / "config.json").is_file():
            raise ConfigError("run", f"{self.run} is not a run folder (no config.json)")

    def averaged(self, recipe: bool = False) -> bool:
        """Whether test-time augmentation is on: ``tta`` on or off, else `recipe` (the run's
        `TrainCfg.tta`; False, the default, for a baseline)."""
        return {"on": True, "off": False}.get(self.tta, recipe)

    @property
    def out_dir(self) -> Path:
        """The output folder: `out`, else `default_out_dir`."""
        return Path(self.out) if self.out else default_out_dir(self)


def default_out_dir(cfg: EvaluateCfg) -> Path:
    """The default output folder of an evaluation, from the config alone (no run is read):
    ``<run>/eval/<split>``, with ``-tta`` after it for ``tta="on"`` and ``-no-tta`` for
    ``tta="off"``; for a baseline ``<data>/eval/<baseline>-<split>`` with the same suffixes."""
    suffix = TTA_SUFFIX[cfg.tta]
    if cfg.baseline:
        return Path(cfg.data) / "eval" / f"{cfg.baseline}-{cfg.split}{suffix}"
    return Path(cfg.run) / "eval" / f"{cfg.split}{suffix}"
