"""The `vistac` console command. Each package registers its own sub-commands."""

from __future__ import annotations

import argparse
import sys

from vistac_sim.errors import UserError


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with the sub-commands of both packages."""
    from vistac_learn import cli as learn_cli
    from vistac_sim import commands as sim_commands

    parser = argparse.ArgumentParser(
        prog="vistac",
        description="Visuo-tactile datasets from MuJoCo (vistac_sim) and learning on them "
        "(vistac_learn).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    sim_commands.register(sub)
    learn_cli.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `vistac` command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except UserError as exc:  # bad input: one clear line, no traceback
        print(f"vistac {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
