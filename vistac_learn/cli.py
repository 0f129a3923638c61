"""Sub-commands of vistac_learn, registered into the `vistac` command."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    """Add the learning sub-commands (models, train, evaluate, ...) to the parser."""
    from vistac_learn import models

    models.add_command(sub)
    from vistac_learn import evaluate, train

    train.add_command(sub)
    evaluate.add_command(sub)
    from vistac_learn import demo

    demo.add_command(sub)
