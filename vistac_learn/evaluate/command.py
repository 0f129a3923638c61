"""`vistac evaluate`: its options (declared by `EvaluateCfg`, `vistac_learn.evaluate.config`)
and handler (a run, or a non-learned baseline: geometric or pinch)."""

from __future__ import annotations

import argparse
import dataclasses

from vistac.config_options import HelpFormatter, add_options, from_options
from vistac.progress import add_progress_option, progress_wanted
from vistac_learn.evaluate.config import EvaluateCfg

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
