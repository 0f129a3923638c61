"""Typed, self-validating config dataclasses: every parameter is declared once.

A config is a frozen dataclass deriving from `Config` (``@dataclass(frozen=True)``; the base
refuses any other), complete and checked where it is made: a changed config is a new one
(`dataclasses.replace`, `apply`), checked again as a whole. Each field is declared with `param`:
its default,
a line of help and what it allows (``ge``/``gt``/``le``/``lt`` bounds, ``choices``). The type
annotation says the kind of value (``float``, ``int``, ``bool``, ``str``, ``Literal[...]``,
``tuple[float, float]``, ``tuple[str, ...]``, ``X | None``, a nested config). That one declaration
serves everything:

- construction checks every field (`Config.__post_init__`); a violation is a `ConfigError`
  naming the field, e.g. ``hysteresis: must be >= 0, got -0.1``. Configs name fields, never CLI
  options: the CLI (`apply` with `labels`, `from_options`) puts the option in the field's place,
  also where a message names another field (``{init}`` in `ConfigError`'s reason);
- `apply` updates a config tree from a nested, partial mapping (a scene file, presets, CLI
  flags); its errors name the source and the dotted key (``scene.yaml: effects.fts3.hysteresis:
  ...``) or the flag (``--friction: ...``);
- `vistac.config_options` declares argparse options from the fields (`add_options`: type,
  default, choices, help; with its `HelpFormatter`, `--help` shows each option's default and
  range) and collects the parsed flags into such a mapping (`option_values`);
- `to_dict` gives the JSON-able tree written into manifests and run folders.

Every number must be finite: nan and inf are refused for every float field of every config.
Values keep the type they were given in: an ``int`` passes as a ``float`` unchanged (a manifest
shows what the scene file said), lists become tuples. A bound is violated only by a value that
compares beyond it.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, Literal

from vistac.errors import UserError, brief, shorten

_BOUNDS = {"ge": (">=", lambda v, b: v < b), "gt": (">", lambda v, b: v <= b),
           "le": ("<=", lambda v, b: v > b), "lt": ("<", lambda v, b: v >= b)}


class ConfigError(UserError):
    """A field of a config that its declaration does not allow.

    Attributes:
        key: The field's name (dotted for a nested config).
        reason: What is wrong, e.g. ``must be >= 0, got -1``, other fields named by their names.
        others: The other fields the reason names; the template writes each as ``{name}``, e.g.
            ``ConfigError("freeze", "needs {init} (a run whose weights to keep)", ("init",))``.
    """

    def __init__(self, key: str, reason: str, others: Iterable[str] = ()):
        self.key, self.template, self.others = key, reason, tuple(others)
        self.reason = self.phrased(lambda name: name)
        super().__init__(f"{key}: {self.reason}")

    def phrased(self, name_of: Callable[[str], str]) -> str:
        """The reason with each other field written as `name_of` gives it (e.g. its option)."""
        if not self.others:
            return self.template
        return self.template.format(**{f: name_of(f) for f in self.others})


def param(default: Any = dataclasses.MISSING, *, help: str = "", ge: float | None = None,
          gt: float | None = None, le: float | None = None, lt: float | None = None,
          choices: Iterable[Any] | None = None, why: str = "", flag: str | None = None,
          metavar: str | tuple[str, ...] | None = None, distinct: str = "",
          default_factory: Any = dataclasses.MISSING) -> Any:
    """A config field: default, help and allowed values, declared once.

    Args:
        default: The default value (omit it for a required field).
        help: One line for `--help` and readers of the code.
        ge, gt, le, lt: Bounds of a number (of every element of a tuple of numbers).
        choices: Allowed values (of every element of a tuple).
        why: Said after a violated bound or choice, e.g. "the curve must stay monotone".
        flag: The CLI option, when it is not ``--`` + the field name with dashes.
        metavar: argparse's metavar of the option.
        distinct: For a tuple whose elements must be at least one and all different: the noun
            of one element, for the message (e.g. "level").
        default_factory: Instead of `default`, for a nested config.

    Returns:
        A `dataclasses.field` carrying the declaration in its metadata.
    """
    meta = {"help": help, "ge": ge, "gt": gt, "le": le, "lt": lt, "why": why, "flag": flag,
            "metavar": metavar, "choices": tuple(choices) if choices is not None else None,
            "distinct": distinct}
    return dataclasses.field(default=default, default_factory=default_factory, metadata=meta)


class Config:
    """Base of the config dataclasses: every field is checked when an instance is made.

    Subclasses are frozen dataclasses. They add cross-field checks by overriding
    `__post_init__` (calling ``super()`` first) and raising `ConfigError` with the field to
    blame. A field normalised on the way (a path made absolute) is set in `__post_init__`, with
    ``object.__setattr__`` after the checks; nothing changes a config once it is made.
    """

    def __post_init__(self) -> None:
        if not type(self).__dataclass_params__.frozen:
            raise TypeError(f"{type(self).__name__}: a Config must be @dataclass(frozen=True)")
        hints = type_hints(type(self))
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            try:
                checked = check_value(value, hints[f.name], f.metadata)
            except ValueError as exc:
                raise ConfigError(f.name, str(exc)) from None
            if checked is not value:
                object.__setattr__(self, f.name, checked)


def checked(cfg: Any, prefix: str = "") -> Any:
    """`cfg` checked again as a whole, its nested configs too: a config is checked when it is
    made, but a caller may have changed one since (``object.__setattr__``) or put an unchecked
    part in it; the work of a command starts from the checked copy.

    Raises:
        ConfigError: the first field that its declaration does not allow (dotted for a nested
            config, e.g. ``physics.friction``).
    """
    changes = {f.name: checked(getattr(cfg, f.name), f"{prefix}{f.name}.")
               for f in dataclasses.fields(cfg)
               if f.init and isinstance(getattr(cfg, f.name), Config)}
    try:
        return dataclasses.replace(cfg, **changes)
    except ConfigError as exc:  # this level's own fields (a nested one raised with its path)
        if not prefix:
            raise
        raise ConfigError(prefix + exc.key, exc.template, exc.others) from None


@functools.cache
def type_hints(cls: type) -> dict[str, Any]:
    """The resolved field annotations of a dataclass."""
    return typing.get_type_hints(cls)


def check_value(value: Any, hint: Any, meta: Mapping[str, Any] | None = None) -> Any:
    """`value` checked against a type annotation and a `param` declaration.

    Returns:
        The value, lists turned into tuples and strings into paths where the annotation asks.

    Raises:
        ValueError: what is wrong with it (without the field's name).
    """
    meta = meta or {}
    if type(value).__module__ == "numpy" and hasattr(value, "tolist"):
        value = value.tolist()  # a NumPy scalar (or array) as the Python number (or list)
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        if value is None and type(None) in args:
            return None
        (inner,) = [a for a in args if a is not type(None)]
        return check_value(value, inner, meta)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ValueError(f"expected {describe(hint)}, got {brief(value)}")
        items = args[:1] * len(value) if args[1:] == (Ellipsis,) else args
        if len(items) != len(value):
            raise ValueError(f"expected {describe(hint)}, got {brief(value)}")
        noun = meta.get("distinct")
        if noun and not value:
            raise ValueError(f"give at least one {noun}")
        if noun and len(set(value)) != len(value):
            raise ValueError(f"a {noun} appears twice ({tuple(value)})")
        return tuple(check_value(v, t, meta) for v, t in zip(value, items, strict=True))
    if origin is Literal:
        if value not in args:
            raise ValueError(f"expected one of {', '.join(map(repr, args))}, got {brief(value)}")
        return value
    if dataclasses.is_dataclass(hint):
        if not isinstance(value, hint):
            raise ValueError(f"expected a {hint.__name__}, got {brief(value)}")
        return value
    if hint is Path:
        if not isinstance(value, str | os.PathLike):
            raise ValueError(f"expected a path, got {brief(value)}")
        value = Path(value)
    elif hint is not Any and not _is_a(value, hint):
        raise ValueError(f"expected {describe(hint)}, got {brief(value)}")
    _check_allowed(value, meta)
    return value


def _is_a(value: Any, hint: Any) -> bool:
    if hint is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, hint)


def _check_allowed(value: Any, meta: Mapping[str, Any]) -> None:
    if isinstance(value, float) and not math.isfinite(value):  # every float field, in one place
        raise ValueError(f"must be a finite number, got {brief(value)}")
    why = f" ({meta['why']})" if meta.get("why") else ""
    choices = meta.get("choices")
    if choices is not None and value not in choices:
        raise ValueError(f"must be one of {', '.join(map(str, choices))}, got {brief(value)}{why}")
    for key, (sign, violates) in _BOUNDS.items():
        bound = meta.get(key)
        if bound is not None and violates(value, bound):
            raise ValueError(f"must be {sign} {bound}, got {brief(value)}{why}")


def describe(hint: Any) -> str:
    """A few words for the kind of value an annotation asks for."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is tuple:
        if args[1:] == (Ellipsis,):
            return f"a list of {_plural(args[0])}"
        return f"a list of {len(args)} {_plural(args[0])}"
    names = {float: "a number", int: "an integer", bool: "true or false", str: "a string"}
    return names.get(hint, getattr(hint, "__name__", str(hint)))


def _plural(hint: Any) -> str:
    return {float: "numbers", int: "integers", bool: "booleans", str: "strings"}.get(hint, "items")


def optional_config(hint: Any) -> type | None:
    """X of an annotation ``X | None`` where X is a dataclass (a switchable part), else None."""
    if typing.get_origin(hint) not in (types.UnionType, typing.Union):
        return None
    args = [a for a in typing.get_args(hint) if a is not type(None)]
    return args[0] if len(args) == 1 and dataclasses.is_dataclass(args[0]) else None


def apply(cfg: Any, data: Any, where: str = "", prefix: str = "",
          labels: Mapping[str, str] | None = None) -> Any:
    """A copy of config `cfg` updated from a nested, partial mapping, checked on the way.

    A switchable part (a field ``X | None``) is switched off by ``None`` or ``false``, on with
    its current (or default) parameters by ``true``, and on with changed parameters by a table
    of them. A nested config takes a table, or a config of its class in place; any other field
    takes its value.

    Args:
        cfg: The config to start from (not changed).
        data: The mapping, e.g. a scene file's section or the values of CLI flags.
        where: What `data` came from, e.g. a file name; prefixes the key in messages.
        prefix: Dotted path of `cfg` in its tree (for messages).
        labels: Name to use instead of a dotted key in messages, e.g. ``{"physics.friction":
            "--friction"}``.

    Returns:
        The updated config.

    Raises:
        UserError: an unknown key, a table expected, or a value the field does not allow; the
            message names `where` and the key (or its label).
    """
    labels = labels or {}

    def label(path: str) -> str:
        return labels.get(path) or (f"{where}: {path}" if where else path)

    if not isinstance(data, Mapping):
        raise UserError(f"{label(prefix)}: expected a table of settings, got {brief(data)}")
    fields = {f.name: f for f in dataclasses.fields(cfg)}
    hints = type_hints(type(cfg))
    changes = {}
    for key, value in data.items():
        path = f"{prefix}.{key}" if prefix else str(key)
        if key not in fields:
            path = path[:len(path) - len(str(key))] + shorten(str(key), 60)
            raise UserError(f"{label(path)}: unknown key (known: {', '.join(fields)})")
        current, part = getattr(cfg, key), optional_config(hints[key])
        target = part or hints[key]
        if isinstance(value, Config) and isinstance(target, type) and isinstance(value, target):
            changes[key] = value  # a whole part, made (and checked) already
        elif part is not None:
            if value is None or value is False:
                changes[key] = None
            elif value is True:
                changes[key] = current if current is not None else part()
            else:
                base = current if current is not None else part()
                changes[key] = apply(base, value, where, path, labels)
        elif dataclasses.is_dataclass(hints[key]):
            changes[key] = apply(current, value, where, path, labels)
        else:
            changes[key] = value
    try:
        return dataclasses.replace(cfg, **changes)
    except ConfigError as exc:
        def other(name: str) -> str:
            path = f"{prefix}.{name}" if prefix else name
            return labels.get(path, name)

        path = f"{prefix}.{exc.key}" if prefix else exc.key
        raise UserError(f"{label(path)}: {exc.phrased(other)}") from None


def to_dict(cfg: Any) -> dict[str, Any]:
    """Plain JSON-able dict of a config tree (tuples become lists, paths strings)."""
    return _jsonable(dataclasses.asdict(cfg))


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value
