"""`vistac ingest`: its options (declared by `IngestCfg` and `IngestSources`) and handler."""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

from vistac.config import Config, param
from vistac.config_options import HelpFormatter, add_options, from_options
from vistac.dataset import SplitCfg
from vistac.dataset.files import check_out_dir
from vistac.dataset.ingest.config import MAX_COLUMN, ColumnMap, IngestCfg, IngestSources
from vistac.dataset.recordings import FORCE_COLUMNS
from vistac.errors import UserError

SOURCE_OPTIONS = ("recordings", "images", "labels", "labels_sheet")
CFG_OPTIONS = ("threshold", "unit")
CRITERIA_OPTIONS = ("min_samples", "saturation", "min_force", "allow_pulling")
SPLIT_OPTIONS = ("by", "fractions")


@dataclass(frozen=True)
class IngestCommandCfg(Config):
    """The options of `vistac ingest` besides the sources (`IngestSources`) and the knobs."""

    out: Path = param(help="dataset folder to create")
    report: Path | None = param(None, help="also write a page per recording (its 50 Hz series, "
                                "grasp segments, chosen samples, rejection reasons; rejected "
                                "first) and their index report.md into this folder")
    columns: tuple[int, int, int, int, int, int] = param(
        (*FORCE_COLUMNS["thumb"], *FORCE_COLUMNS["index"]), ge=0, le=MAX_COLUMN,
        metavar=("THUMB_X", "THUMB_Y", "THUMB_Z", "INDEX_X", "INDEX_Y", "INDEX_Z"),
        help="0-based CSV columns of the forces (the two fields of `ColumnMap` in one option)")


def add_command(sub: argparse._SubParsersAction) -> None:
    """Add `vistac ingest` to the `vistac` parser."""
    p = sub.add_parser(
        "ingest",
        help="turn RH8D/FTS-3 recordings (or label spreadsheets) + images into a dataset",
        description="Split each recording into grasps at a threshold on |index F_z|, take each "
        "grasp's first extremum beyond its mean, reject unusable grasps by documented criteria "
        "(rejected.csv), and write the standard dataset layout. Recording NNN.csv belongs to "
        "image NNN.png (any image type) and keeps configuration id NNN.",
        formatter_class=HelpFormatter,
    )
    add_options(p, IngestSources, SOURCE_OPTIONS[:2])
    add_options(p, IngestCommandCfg, ("out", "report"))
    add_options(p, IngestSources, SOURCE_OPTIONS[2:])
    add_options(p, IngestCfg, CFG_OPTIONS)
    add_options(p, IngestCommandCfg, ("columns",))
    add_options(p, IngestCfg, CRITERIA_OPTIONS)
    add_options(p, IngestSources, ("objects_csv",))
    add_options(p, SplitCfg, SPLIT_OPTIONS)
    add_options(p, IngestSources, ("seed", "image_size"))
    p.set_defaults(func=_run_ingest)


def _run_ingest(args: argparse.Namespace) -> int:
    from vistac.api import ingest

    command = from_options(IngestCommandCfg, args, ("out", "report", "columns"))
    columns = ColumnMap(command.columns[:3], command.columns[3:])
    out = command.out
    check_out_dir(out)
    if command.report is not None:
        report = check_out_dir(command.report, "--report")
        if report == out.absolute() or out.absolute() in report.parents:
            raise UserError(f"--report {command.report}: inside the dataset --out {out}; the "
                            "report goes outside it")
    cfg = from_options(IngestCfg, args, CFG_OPTIONS + CRITERIA_OPTIONS, columns=columns)
    split = from_options(SplitCfg, args, SPLIT_OPTIONS)
    src = from_options(IngestSources, args, (*SOURCE_OPTIONS, "objects_csv", "seed",
                                             "image_size"), split=split)
    manifest = ingest(src, out, cfg).manifest
    print(f"wrote {out}: " + json.dumps({"counts": manifest["counts"],
                                              "rejected": manifest["rejected"]["by_reason"]}))
    if command.report is not None:
        from vistac.dataset import open_tables
        from vistac.dataset.ingest.pages import write_recordings_report

        pages, notes = write_recordings_report(open_tables(out), command.report)
        for note in notes:
            print(f"note: {note}")
        rejected = sum(1 for p in pages if p.rejected or p.error)
        print(f"recordings: {len(pages)} ({rejected} with rejected grasps); pages and index in "
              f"{command.report / 'report.md'}")
    return 0
