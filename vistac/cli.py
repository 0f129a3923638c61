"""The `vistac` console command: a thin dispatcher over the sub-commands of both packages.

Every sub-command lives in a command module that defines ``add_command(sub)`` (its options,
each a field of a typed config, so that `--help` shows its default and range; progress on
stderr switched off by `--no-progress`, `vistac.progress`) and a small handler turning the
parsed, validated config into work. Only the chosen command's module is imported (so
`vistac generate` does not pay for importing torch, nor `vistac train` for MuJoCo);
`vistac --help` lists them all. A new sub-command is one line in `COMMANDS` plus its module.

Bad input never ends in a traceback: a malformed command line, a `UserError` (an option, file or
row its check refused) and an `OSError` (a full disk, a folder that cannot be written) are
printed as one line ``vistac COMMAND: error: ...`` (cut to a readable length: a message may
quote a value of megabytes) and exit with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from vistac.errors import UserError, shorten

# name -> (command module with `add_command(sub)`, one line of help)
COMMANDS: dict[str, tuple[str, str]] = {
    "generate": ("vistac_sim.generate.command",
                 "simulate presses and write a visuo-tactile dataset"),
    "ingest": ("vistac.dataset.ingest.command",
               "turn RH8D/FTS-3 recordings and their images into a dataset"),
    "inspect": ("vistac_learn.inspect.command",
                "see a dataset (labels on its images, distributions, recordings) or a run"),
    "models": ("vistac_learn.models.command",
               "list the model zoo with parameters and multiply-accumulates"),
    "train": ("vistac_learn.train.command", "train a model on a dataset"),
    "evaluate": ("vistac_learn.evaluate.command",
                 "score a run or a baseline with the study's metrics"),
    "tune": ("vistac_learn.tune.command", "tune training options by Bayesian optimisation"),
    "experiment": ("vistac_learn.experiments.command",
                   "sim-to-real fine-tuning and label-noise experiments"),
    "demo": ("vistac_learn.demo", "generate, train, evaluate and report on a small default"),
}


class UsageError(Exception):
    """A command line argparse cannot parse (unknown option, missing value, bad choice)."""


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (raised, printed by `main`), not usage."""

    def error(self, message: str):  # type: ignore[override]
        raise UsageError(f"{self.prog}: error: {message} (see {self.prog} --help)")


def build_parser(argv: list[str]) -> argparse.ArgumentParser:
    """The top-level parser; the full options of the command named in `argv` are loaded."""
    parser = Parser(
        prog="vistac",
        description="Visuo-tactile datasets from MuJoCo (vistac_sim) and learning on them "
        "(vistac_learn). `vistac COMMAND --help` shows a command's options.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    chosen = next((a for a in argv if not a.startswith("-")), None)
    for name, (module, help_text) in COMMANDS.items():
        if name == chosen:
            importlib.import_module(module).add_command(sub)
        else:
            sub.add_parser(name, help=help_text)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `vistac` command; returns its exit status (2 for bad input)."""
    argv = sys.argv[1:] if argv is None else argv
    # OpenCV's own warnings (e.g. "can not handle images with 32-bit samples" before an image
    # it cannot read) would print beside the one line that says what is wrong
    os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")
    if not all(a.isascii() for a in argv):  # before anything is read or written under a name
        from vistac.dataset.files import locale_problem

        for i, arg in enumerate(argv):
            problem = locale_problem(arg)
            if problem is not None:  # named after its option, as every error is
                option = argv[i - 1] if i and argv[i - 1].startswith("-") else ""
                print(f"vistac: error: {option} {problem}".replace(":  ", ": "), file=sys.stderr)
                return 2
    try:
        args = build_parser(argv).parse_args(argv)
    except UsageError as exc:
        print(one_line(exc), file=sys.stderr)
        return 2
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except (UserError, OSError) as exc:  # bad input, a full disk: one clear line, no traceback
        print(f"vistac {args.command}: error: {one_line(exc)}", file=sys.stderr)
        return 2


def one_line(exc: BaseException) -> str:
    """The message of an error on one line, cut to a readable length (`errors.MAX_MESSAGE`)."""
    return shorten(" ".join(str(exc).split()) or type(exc).__name__)


if __name__ == "__main__":
    sys.exit(main())
