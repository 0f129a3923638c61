"""`vistac train`: its options (declared by `TrainCfg`) and handler."""

from __future__ import annotations

import argparse
import dataclasses

from vistac.config import HelpFormatter, add_options, from_options
from vistac_learn.train.config import TrainCfg

OPTIONS = tuple(f.name for f in dataclasses.fields(TrainCfg) if f.name != "eval_batch_size")


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register `vistac train`."""
    p = sub.add_parser(
        "train",
        help="train a model on an image variant of a dataset",
        description="Train a registered model (see `vistac models`) on one image variant of a "
        "dataset; select the best epoch on the validation split; resumable.",
        formatter_class=HelpFormatter,
    )
    add_options(p, TrainCfg, OPTIONS)
    p.add_argument("--resume", action="store_true", help="continue the run in --out")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=_handler)


def _handler(args: argparse.Namespace) -> int:
    from vistac_learn.train.loop import train

    out = train(from_options(TrainCfg, args, OPTIONS), resume=args.resume,
                progress=not args.quiet)
    print(f"run written to {out}")
    return 0
