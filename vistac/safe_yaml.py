"""YAML read safely: no code, bounded alias expansion, numbers such as ``1e-2`` read as numbers.

PyYAML's `safe_load` builds no objects of arbitrary classes, but two things remain:

- Aliases: ``a: &a [x, x]`` / ``b: &b [*a, *a]`` / ... loads fast (each alias is one shared
  object), but anything that walks the result (a check, a message quoting the value) visits
  every path: ten lines make 10^9 items, a 40 s walk into a MemoryError. `load_yaml` counts
  the items the document expands to and refuses more than `MAX_ITEMS`, and refuses recursion.
- YAML 1.1 reads ``1e-2`` (no dot) and ``1.5e3`` (no exponent sign) as strings; YAML 1.2 and
  every user read them as numbers. `Loader` does too.
"""

from __future__ import annotations

import re
from typing import Any

import yaml

from vistac.errors import UserError

MAX_ITEMS = 100_000
"""At most this many values (scalars, lists, tables, counted as often as aliases repeat them)
in one document: scene files hold tens."""

_FLOAT = re.compile(r"""^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$""")
"""Exponent notation YAML 1.1 misses: no dot (``1e-2``) or no exponent sign (``1.5e3``)."""


class Loader(yaml.SafeLoader):
    """`yaml.SafeLoader` that also reads ``1e-2`` and ``1.5e3`` as floats."""


Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT, list("-+0123456789."))


def load_yaml(text: str, source: str) -> Any:
    """The value of a YAML document, checked for alias bombs and recursion.

    Args:
        text: the document.
        source: what it came from (a file name), for messages.

    Raises:
        UserError: a parse error, nesting too deep, a recursive alias, or more than
            `MAX_ITEMS` values once aliases are expanded.
    """
    try:
        data = yaml.load(text, Loader=Loader)  # noqa: S506 (a SafeLoader)
    except yaml.YAMLError as exc:
        raise UserError(f"{source}: cannot parse: {' '.join(str(exc).split())}") from None
    except RecursionError:
        raise UserError(f"{source}: lists or tables nested too deeply") from None
    items = expanded_size(data, source)
    if items > MAX_ITEMS:
        raise UserError(f"{source}: expands to {items:.3g} values through its aliases (at most "
                        f"{MAX_ITEMS}); write the values out or remove the aliases")
    return data


def expanded_size(data: Any, source: str = "document") -> int:
    """How many values `data` holds, a shared (aliased) part counted at each place it appears.

    Linear in the number of distinct objects (each is sized once), whatever the expansion.

    Raises:
        UserError: a list or table that contains itself (a recursive alias).
    """
    sizes: dict[int, int] = {}
    open_: set[int] = set()

    def size(value: Any) -> int:
        if not isinstance(value, list | dict):
            return 1
        key = id(value)
        if key in sizes:
            return sizes[key]
        if key in open_:
            raise UserError(f"{source}: an alias refers to a list or table that contains it")
        open_.add(key)
        parts = [*value.keys(), *value.values()] if isinstance(value, dict) else value
        total = 1 + sum(size(v) for v in parts)
        open_.discard(key)
        sizes[key] = total
        return total

    try:
        return size(data)
    except RecursionError:
        raise UserError(f"{source}: lists or tables nested too deeply") from None
