"""`vistac evaluate`: its options (declared by `EvaluateCfg`) and handler (a run, or a
non-learned baseline: geometric or pinch)."""

from __future__ import annotations

import argparse
import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from vistac.config import Config, ConfigError, HelpFormatter, add_options, from_options, param
from vistac.progress import add_progress_option, progress_wanted
from vistac_learn.data.samples import FINGER_CHOICES, ROTATION_MODES, RotationCfg
from vistac_learn.data.tip_coverage import MAX_MISSING_PCT
from vistac_learn.train.config import DEVICES


@dataclass(frozen=True)
class EvaluateCfg(Config):
    """What `vistac evaluate` scores, on which split, and where the results go."""

    run: str | None = param(None, help="run folder (from `vistac train`)")
    baseline: Literal["geometric", "pinch"] | None = param(
        None, help="score a baseline instead of a run: geometric (surface normal) or pinch "
        "(closing axis through the contact points, friction cone)")
    data: str | None = param(None, help="dataset (default: the run's; required with --baseline)")
    split: str = param("test", choices=("train", "val", "test"), help="split to score")
    tta: bool = param(False, help="test-time augmentation: average each configuration's "
                      "rotations and its mirrored view (default: as the run's recipe says, "
                      "on for the default recipe; always with --baseline)")
    no_tta: bool = param(False, help="run only: no test-time augmentation, whatever the run's "
                         "recipe says")
    checkpoint: Literal["best", "last"] = param("best", help="the run's checkpoint")
    out: str | None = param(None, help="output folder (default <run>/eval/<split>[-tta], with "
                            "--baseline <data>/eval/<baseline>-<split>)")
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
        if self.tta and self.no_tta:
            raise ConfigError("tta", "give either --tta or --no-tta, not both")
        if self.baseline and self.run:
            raise ConfigError("baseline", "give either --run or --baseline, not both")
        if self.baseline and not self.data:
            raise ConfigError("baseline", "needs --data")
        if not self.baseline and not self.run:
            raise ConfigError("run", "required (or --baseline geometric|pinch --data D)")
        if self.run and not (Path(self.run) / "config.json").is_file():
            raise ConfigError("run", f"{self.run} is not a run folder (no config.json)")

    @property
    def run_tta(self) -> bool | None:
        """A run's test-time augmentation: on, off, or None (as its recipe says)."""
        return True if self.tta else (False if self.no_tta else None)

    @property
    def out_dir(self) -> Path:
        """The output folder, its default filled in."""
        if self.out:
            return Path(self.out)
        if self.baseline:
            return Path(self.data) / "eval" / f"{self.baseline}-{self.split}"
        return Path(self.run) / "eval" / (self.split + ("-tta" if self.tta else ""))


OPTIONS = tuple(f.name for f in dataclasses.fields(EvaluateCfg))


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register `vistac evaluate`."""
    p = sub.add_parser(
        "evaluate",
        help="score a run (or a non-learned baseline) with the cone metrics",
        description="Score a trained run's best checkpoint, or a non-learned baseline "
        "(geometric or pinch), on a dataset split: every thesis section-6 metric plus angular "
        "metrics per finger, a table in the study's layout, metrics.json, predictions.parquet "
        "and figures. On simulated data the table also shows the noise floor (the clean forces "
        "scored as a prediction) and, beside a run, the pinch baseline.",
        formatter_class=HelpFormatter,
    )
    add_options(p, EvaluateCfg, OPTIONS)
    add_progress_option(p)
    p.set_defaults(func=_handler)


def _handler(args: argparse.Namespace) -> int:
    from vistac.api import evaluate

    ev = evaluate(from_options(EvaluateCfg, args, OPTIONS), progress=progress_wanted(args))
    print(ev.table)
    if ev.result.get("fingertips_line"):
        print(ev.result["fingertips_line"])
    print(f"{ev.result['n_predictions']} predictions of {ev.result['n_configs']} "
          f"configurations; results in {ev.path}")
    return 0
