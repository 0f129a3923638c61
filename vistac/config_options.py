"""Command-line options made from config fields: every option of every command is a field.

`add_options` declares argparse options from a config class's fields (type, default,
choices, help); `HelpFormatter` shows each option's default and range in `--help`;
`option_values` and `from_options` turn the parsed flags back into a checked config, and
`flag_labels` lets `vistac.config.apply` name the option in its messages. The fields
themselves, their checks and `apply` live in `vistac.config`.
"""

from __future__ import annotations

import argparse
import dataclasses
import types
import typing
from collections.abc import Iterable, Mapping
from typing import Any, Literal

from vistac.config import _BOUNDS, ConfigError, type_hints
from vistac.errors import UserError


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows after each option's help its default and what it allows, e.g. ``(default: 25;
    range: [1, 100000])``.

    The default is the action's ``default_text`` where `add_options` set one (a config field's
    default, also where the parser's default is None because a base config fills the value in),
    else the parser's default; None shows none. Switches show ``on``/``off``, lists their values
    as typed on the command line.
    """

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        notes = []
        default = getattr(action, "default_text", None)
        if default is None and action.default not in (None, argparse.SUPPRESS):
            default = shown_value(action.default)
        if default is not None and action.option_strings and "%(default)" not in text:
            notes.append(f"default: {default}")
        if getattr(action, "allowed", ""):
            notes.append(action.allowed)
        if not notes:
            return action.help
        note = "; ".join(notes).replace("%", "%%")
        return f"{text} ({note})" if text else f"({note})"


class RawDescriptionHelpFormatter(argparse.RawDescriptionHelpFormatter, HelpFormatter):
    """`HelpFormatter` keeping the description's own line breaks."""


def shown_value(value: Any) -> str:
    """A value as `--help` shows it: switches on/off, lists as typed on the command line."""
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, list | tuple):
        return " ".join(map(shown_value, value)) or "none"
    if isinstance(value, float):
        return _number(value)
    return str(value)


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() and abs(value) < 1e15 else f"{value:g}"


def allowed_range(meta: Mapping[str, Any], each: bool = False) -> str:
    """A field's bounds as `--help` shows them: ``range: [0, 1)``, ``range: > 0``; empty
    without bounds. `each`: they bound every element of a list."""
    lo = next(((k, meta[k]) for k in ("ge", "gt") if meta.get(k) is not None), None)
    hi = next(((k, meta[k]) for k in ("le", "lt") if meta.get(k) is not None), None)
    if lo is None and hi is None:
        return ""
    if lo is not None and hi is not None:
        text = (("[" if lo[0] == "ge" else "(") + f"{_number(lo[1])}, {_number(hi[1])}"
                + ("]" if hi[0] == "le" else ")"))
    else:
        key, bound = lo or hi
        text = f"{_BOUNDS[key][0]} {_number(bound)}"
    return ("range of each: " if each else "range: ") + text


def field_of(cls: type, path: str) -> tuple[dataclasses.Field, Any, Any]:
    """(field, annotation, default) of a dotted field path in a config class tree.

    The default is MISSING for a required field.
    """
    *parents, name = path.split(".")
    for part in parents:
        cls = type_hints(cls)[part]
    f = next(f for f in dataclasses.fields(cls) if f.name == name)
    default = f.default if f.default_factory is dataclasses.MISSING else f.default_factory()
    return f, type_hints(cls)[name], default


def flag_of(cls: type, path: str) -> str:
    """The CLI option of a field: its declared ``flag``, else ``--`` + its name with dashes."""
    f = field_of(cls, path)[0]
    return f.metadata.get("flag") or "--" + f.name.replace("_", "-")


def add_options(parser: argparse.ArgumentParser, cls: type, paths: Iterable[str], *,
                unset: bool = False,
                alternatives: Mapping[str, Mapping[str, Any]] | None = None
                ) -> list[argparse.Action]:
    """Add one option per field path of config class `cls`, as the field declares it.

    ``bool`` fields become switches (``--x``, and ``--no-x`` too when on by default), tuples
    ``nargs`` options, ``Literal`` fields and declared choices argparse choices; a field without
    a default is a required option. `--help` (with `HelpFormatter`) shows each field's default
    and bounds.

    Args:
        parser: Where the options go.
        cls: The config class.
        paths: Dotted field paths.
        unset: Options not given parse as None (a base config made elsewhere keeps its value);
            `--help` still shows the field's default.
        alternatives: Other sets of defaults, shown beside the field's, e.g. ``{"--protocol
            study": {"epochs": 20}}``.

    Returns:
        The options added (their ``default_text`` may be changed for `--help`).
    """
    actions = []
    for path in paths:
        f, hint, default = field_of(cls, path)
        meta = f.metadata
        kwargs: dict[str, Any] = {"help": meta.get("help") or None}
        if typing.get_origin(hint) in (types.UnionType, typing.Union):
            (hint,) = [a for a in typing.get_args(hint) if a is not type(None)]
        origin, args = typing.get_origin(hint), typing.get_args(hint)
        if hint is bool:  # a switch; one that defaults to on gets its --no- form too
            kwargs["action"] = argparse.BooleanOptionalAction if default is True else "store_true"
        elif origin is tuple:
            kwargs["nargs"] = "+" if args[1:] == (Ellipsis,) else len(args)
            kwargs["type"] = args[0]
        elif origin is Literal:
            kwargs["choices"] = args
        else:
            kwargs["type"] = hint
        if meta.get("choices") is not None:
            kwargs["choices"] = meta["choices"]
        if meta.get("metavar") is not None:
            kwargs["metavar"] = meta["metavar"]
        if default is dataclasses.MISSING:
            kwargs["required"] = True
        elif unset:
            kwargs["default"] = None
        elif hint is not bool:
            kwargs["default"] = list(default) if isinstance(default, tuple) else default
        action = parser.add_argument(flag_of(cls, path), **kwargs)
        if default is not dataclasses.MISSING and default is not None:
            others = [f"{name}: {shown_value(values[path])}"
                      for name, values in (alternatives or {}).items()
                      if path in values and values[path] != default]
            action.default_text = ", ".join([shown_value(default), *others])
        action.allowed = allowed_range(meta, each=origin is tuple)
        actions.append(action)
    return actions


def option_values(args: argparse.Namespace, cls: type, paths: Iterable[str]) -> dict[str, Any]:
    """The parsed values of `add_options` options as a nested mapping for `apply`."""
    out: dict[str, Any] = {}
    for path in paths:
        *parents, name = path.split(".")
        node = out
        for part in parents:
            node = node.setdefault(part, {})
        node[name] = getattr(args, flag_of(cls, path).lstrip("-").replace("-", "_"))
    return out


def from_options(cls: type, args: argparse.Namespace, paths: Iterable[str], **fixed: Any) -> Any:
    """A config made from parsed `add_options` options (plus `fixed` values), checked.

    Raises:
        UserError: a value its field does not allow, naming the option.
    """
    paths = list(paths)
    values = option_values(args, cls, paths) | fixed
    try:
        return cls(**values)
    except ConfigError as exc:
        def name_of(key: str) -> str:
            return flag_of(cls, key) if key in paths else key

        raise UserError(f"{name_of(exc.key)}: {exc.phrased(name_of)}") from None


def flag_labels(cls: type, paths: Iterable[str]) -> dict[str, str]:
    """Dotted field path -> CLI option, for the messages of `apply`."""
    return {p: flag_of(cls, p) for p in paths}
