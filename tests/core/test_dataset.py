"""vistac.dataset: the one reader of the format, its checks and messages, and the label rule."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from learn_fixtures import make_dataset

from vistac.dataset import FINGERS, open_tables, press_row, press_rows, unit_labels
from vistac.dataset.schema import (
    FAILED_OBJECTS_TYPE,
    FORMAT_VERSION,
    LABEL_COLUMNS,
    REDRAWS_TYPE,
    box_columns,
    failed_object_counts,
    failed_objects_cell,
    force_columns,
    label_columns,
    redraw_cell,
    redraw_counts,
    with_declared_types,
)
from vistac.errors import UserError


@pytest.fixture(scope="module")
def ds_dir(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("data") / "ds", n=8, repeats=3, size=64)


def _copy(src, dst):
    shutil.copytree(src, dst)
    return dst


def test_unit_labels_convention():
    forces = np.array([[[0.1, 0.3, -0.4], [0.0, 0.0, 0.0]], [[1, -2, -2], [0, 1e-9, 0]]])
    labels = unit_labels(forces)
    np.testing.assert_allclose(labels[0, 0], [0.6, -0.8])
    assert labels[0, 1].tolist() == [0.0, -1.0]  # no (F_y, F_z): straight against the approach
    assert labels[1, 1].tolist() == [1.0, 0.0]
    np.testing.assert_allclose(np.linalg.norm(labels, axis=-1), 1.0)
    assert unit_labels(np.zeros(3)).tolist() == [0.0, -1.0]


def test_press_row_names_every_column_once():
    row = press_row(7, 2, np.arange(6.0).reshape(2, 3), unit_labels(-np.ones((2, 3))))
    assert list(row) == ["config_id", "repeat", *force_columns("index"),
                         *force_columns("thumb"), *LABEL_COLUMNS]
    assert row["force_thumb_y"] == 4.0 and row["r_z_index"] == pytest.approx(-2 ** -0.5)


def test_press_rows_put_each_finger_and_repeat_in_its_own_columns():
    """Forces (R, 2, 3) and labels (R, 2, 2) in `FINGERS` order land in the columns named for
    that finger, one row per repeat; the column names of different fingers never collide."""
    rng = np.random.default_rng(0)
    forces = rng.normal(size=(4, len(FINGERS), 3))
    labels = unit_labels(forces)
    table = pd.DataFrame(press_rows(11, forces, labels))
    assert table["repeat"].tolist() == [0, 1, 2, 3] and set(table["config_id"]) == {11}
    for i, f in enumerate(FINGERS):
        np.testing.assert_array_equal(table[force_columns(f)].to_numpy(), forces[:, i])
        np.testing.assert_array_equal(table[label_columns(f)].to_numpy(), labels[:, i])
    names = [c for f in FINGERS for c in (*force_columns(f), *label_columns(f), *box_columns(f))]
    assert len(set(names)) == len(names)
    with pytest.raises(ValueError, match="not"):
        press_rows(11, forces[:, :1], labels[:, :1])  # one finger only: refused


def test_interrupted_run_is_named(tmp_path):
    (tmp_path / ".partial").mkdir()
    with pytest.raises(UserError, match="interrupted run"):
        open_tables(tmp_path)


def test_open_tables_reads_cones_sorted_by_config(ds_dir):
    t = open_tables(ds_dir)
    assert list(t.configs["config_id"]) == list(range(8))
    for f in ("index", "thumb"):
        assert len(t.cones[f]) == 8
        assert all(c.shape == (3, 2) for c in t.cones[f])
        np.testing.assert_allclose(np.hypot(*t.mean_label(f).T), 1.0, atol=1e-12)
    # the cone of row 2 is exactly the presses of config 2
    p = t.presses[t.presses.config_id == 2]
    np.testing.assert_array_equal(t.cones["index"][2], p[["r_y_index", "r_z_index"]].to_numpy())


def test_splits_are_whole_configurations(ds_dir):
    t = open_tables(ds_dir)
    rows = {s: set(t.rows(s)) for s in ("train", "val", "test")}
    assert rows["train"] | rows["val"] | rows["test"] == set(range(8))
    assert not (rows["train"] & rows["val"]) and not (rows["train"] & rows["test"])
    with pytest.raises(UserError, match="no configuration in split 'bogus'"):
        t.rows("bogus")


def test_incomplete_dataset_is_refused(tmp_path):
    d = make_dataset(tmp_path / "ds", n=3, repeats=2, size=32, complete=False)
    with pytest.raises(UserError, match="not complete"):
        open_tables(d)


def test_missing_column_and_bad_label_name_file_and_row(ds_dir, tmp_path):
    d = _copy(ds_dir, tmp_path / "a")
    p = pd.read_parquet(d / "presses.parquet").drop(columns=["r_z_thumb"])
    p.to_parquet(d / "presses.parquet")
    with pytest.raises(UserError, match=r"presses.parquet: missing column\(s\) r_z_thumb"):
        open_tables(d)
    d = _copy(ds_dir, tmp_path / "b")
    p = pd.read_parquet(d / "presses.parquet")
    p.loc[4, "r_y_index"] = 3.0
    p.to_parquet(d / "presses.parquet")
    with pytest.raises(UserError, match="row 4: \\(index\\) label"):
        open_tables(d)
    with pytest.raises(UserError, match="manifest.json: missing"):
        open_tables(tmp_path)


def test_real_recording_layout_without_sim_columns(ds_dir, tmp_path):
    d = _copy(ds_dir, tmp_path / "real")
    c = pd.read_parquet(d / "configs.parquet")
    sim_only = [k for k in c.columns if k.startswith(("tip_", "normal_", "force_clean_", "bbox_"))]
    c.drop(columns=sim_only).to_parquet(d / "configs.parquet")
    t = open_tables(d)
    assert not t.has_boxes("index") and t.box(0, "index") is None


def test_manifest_must_be_json(tmp_path, ds_dir):
    d = _copy(ds_dir, tmp_path / "c")
    (d / "manifest.json").write_text("{not json")
    with pytest.raises(UserError, match="not valid JSON"):
        open_tables(d)
    (d / "manifest.json").write_text(json.dumps({"complete": True}))
    with pytest.raises(UserError, match="format_version missing"):
        open_tables(d)
    (d / "manifest.json").write_text(json.dumps({"complete": True,
                                                 "format_version": FORMAT_VERSION}))
    assert len(open_tables(d).configs) == 8


def test_nested_cells_round_trip_through_parquet(tmp_path):
    """`redraw_reasons` and `failed_objects` are native lists of structs: an empty cell keeps
    the declared type, and pyarrow and pandas give back the counts that were written."""
    redraws = [{}, {"unreachable": 3, "fingers_overlap": 1}]
    failed = [{}, {"box_2": {"unreachable": 5}, "ring_0": {"slipped": 2, "unreachable": 1}}]
    rows = [{"config_id": i, "redraw_reasons": redraw_cell(r), "failed_objects":
             failed_objects_cell(f)} for i, (r, f) in enumerate(zip(redraws, failed, strict=True))]
    for part in (rows[:1], rows):  # a table of empty cells alone still has the declared types
        table = with_declared_types(pa.Table.from_pylist(part))
        assert table.schema.field("redraw_reasons").type == REDRAWS_TYPE
        assert table.schema.field("failed_objects").type == FAILED_OBJECTS_TYPE
    pq.write_table(table, tmp_path / "t.parquet")
    assert pq.read_schema(tmp_path / "t.parquet").field("redraw_reasons").type == REDRAWS_TYPE
    frame = pd.read_parquet(tmp_path / "t.parquet")
    for i in range(2):
        assert redraw_counts(frame["redraw_reasons"][i]) == redraws[i]
        assert failed_object_counts(frame["failed_objects"][i]) == failed[i]
    assert [c["reason"] for c in rows[1]["redraw_reasons"]] == ["fingers_overlap", "unreachable"]


def test_format_1_is_read_and_older_or_newer_refused_in_one_line(tmp_path, ds_dir):
    """Format 1 differs only in bookkeeping columns no reader needs: it is read. Others are
    refused with what to do."""
    d = _copy(ds_dir, tmp_path / "old")
    man = json.loads((d / "manifest.json").read_text())
    for version, needle in [(1, None), (0, "make the dataset again with this vistac"),
                            (FORMAT_VERSION + 1, "update vistac"), (1.0, "make the dataset")]:
        (d / "manifest.json").write_text(json.dumps(man | {"format_version": version}))
        if needle is None:
            assert len(open_tables(d).configs) == 8
            continue
        with pytest.raises(UserError, match=needle) as err:
            open_tables(d)
        assert "\n" not in str(err.value) and "reads (1, 2)" in str(err.value)
