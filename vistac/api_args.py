"""The API's arguments checked before any work: each a config of its class (checked again as a
whole), a path, a whole number; a wrong one is a `UserError` naming the argument."""

from __future__ import annotations

import numbers
import os
import sys
from pathlib import Path
from typing import Any

from vistac.config import checked
from vistac.errors import UserError, brief


def config_arg(value: Any, cls: type, name: str) -> Any:
    """Argument `name`, a config of class `cls`, checked again as a whole (`checked`: a caller
    may have changed it since it was made).

    Raises:
        UserError: not a `cls` (a dict, None, ...), naming the argument; a `ConfigError`
            naming the field that is not allowed.
    """
    if not isinstance(value, cls):
        article = "an" if cls.__name__[0] in "AEIOU" else "a"
        raise UserError(f"{name}: expected {article} {cls.__name__} ({cls.__module__}."
                        f"{cls.__name__}(...)), got {brief(value)}")
    return checked(value)


def optional_config_arg(value: Any, cls: type, name: str) -> Any:
    """`config_arg` for an argument that may be None."""
    return None if value is None else config_arg(value, cls, name)


def folder_arg(value: Any, name: str) -> Path:
    """Argument `name`, a path (text or `os.PathLike`, not empty).

    Raises:
        UserError: anything else (None, a number), naming the argument.
    """
    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    if not isinstance(value, str) or not value.strip():
        raise UserError(f"{name}: expected a path (str or pathlib.Path), got {brief(value)}")
    return Path(value)


def count_arg(value: Any, name: str) -> int:
    """Argument `name`, a whole number (a NumPy integer too; not a bool, text or float).

    Raises:
        UserError: naming the argument.
    """
    if isinstance(value, numbers.Integral) and not isinstance(value, bool | np_bool()):
        return int(value)
    raise UserError(f"{name}: expected an integer, got {brief(value)}")


def np_bool() -> type:
    """NumPy's bool scalar type when NumPy is loaded (it is no `bool`), else `bool`."""
    np = sys.modules.get("numpy")
    return np.bool_ if np is not None else bool


def check_max_cells(max_cells: int | None) -> None:
    """`max_cells` of the experiments: None or a whole number >= 1."""
    if max_cells is not None:
        max_cells = count_arg(max_cells, "max_cells")
    if max_cells is not None and max_cells < 1:
        raise UserError(f"--max-cells: must be >= 1, got {max_cells}")
