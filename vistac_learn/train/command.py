"""`vistac train`: its options (declared by `TrainCfg`), the protocol switch and the handler."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from vistac.config import HelpFormatter, add_options, apply, flag_labels, option_values
from vistac_learn.train.config import PROTOCOLS, STUDY, TrainCfg, protocol_cfg

OPTIONS = tuple(f.name for f in dataclasses.fields(TrainCfg)
                if f.name not in ("data", "out", "eval_batch_size"))


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register `vistac train`."""
    study = ", ".join(f"{k}={v}" for k, v in STUDY.items())
    p = sub.add_parser(
        "train",
        help="train a model on a dataset",
        description="Train a registered model (see `vistac models`) on a dataset; select the "
        "best epoch on the validation split; resumable. Defaults are those of --protocol "
        "default (the pinch view and pinchnet, both fingers); --protocol study switches them to "
        f"the reference study's ({study}); any option overrides either.",
        formatter_class=HelpFormatter,
    )
    p.add_argument("--data", required=True, help="dataset directory")
    p.add_argument("--out", required=True, help="run folder to create (or continue)")
    p.add_argument("--protocol", default="default", choices=tuple(PROTOCOLS),
                   help="set of defaults: the project's recipe or the reference study's")
    add_options(p, TrainCfg, OPTIONS)
    p.set_defaults(**{o: None for o in OPTIONS})  # unset options keep the protocol's value
    p.add_argument("--resume", action="store_true", help="continue the run in --out")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=_handler)


def options_cfg(args: argparse.Namespace) -> TrainCfg:
    """The run's config: the protocol's defaults, then the options given."""
    given = {k: v for k, v in option_values(args, TrainCfg, OPTIONS).items() if v is not None}
    base = protocol_cfg(args.protocol, args.data, args.out)
    return apply(base, given, labels=flag_labels(TrainCfg, OPTIONS))


def _handler(args: argparse.Namespace) -> int:
    from vistac.api import train
    from vistac_learn.train.run_folder import finished

    cfg = options_cfg(args)
    done = args.resume and finished(Path(cfg.out), cfg.epochs)
    run = train(cfg, cfg.data, cfg.out, resume=args.resume, progress=not args.quiet)
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
