"""Assignment of whole configurations (or whole objects) to train / val / test."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from vistac.config import Config, ConfigError, param
from vistac.dataset.schema import SPLITS
from vistac.errors import UserError


@dataclass(frozen=True)
class SplitCfg(Config):
    """How configurations are split (whole configurations or whole objects)."""

    by: Literal["config", "object"] = param("config", flag="--split-by",
                                            help="split whole configurations or whole objects")
    fractions: tuple[float, float, float] = param((0.7, 0.15, 0.15), flag="--split",
                                                  metavar=("TRAIN", "VAL", "TEST"),
                                                  ge=0, le=1, help="split fractions, each "
                                                  "in [0, 1], summing to 1")

    def __post_init__(self) -> None:
        super().__post_init__()
        if abs(sum(self.fractions) - 1) > 1e-6:
            terms = " + ".join(f"{f:g}" for f in self.fractions)
            raise ConfigError("fractions", f"must sum to 1, got {terms} = "
                              f"{sum(self.fractions):g}")


def assign_splits(configs, by: str, fractions, seed: int) -> np.ndarray:
    """Split labels for whole configurations, or whole objects when `by == "object"`.

    `configs`: the configs table, or any mapping of its `config_id` / `object_id` columns.
    """
    fr = np.asarray(fractions, float)
    if fr.shape != (3,) or not np.isfinite(fr).all() or (fr < 0).any() \
            or abs(fr.sum() - 1) > 1e-6:
        raise UserError(f"split fractions must be three numbers in [0, 1] summing to 1, got "
                        f"{fractions}")
    rng = np.random.default_rng([seed, 0x5B1])
    keys = np.asarray(configs["object_id"] if by == "object" else configs["config_id"])
    units = np.unique(keys)  # sorted
    units = units[rng.permutation(len(units))]
    bounds = np.round(np.cumsum(fr) * len(units)).astype(int)
    label_of = {u: SPLITS[int(np.searchsorted(bounds, i, side="right"))] for i, u in
                enumerate(units)}
    return np.array([label_of[k] for k in keys])
