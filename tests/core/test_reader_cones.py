"""The reader's cones: each configuration's presses, in repeat order, whatever the table order;
a configuration without presses is refused naming its row."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from learn_fixtures import make_dataset

from vistac.dataset import open_tables
from vistac.errors import UserError


def test_cones_are_each_configurations_presses_in_repeat_order(tmp_path):
    root = make_dataset(tmp_path / "d", n=5, repeats=3, size=32)
    presses = pd.read_parquet(root / "presses.parquet")
    shuffled = presses.sample(frac=1.0, random_state=1)
    shuffled.to_parquet(root / "presses.parquet", index=False)
    tables = open_tables(root)
    for row, cid in enumerate(tables.configs["config_id"]):
        want = presses[presses["config_id"] == cid].sort_values("repeat")
        for f in ("index", "thumb"):
            np.testing.assert_array_equal(tables.cones[f][row],
                                          want[[f"r_y_{f}", f"r_z_{f}"]].to_numpy(float))


def test_configuration_without_presses_is_refused(tmp_path):
    root = make_dataset(tmp_path / "d", n=5, repeats=2, size=32)
    presses = pd.read_parquet(root / "presses.parquet")
    presses[presses["config_id"] != 3].to_parquet(root / "presses.parquet", index=False)
    with pytest.raises(UserError, match=r"configs.parquet: row 3: config_id 3 has no presses"):
        open_tables(root)
