"""The search space of `vistac tune`: which training options vary, over what range, on what scale.

Defaults (`DEFAULT_SPACE`) cover what matters for the default recipe (pinchnet on fingertip
crops, AdamW with a one-cycle schedule): the peak learning rate and the weight decay on a log
scale, the batch size (an integer), and the crop-jitter strength of the augmentation. A YAML or
JSON file (``--space FILE``) changes them::

    init_points: 4            # random trials before the Gaussian process takes over
    params:
      lr: {low: 1.0e-4, high: 1.0e-2, scale: log}
      batch_size: {low: 8, high: 48, type: int}
      jitter: null            # not tuned (keeps the base run's value)
      epochs: {low: 5, high: 20, type: int}   # any numeric option of `vistac train`

The optimiser works on coordinates: ``log10_<name>`` for a log-scale option, the value itself
otherwise (integers are rounded by the optimiser, `bayes_opt`'s integer parameters).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from vistac.config import Config, ConfigError, param, to_dict, type_hints
from vistac.dataset.files import check_file
from vistac.errors import UserError
from vistac.safe_yaml import load_yaml
from vistac_learn.train.config import TrainCfg


@dataclass(frozen=True)
class Dim(Config):
    """One tuned option of `TrainCfg`."""

    name: str = param(help="the `vistac train` option (TrainCfg field)")
    low: float = param(help="lowest value")
    high: float = param(help="highest value")
    scale: Literal["linear", "log"] = param("linear", help="log: searched as log10")
    type: Literal["float", "int"] = param("float", help="int: rounded to integers")

    def __post_init__(self) -> None:
        super().__post_init__()
        hint = type_hints(TrainCfg).get(self.name)
        if hint not in (int, float, int | None, float | None):
            raise ConfigError("name", f"{self.name!r} is not a numeric option of `vistac "
                              "train`")
        if (hint in (int, int | None)) != (self.type == "int"):
            want = "float" if self.type == "int" else "int"
            raise ConfigError("type", f"{self.name} takes {want} values; use type: {want}")
        if not self.low < self.high:
            raise ConfigError("low", f"must be below high ({self.high}), got {self.low}")
        if self.scale == "log" and self.low <= 0:
            raise ConfigError("low", f"must be > 0 on a log scale, got {self.low}")
        if self.type == "int" and self.scale == "log":
            raise ConfigError("scale", "an integer option is searched on a linear scale")
        if self.type == "int" and not (float(self.low).is_integer()
                                       and float(self.high).is_integer()):
            raise ConfigError("low", "the bounds of an integer option are integers")

    @property
    def key(self) -> str:
        """The optimiser's coordinate name."""
        return f"log10_{self.name}" if self.scale == "log" else self.name

    def bounds(self) -> tuple:
        """`bayes_opt` bounds of the coordinate."""
        if self.scale == "log":
            return (math.log10(self.low), math.log10(self.high))
        if self.type == "int":
            return (int(self.low), int(self.high), int)
        return (float(self.low), float(self.high))

    def value(self, coord: float) -> float | int:
        """The option's value at an optimiser coordinate."""
        if self.scale == "log":
            return float(10.0 ** coord)
        return int(round(coord)) if self.type == "int" else float(coord)

    def coord(self, value: float) -> float:
        """The optimiser coordinate of an option's value."""
        return math.log10(value) if self.scale == "log" else float(value)


@dataclass(frozen=True)
class SpaceCfg(Config):
    """The search space and the optimiser's warm-up."""

    dims: tuple[Dim, ...] = param(help="tuned options")
    init_points: int = param(4, ge=0, le=1000, help="random trials before the Gaussian "
                             "process suggests")

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.dims:
            raise ConfigError("params", "nothing to tune (every parameter switched off)")
        names = [d.name for d in self.dims]
        if len(set(names)) != len(names):
            raise ConfigError("params", f"a parameter appears twice ({', '.join(names)})")

    def pbounds(self) -> dict[str, tuple]:
        return {d.key: d.bounds() for d in self.dims}

    def values(self, coords: dict[str, float]) -> dict[str, float | int]:
        """Training options of an optimiser point."""
        return {d.name: d.value(coords[d.key]) for d in self.dims}

    def coords(self, values: dict[str, float]) -> dict[str, float]:
        """Optimiser point of training options."""
        return {d.key: d.coord(values[d.name]) for d in self.dims}

    def to_json(self) -> dict[str, Any]:
        return to_dict(self)


DEFAULT_SPACE = SpaceCfg(dims=(
    Dim("lr", 3e-4, 3e-2, "log"),
    Dim("weight_decay", 1e-6, 1e-2, "log"),
    Dim("batch_size", 8, 64, type="int"),
    Dim("jitter", 0.0, 2.0),
))


def load_space(path: str | Path | None, base: SpaceCfg = DEFAULT_SPACE) -> SpaceCfg:
    """The default space, changed by a YAML or JSON file (see the module's docstring).

    Raises:
        UserError: an unreadable file, an unknown key, bad bounds; naming the file and key.
    """
    if path is None:
        return base
    path = Path(path)
    check_file(path, "--space")
    try:
        text = path.read_text()
        data = json.loads(text) if path.suffix == ".json" \
            else load_yaml(text, f"--space {path}")  # bounded aliases, 1e-5 is a number
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UserError(f"--space {path}: cannot read ({str(exc).splitlines()[0]})") from None
    data = data or {}
    if not isinstance(data, dict) or set(data) - {"params", "init_points"}:
        raise UserError(f"--space {path}: expected a table with keys params, init_points")
    dims = {d.name: d for d in base.dims}
    params = data.get("params") or {}
    if not isinstance(params, dict):
        raise UserError(f"--space {path}: params: expected a table of parameters")
    for name, spec in params.items():
        where = f"--space {path}: params.{name}"
        if spec is None or spec is False:
            dims.pop(name, None)
            continue
        if not isinstance(spec, dict):
            raise UserError(f"{where}: expected a table (low, high, scale, type) or null")
        old = dataclasses.asdict(dims[name]) if name in dims else {}
        try:
            dims[name] = Dim(**(old | spec | {"name": name}))
        except ConfigError as exc:
            raise UserError(f"{where}.{exc.key}: {exc.reason}") from None
        except TypeError:
            raise UserError(f"{where}: keys are low, high, scale, type; got "
                            f"{', '.join(map(str, spec))}") from None
    try:
        return SpaceCfg(tuple(dims.values()), data.get("init_points", base.init_points))
    except ConfigError as exc:
        raise UserError(f"--space {path}: {exc}") from None
