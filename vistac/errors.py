"""Errors shared by every package of the project, and how their messages stay readable."""

from __future__ import annotations

import reprlib
from typing import Any

MAX_MESSAGE = 400
"""Characters of an error line the CLI prints at most (a value quoted in it may be megabytes)."""

_REPR = reprlib.Repr()  # keyword arguments only from Python 3.12
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother, _REPR.maxlong = 3, 60, 60, 40
_REPR.maxdict = _REPR.maxlist = _REPR.maxtuple = _REPR.maxset = 6


class UserError(Exception):
    """Bad input from the user (a file, an option, a data row); the message names it and why.

    The CLI prints it as one line without a traceback and exits with status 2.
    """


def brief(value: Any) -> str:
    """`repr(value)` cut to a readable size (long strings, big lists and deep tables elided)."""
    return _REPR.repr(value)


def shorten(text: str, limit: int = MAX_MESSAGE) -> str:
    """`text` cut to about `limit` characters in its middle (a message names what at its start
    and says why at its end), saying how many were left out."""
    if len(text) <= limit:
        return text
    head, tail = limit * 2 // 3, limit // 3
    return f"{text[:head]} ... ({len(text) - head - tail} characters cut) ... {text[-tail:]}"
