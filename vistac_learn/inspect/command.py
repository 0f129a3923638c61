"""`vistac inspect PATH`: its options (declared by `InspectCfg`) and handler."""

from __future__ import annotations

import argparse
import dataclasses

from vistac.config_options import HelpFormatter, add_options, from_options
from vistac_learn.inspect.config import InspectCfg

OPTIONS = tuple(f.name for f in dataclasses.fields(InspectCfg))


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register `vistac inspect`."""
    p = sub.add_parser(
        "inspect",
        help="look at a dataset (labels on the images, distributions, recordings) or a run",
        description="Inspect a dataset folder: print a summary and write a report folder "
        "(contact sheet with each fingertip's force direction drawn on the image, label "
        "distributions by family and split, rejection reasons, recordings pages for "
        "datasets with recordings, report.md). A dataset without a card gets its README.md; "
        "nothing else in it is changed. A damaged or unfinished dataset is shown as far as "
        "it is readable. Given a run folder: its worst test configurations beside its "
        "metrics (needs `vistac evaluate --run RUN` first).",
        formatter_class=HelpFormatter,
    )
    p.add_argument("path", metavar="PATH", help="dataset or run folder")
    add_options(p, InspectCfg, OPTIONS)
    p.set_defaults(func=_handler)


def _handler(args: argparse.Namespace) -> int:
    from vistac_learn.inspect.report import inspect_path

    rep = inspect_path(args.path, from_options(InspectCfg, args, OPTIONS))
    for line in rep.lines:
        print(line)
    if rep.card is not None:
        print(f"wrote the dataset card {rep.card}")
    print(f"report: {rep.out / 'report.md'} ({len(rep.files)} files, {rep.seconds:.1f} s)")
    return 0
