"""`vistac train`: its options (declared by `TrainCfg` and `TrainCommandCfg`), the protocol
switch and the handler."""

from __future__ import annotations

import argparse
import dataclasses
from dataclasses import dataclass
from pathlib import Path

from vistac.config import Config, apply, param
from vistac.config_options import (
    HelpFormatter,
    add_options,
    flag_labels,
    from_options,
    option_values,
)
from vistac.progress import add_progress_option, progress_wanted
from vistac_learn.train.config import PROTOCOLS, STUDY, TrainCfg, protocol_cfg

OPTIONS = tuple(f.name for f in dataclasses.fields(TrainCfg)
                if f.name not in ("data", "out", "eval_batch_size"))
# `--help` shows each option's default under both protocols
PROTOCOL_DEFAULTS = {"--protocol study": STUDY}


@dataclass(frozen=True)
class TrainCommandCfg(Config):
    """The options of `vistac train` that are not a run's settings (`TrainCfg`); `vistac tune`
    and `vistac experiment` share `protocol`."""

    data: str = param(help="dataset directory")
    out: str = param(help="run folder to create (or continue)")
    protocol: str = param("default", choices=tuple(PROTOCOLS), help="set of defaults: the "
                          "project's recipe (default) or the reference study's (study)")
    resume: bool = param(False, help="continue the run in --out")


def add_train_options(p: argparse.ArgumentParser, options: tuple[str, ...] = OPTIONS) -> None:
    """`--protocol` and the `TrainCfg` options (unset ones keep the protocol's value)."""
    add_options(p, TrainCommandCfg, ("protocol",))
    add_options(p, TrainCfg, options, unset=True, alternatives=PROTOCOL_DEFAULTS)


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register `vistac train`."""
    p = sub.add_parser(
        "train",
        help="train a model on a dataset",
        description="Train a registered model (see `vistac models`) on a dataset; select the "
        "best epoch on the validation split; resumable. Defaults are those of --protocol "
        "default (the pinch view and pinchnet, both fingers); --protocol study switches them to "
        "the reference study's (each option below shows both where they differ); any option "
        "overrides either.",
        formatter_class=HelpFormatter,
    )
    add_options(p, TrainCommandCfg, ("data", "out"))
    add_train_options(p)
    add_options(p, TrainCommandCfg, ("resume",))
    add_progress_option(p)
    p.set_defaults(func=_handler)


def options_cfg(args: argparse.Namespace) -> TrainCfg:
    """The run's config: the protocol's defaults, then the options given."""
    given = {k: v for k, v in option_values(args, TrainCfg, OPTIONS).items() if v is not None}
    base = protocol_cfg(args.protocol, args.data, args.out)
    return apply(base, given, labels=flag_labels(TrainCfg, OPTIONS))


def _handler(args: argparse.Namespace) -> int:
    from vistac.api import train
    from vistac_learn.train.run_folder import finished

    cmd = from_options(TrainCommandCfg, args, ("data", "out", "protocol", "resume"))
    cfg = options_cfg(args)
    done = cmd.resume and finished(Path(cfg.out), cfg.epochs)
    run = train(cfg, cfg.data, cfg.out, resume=cmd.resume, progress=progress_wanted(args))
    for line in fingertip_lines(run.path):
        print(line)
    if done:
        print(f"{run.path}: already trained for {cfg.epochs} epochs; nothing to do (best epoch "
              f"{run.best_epoch}, validation median angle {run.objective:.2f} deg)")
        return 0
    print(f"run written to {run.path} (best epoch {run.best_epoch}, validation median angle "
          f"{run.objective:.2f} deg)")
    return 0


def fingertip_lines(run: Path) -> list[str]:
    """What a run's ``config.json`` says of the fingertips not found, one line per split."""
    from vistac_learn.data.tip_coverage import TipCoverage
    from vistac_learn.train.run_files import read_run_config

    counts = read_run_config(run, "train it again").get("fingertips") or {}
    return [TipCoverage.from_dict(c).line() for c in counts.values()]
