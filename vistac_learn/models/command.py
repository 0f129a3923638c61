"""`vistac models`: the registry as a table of sizes and costs."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass

from vistac.config import Config, param
from vistac.config_options import HelpFormatter, add_options, from_options
from vistac_learn.models import list_models, model_info

OPTIONS = ("in_channels", "out_features")


@dataclass(frozen=True)
class ModelsCfg(Config):
    """The options of `vistac models`: the input and output the table's sizes are for."""

    in_channels: int = param(1, ge=1, le=1024, help="image channels (1 = edge image, "
                             "3 = colour)")
    out_features: int = param(2, ge=1, le=1024, help="outputs (2 = one finger, 4 = both)")


def human(value: float, unit: str) -> str:
    """Format a count in a fixed unit with three significant digits ("0.661 G", "58.3 M").

    One unit per table column keeps the rows comparable at a glance.

    Args:
        value: a non-negative count.
        unit: "k", "M" or "G".

    Returns:
        The formatted string.
    """
    factor = {"k": 1e3, "M": 1e6, "G": 1e9}[unit]
    return f"{value / factor:.3g} {unit}"


def format_table(infos: Sequence[dict]) -> str:
    """Render model infos as a text table: name, input, params, MACs, f, w.

    Args:
        infos: dicts from `model_info`.

    Returns:
        The table, one line per model, with a header line.
    """
    header = ("name", "thesis name", "input", "params", "MACs", "f", "w")
    rows = [
        (
            i["name"], i["display"], str(i["input_size"]),
            human(i["params"], "M"), human(i["macs"], "G"),
            str(i["fc_in"]), "-" if i["fc_width"] is None else str(i["fc_width"]),
        )
        for i in infos
    ]
    widths = [max(len(r[c]) for r in (header, *rows)) for c in range(len(header))]
    left = 2  # name columns left-aligned, numbers right-aligned

    def line(row: Sequence[str]) -> str:
        return "  ".join(
            cell.ljust(width) if c < left else cell.rjust(width)
            for c, (cell, width) in enumerate(zip(row, widths, strict=True))
        ).rstrip()

    return "\n".join([line(header), *(line(r) for r in rows)])


def _run_models(args: argparse.Namespace) -> int:
    """Print the model table (the `vistac models` command).

    Args:
        args: parsed options of `ModelsCfg`.

    Returns:
        Exit code 0.
    """
    cfg = from_options(ModelsCfg, args, OPTIONS)
    infos = [model_info(name, cfg.in_channels, cfg.out_features) for name in list_models()]
    print(format_table(infos))
    print(f"MACs = multiply-accumulates of Conv2d/Linear for one {cfg.in_channels}-channel image "
          "at the model's input size.")
    return 0


def add_command(sub: argparse._SubParsersAction) -> None:
    """Add the `models` sub-command to the `vistac` parser.

    Args:
        sub: the top-level sub-parsers object.
    """
    parser = sub.add_parser(
        "models",
        help="list the registered models with parameters and multiply-accumulates",
        description="List every registered model: input size, parameters, multiply-accumulates "
        "per image, FC input size f and FC width w.",
        formatter_class=HelpFormatter,
    )
    add_options(parser, ModelsCfg, OPTIONS)
    parser.set_defaults(func=_run_models)
