"""vistac_learn.data: reading a dataset directory, splits, cones, pair datasets, targets."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from learn_fixtures import make_dataset

from vistac_learn.data import PairDataset, RotationCfg, fingers_of, open_dataset
from vistac_sim.errors import UserError


@pytest.fixture(scope="module")
def ds_dir(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("data") / "ds", n=8, repeats=3, size=64)


def _copy(src, dst):
    import shutil

    shutil.copytree(src, dst)
    return dst


def test_open_dataset_reads_cones_sorted_by_config(ds_dir):
    t = open_dataset(ds_dir)
    assert list(t.configs["config_id"]) == list(range(8))
    for f in ("index", "thumb"):
        assert len(t.cones[f]) == 8
        assert all(c.shape == (3, 2) for c in t.cones[f])
        np.testing.assert_allclose(np.hypot(*t.mean_label(f).T), 1.0, atol=1e-12)
    # the cone of row 2 is exactly the presses of config 2
    p = t.presses[t.presses.config_id == 2]
    np.testing.assert_array_equal(t.cones["index"][2], p[["r_y_index", "r_z_index"]].to_numpy())


def test_splits_are_whole_configurations(ds_dir):
    t = open_dataset(ds_dir)
    rows = {s: set(t.rows(s)) for s in ("train", "val", "test")}
    assert rows["train"] | rows["val"] | rows["test"] == set(range(8))
    assert not (rows["train"] & rows["val"]) and not (rows["train"] & rows["test"])
    with pytest.raises(UserError, match="no configuration in split 'bogus'"):
        t.rows("bogus")


def test_incomplete_dataset_is_refused(tmp_path):
    d = make_dataset(tmp_path / "ds", n=3, repeats=2, size=32, complete=False)
    with pytest.raises(UserError, match="not complete"):
        open_dataset(d)


def test_missing_column_and_bad_label_name_file_and_row(ds_dir, tmp_path):
    d = _copy(ds_dir, tmp_path / "a")
    p = pd.read_parquet(d / "presses.parquet").drop(columns=["r_z_thumb"])
    p.to_parquet(d / "presses.parquet")
    with pytest.raises(UserError, match=r"presses.parquet: missing column\(s\) r_z_thumb"):
        open_dataset(d)
    d = _copy(ds_dir, tmp_path / "b")
    p = pd.read_parquet(d / "presses.parquet")
    p.loc[4, "r_y_index"] = 3.0
    p.to_parquet(d / "presses.parquet")
    with pytest.raises(UserError, match="row 4: \\(index\\) label"):
        open_dataset(d)
    with pytest.raises(UserError, match="manifest.json: missing"):
        open_dataset(tmp_path)


def test_real_recording_layout_without_sim_columns(ds_dir, tmp_path):
    d = _copy(ds_dir, tmp_path / "real")
    c = pd.read_parquet(d / "configs.parquet")
    sim_only = [k for k in c.columns if k.startswith(("tip_", "normal_", "force_clean_", "bbox_"))]
    c.drop(columns=sim_only).to_parquet(d / "configs.parquet")
    t = open_dataset(d)
    assert not t.has_boxes("index") and t.box(0, "index") is None


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


def test_manifest_must_be_json(tmp_path, ds_dir):
    d = _copy(ds_dir, tmp_path / "c")
    (d / "manifest.json").write_text("{not json")
    with pytest.raises(UserError, match="not valid JSON"):
        open_dataset(d)
    (d / "manifest.json").write_text(json.dumps({"complete": True}))
    assert len(open_dataset(d).configs) == 8
