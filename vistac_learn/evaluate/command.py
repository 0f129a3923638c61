"""`vistac evaluate`: its options and handler (a run, or the geometric baseline)."""

from __future__ import annotations

import argparse
from pathlib import Path

from vistac.errors import UserError
from vistac_learn.data.samples import FINGER_CHOICES, ROTATION_MODES, RotationCfg
from vistac_learn.train.config import DEVICES


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register `vistac evaluate`."""
    p = sub.add_parser(
        "evaluate",
        help="score a run (or the geometric baseline) with the cone metrics",
        description="Score a trained run's best checkpoint, or the non-learned geometric "
        "baseline, on a dataset split: every thesis section-6 metric plus angular metrics per "
        "finger, a table in the study's layout, metrics.json, predictions.parquet and figures.",
    )
    p.add_argument("--run", help="run folder (from `vistac train`)")
    p.add_argument("--baseline", choices=("geometric",), help="score a baseline instead of a run")
    p.add_argument("--data", help="dataset (default: the run's; required with --baseline)")
    p.add_argument("--split", default="test", help="split to score (default test)")
    p.add_argument("--tta", action="store_true", help="test-time augmentation: average each configuration's rotations and its "
                   "mirrored view")
    p.add_argument("--checkpoint", default="best", choices=("best", "last"))
    p.add_argument("--out", help="output folder (default <run>/eval/<split>[-tta], with "
                   "--baseline <data>/eval/geometric-<split>)")
    p.add_argument("--finger", default="index", choices=FINGER_CHOICES,
                   help="baseline only: fingers to predict")
    p.add_argument("--rotations", default=RotationCfg.mode, choices=ROTATION_MODES,
                   help="baseline only: rotation set")
    p.add_argument("--n-rotations", type=int, default=RotationCfg.n, help="baseline only")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    p.add_argument("--device", choices=DEVICES, help="override the run's device")
    p.add_argument("--cross-dataset", action="store_true",
                   help="score the run on a --data other than the one it was trained on")
    p.set_defaults(func=_handler)


def _handler(args: argparse.Namespace) -> int:
    from vistac_learn.evaluate.run import evaluate_baseline, evaluate_run

    if args.baseline:
        if args.run:
            raise UserError("give either --run or --baseline, not both")
        if not args.data:
            raise UserError("--baseline needs --data")
        out = args.out or str(Path(args.data) / "eval" / f"geometric-{args.split}")
        res = evaluate_baseline(args.data, out, args.split, args.finger,
                                RotationCfg(args.rotations, args.n_rotations), args.tta,
                                not args.no_plots, progress=True)
    else:
        if not args.run:
            raise UserError("give --run RUN (or --baseline geometric --data D --out DIR)")
        res = evaluate_run(args.run, args.data, args.split, args.tta, args.checkpoint, args.out,
                           not args.no_plots, args.device, progress=True,
                           cross_dataset=args.cross_dataset)
        out = args.out or str(Path(args.run) / "eval" / (args.split + ("-tta" if args.tta
                                                                        else "")))
    print(f"{res['n_predictions']} predictions of {res['n_configs']} configurations; "
          f"results in {out}")
    return 0
