"""vistac_learn.data.located_boxes: finger boxes read off the images of a dataset without any
(as `vistac ingest` leaves it), so that the study's views train on it."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest

from vistac.dataset import FINGERS, open_tables
from vistac.dataset.schema import box_columns
from vistac_learn.data.located_boxes import box_table, locate_boxes, mask_box
from vistac_learn.data.samples import SampleSet, SampleSpec
from vistac_learn.data.variants import read_rgb
from vistac_learn.data.views import make_view
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.loop import train_run_folder

SIDE_PX = 4.0  # largest error of a located box's side (measured 2.3 px on the 24 images)
MEAN_PX = 1.0  # mean absolute error of a side (measured 0.23 px)


@pytest.fixture(scope="module")
def no_boxes(small_dataset, tmp_path_factory):
    """The generated dataset with every ``bbox_*`` value NaN, as after `vistac ingest`."""
    d = tmp_path_factory.mktemp("noboxes") / "d"
    shutil.copytree(small_dataset, d, ignore=shutil.ignore_patterns("cache"))
    c = pd.read_parquet(d / "configs.parquet")
    for f in FINGERS:
        c[box_columns(f)] = np.nan
    c.to_parquet(d / "configs.parquet")
    return d


def _sides(b: np.ndarray) -> np.ndarray:
    return np.array([b[0], b[1], b[0] + b[2], b[1] + b[3]])


def test_mask_box_convention():
    m = np.zeros((10, 12), bool)
    m[2:5, 3:9] = True  # rows 2..4, columns 3..8
    assert mask_box(m).tolist() == [3.0, 2.0, 6.0, 3.0]
    assert mask_box(np.zeros((4, 4), bool)) is None


def test_located_boxes_agree_with_simulator(small_dataset):
    t = open_tables(small_dataset)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    errs = []
    for row in range(len(t.configs)):
        found = locate_boxes(read_rgb(t.image_path(row)), colours)
        for f in FINGERS:
            assert found[f].ok, (row, f, found[f].reason)
            errs.append(_sides(found[f].box) - _sides(t.box(row, f)))
    errs = np.abs(np.array(errs))
    assert errs.max() <= SIDE_PX, errs.max(axis=0)
    assert errs.mean() <= MEAN_PX, errs.mean(axis=0)


def test_box_table_keeps_the_simulators_boxes(small_dataset, no_boxes, tmp_path):
    t = open_tables(small_dataset)
    own = box_table(t, cache_dir=tmp_path)
    for row in range(len(t.configs)):
        for f in FINGERS:
            assert np.array_equal(own.box(row, f), t.box(row, f))  # exact, not located
    # a generated dataset's samples do not change: its own boxes, no table made
    spec = SampleSpec(make_view("edge-crop"), 32, ("index",))
    ds = SampleSet(t, t.rows(None), spec)
    assert ds.boxes is None
    located = box_table(open_tables(no_boxes), cache_dir=tmp_path)
    assert located.frame["index_ok"].all() and located.frame["thumb_ok"].all()
    again = box_table(open_tables(no_boxes), cache_dir=tmp_path)  # from the cache
    pd.testing.assert_frame_equal(located.frame, again.frame)


def test_study_views_render_without_boxes(no_boxes, tmp_path):
    t = open_tables(no_boxes)
    assert not t.has_boxes("index")
    boxes = box_table(t, cache_dir=tmp_path)
    ds = SampleSet(t, t.rows(None), SampleSpec(make_view("edge-index"), 32, ("index",)),
                   boxes=boxes)
    batch = ds.batch(np.arange(4))
    assert batch["image"].shape == (4, 1, 32, 32) and batch["found"].all()
    # a finger not found: that row's sample is masked out, not an error
    boxes.frame.loc[1, "index_ok"] = False
    boxes.frame.loc[1, "index_reason"] = "0 px of its colour"
    ds = SampleSet(t, t.rows(None), SampleSpec(make_view("edge-index"), 32, ("index",)),
                   boxes=boxes)
    rows = list(ds.item_row)
    item = ds[rows.index(1)]
    assert not item["found"].any() and not item["image"].any()


def test_study_protocol_trains_on_a_dataset_without_boxes(no_boxes, tmp_path):
    cfg = protocol_cfg("study", str(no_boxes), str(tmp_path / "run"), model="smallconv",
                       epochs=1, n_rotations=1, batch_size=8, device="cpu",
                       cache_dir=str(tmp_path / "cache"))
    run = train_run_folder(cfg, progress=False)
    assert (run / "checkpoints" / "best.pt").exists()
    meta = json.loads((run / "config.json").read_text())
    assert all(c["missing"] == 0 and c["what"] == "finger boxes"
               for c in meta["fingertips"].values())
