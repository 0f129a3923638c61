"""vistac_learn.data.pairs: rotation sets, pair datasets and their targets."""

from __future__ import annotations

import numpy as np
import pytest
from learn_fixtures import make_dataset

from vistac.dataset import open_dataset
from vistac.errors import UserError
from vistac_learn.data.pairs import PairDataset, RotationCfg, fingers_of


@pytest.fixture(scope="module")
def ds_dir(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("data") / "ds", n=8, repeats=3, size=64)


def test_rotation_sets():
    ids = np.array([5, 1, 9])
    fixed = RotationCfg().angles(ids)
    assert fixed.shape == (3, 20)
    np.testing.assert_allclose(fixed[1], np.arange(20) * 18.0)
    r1 = RotationCfg("random", n=4, seed=3).angles(ids)
    r2 = RotationCfg("random", n=4, seed=3).angles(ids[::-1])
    np.testing.assert_array_equal(r1, r2[::-1])  # per configuration, not per position
    assert ((r1 >= 0) & (r1 < 360)).all()
    assert RotationCfg("none").angles(ids).shape == (3, 1)
    with pytest.raises(UserError):
        RotationCfg("sideways").angles(ids)


def test_pair_dataset_targets(ds_dir):
    t = open_dataset(ds_dir)
    rows = t.rows("train")
    imgs = np.zeros((8, 3, 1, 4, 4), np.uint8)
    mean = PairDataset(t, rows, imgs, ("index",), "mean")
    assert len(mean) == len(rows) * 3
    b = mean.batch(np.arange(len(mean)))
    assert b["image"].shape == (len(mean), 1, 4, 4) and b["target"].shape == (len(mean), 2)
    np.testing.assert_allclose(b["target"].numpy(), t.mean_label("index")[b["row"].numpy()],
                               rtol=1e-6)
    both = PairDataset(t, rows, imgs, fingers_of("both"), "mean")
    assert both.batch(np.arange(3))["target"].shape == (3, 4)
    press = PairDataset(t, rows, imgs, ("thumb",), "press", seed=1)
    e0 = press.targets(np.arange(len(press)))
    np.testing.assert_array_equal(e0, press.targets(np.arange(len(press))))
    press.set_epoch(1)
    e1 = press.targets(np.arange(len(press)))
    assert not np.array_equal(e0, e1)
    for tgt, r in zip(e1, press.item_row, strict=True):  # every target is one of the presses
        assert np.isclose(t.cones["thumb"][r], tgt, atol=1e-6).all(axis=1).any()
    every = PairDataset(t, rows, imgs, ("index",), "all")
    assert len(every) == len(rows) * 3 * 3
    item = every[0]
    assert set(item) == {"image", "target", "row", "rot"}
