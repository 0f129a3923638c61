"""Sub-commands of vistac_sim, registered into the `vistac` command."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    """Add the simulation sub-commands (generate, ...) to the parser."""
