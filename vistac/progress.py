"""Progress on stderr: a bar on a terminal, plain lines in a log; `--no-progress`.

Every long loop of the library reports through `bar` (the API's ``progress=True``; the commands'
`--no-progress` switches it off). On a terminal it is a tqdm bar. When stderr is not a terminal
(``2> log``, a pipe, a job scheduler) a bar's carriage-return frames would fill the file, so it
is plain lines instead, as its loop's steps deserve:

- ``lines="each"``: one line per step of a coarse loop (a generate chunk, a tuning trial, an
  experiment cell), e.g. ``generate: 40/200 cfg, 12 s``;
- ``lines="end"``: one line when a fine-grained loop ends (objects checked), none for a bar
  that clears itself on a terminal (``leave=False``: images located, rows scored);
- ``lines="none"``: nothing (the batches of an epoch: the training loop writes a line per epoch).

`note` writes a line of its own (an epoch's summary) without breaking a bar on a terminal.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any, Literal

from vistac.config import Config, param
from vistac.config_options import add_options

PROGRESS_OPTIONS = ("no_progress",)
Lines = Literal["each", "end", "none"]


@dataclass(frozen=True)
class ProgressCfg(Config):
    """The one progress option every long-running command has."""

    no_progress: bool = param(False, help="no progress bars and no progress lines on stderr "
                              "(without a terminal there are no bars anyway: one plain line per "
                              "epoch, chunk, trial or cell)")


def add_progress_option(parser: argparse.ArgumentParser) -> None:
    """`--no-progress`, and `--quiet` as its hidden alias (the name train and tune had)."""
    add_options(parser, ProgressCfg, PROGRESS_OPTIONS)
    parser.add_argument("--quiet", dest="no_progress", action="store_true",
                        help=argparse.SUPPRESS)


def progress_wanted(args: argparse.Namespace) -> bool:
    """Whether the parsed options of a command ask for progress (no `--no-progress`)."""
    return not args.no_progress


def on_terminal() -> bool:
    """Whether stderr is a terminal (bars), not a file or a pipe (plain lines)."""
    isatty = getattr(sys.stderr, "isatty", None)
    try:
        return bool(isatty and isatty())
    except (ValueError, OSError):  # a closed stream
        return False


def bar(iterable: Iterable[Any] | None = None, *, total: int | None = None, desc: str = "",
        unit: str = "it", initial: int = 0, enabled: bool = True, lines: Lines = "end",
        leave: bool = True, smoothing: float = 0.3) -> Any:
    """A progress bar (tqdm) on a terminal, else a `LineProgress`; nothing when not `enabled`.

    Both have tqdm's ``update``, ``set_postfix``, ``set_postfix_str``, ``close`` and iterate
    over `iterable` when one is given.
    """
    if enabled and on_terminal():
        from tqdm import tqdm

        return tqdm(iterable, total=total, desc=desc, unit=unit, initial=initial, leave=leave,
                    smoothing=smoothing)
    if not enabled or (lines == "end" and not leave):
        lines = "none"
    return LineProgress(iterable, total, desc, unit, initial, lines)


def note(line: str) -> None:
    """One line on stderr, above a bar on a terminal."""
    if on_terminal():
        from tqdm import tqdm

        tqdm.write(line, file=sys.stderr)
    else:
        print(line, file=sys.stderr, flush=True)


class LineProgress:
    """Progress as plain lines on stderr (see the module's description)."""

    def __init__(self, iterable: Iterable[Any] | None, total: int | None, desc: str, unit: str,
                 initial: int, lines: Lines):
        self.iterable, self.desc, self.unit, self.lines = iterable, desc, unit, lines
        if total is None and iterable is not None and hasattr(iterable, "__len__"):
            total = len(iterable)  # type: ignore[arg-type]
        self.total, self.n, self.start, self.postfix = total, initial, initial, ""
        self.t0 = time.perf_counter()
        self.closed = False

    def __iter__(self) -> Iterator[Any]:
        try:
            for item in () if self.iterable is None else self.iterable:
                yield item
                self.update(1)
        finally:
            self.close()

    def __enter__(self) -> LineProgress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def update(self, n: int = 1) -> None:
        self.n += n
        if self.lines == "each":
            self._line()

    def set_postfix(self, **values: Any) -> None:
        self.postfix = ", ".join(f"{k}={v}" for k, v in values.items())

    def set_postfix_str(self, text: str) -> None:
        self.postfix = text

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        if self.lines == "end" and self.n > self.start:
            self._line()

    def _line(self) -> None:
        done = f"{self.n}/{self.total}" if self.total is not None else str(self.n)
        head = f"{self.desc}: " if self.desc else ""
        tail = f", {self.postfix}" if self.postfix else ""
        print(f"{head}{done} {self.unit}, {time.perf_counter() - self.t0:.0f} s{tail}",
              file=sys.stderr, flush=True)
