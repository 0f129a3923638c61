"""`vistac train`: its options (declared by `TrainCfg`), the protocol switch and the handler."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from vistac.config import HelpFormatter, add_options, apply, flag_labels, option_values
from vistac.dataset import read_manifest
from vistac.dataset.files import check_out_dir
from vistac.errors import UserError
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


def check_paths(cfg: TrainCfg) -> None:
    """Before any work: the dataset is complete, --out and --cache-dir can be written, --init
    is a finished run.

    Raises:
        UserError: naming the option.
    """
    try:
        read_manifest(Path(cfg.data))
    except UserError as exc:
        raise UserError(f"--data {exc}") from None
    check_out_dir(cfg.out)
    if cfg.cache_dir is not None:
        check_out_dir(cfg.cache_dir, "--cache-dir")
    if cfg.init is not None and not (Path(cfg.init) / "checkpoints" / "best.pt").is_file():
        raise UserError(f"--init {cfg.init}: not a finished run (no checkpoints/best.pt)")


def _handler(args: argparse.Namespace) -> int:
    from vistac_learn.train.job import JobCfg, run_job

    cfg = options_cfg(args)
    check_paths(cfg)
    res = run_job(JobCfg(cfg, resume="yes" if args.resume else "no", progress=not args.quiet))
    print(f"run written to {res.run} (best epoch {res.best_epoch}, validation median angle "
          f"{res.objective:.2f} deg)")
    return 0
