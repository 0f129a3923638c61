"""Fixtures of the simulator tests."""

from __future__ import annotations

import numpy as np
import pytest
from ingest_fixtures import PLATEAUS, press_series, write_csv, write_png


@pytest.fixture
def folders(tmp_path):
    """Recordings and images of PLATEAUS (ids 3, 7, 12)."""
    rng = np.random.default_rng(0)
    rec, img = tmp_path / "rec", tmp_path / "img"
    rec.mkdir()
    img.mkdir()
    for cid, plateaus in PLATEAUS.items():
        write_csv(rec / f"{cid:06d}.csv", press_series(plateaus, rng))
        write_png(img / f"{cid:06d}.png")
    return rec, img
