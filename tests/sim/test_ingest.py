"""`vistac ingest`: the dataset, error paths, spreadsheets, the round trip with generate."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from ingest_fixtures import (
    PLATEAUS,
    direction,
    no_leftovers,
    press_series,
    recordings_with_rejections,
    write_csv,
    write_png,
)

from vistac.dataset import SplitCfg
from vistac.dataset.ingest.config import IngestSources
from vistac.dataset.ingest.run import ingest
from vistac.errors import UserError


# ---------------------------------------------------------------------------- the dataset
def test_ingest_synthetic_recordings(folders, tmp_path):
    from vistac.dataset import open_tables

    rec, img = folders
    out = tmp_path / "ds"
    man = ingest(IngestSources(images=img, recordings=rec), out)
    assert man["complete"] and man["counts"]["configs"] == 3
    assert man["counts"]["presses"] == sum(map(len, PLATEAUS.values()))
    assert man["counts"]["rejected"] == 0
    tables = open_tables(out)
    cfg, prs = tables.configs, tables.presses
    assert cfg["config_id"].tolist() == [3, 7, 12]
    assert cfg["image"].tolist() == ["000003.png", "000007.png", "000012.png"]
    for col in ("bbox_index_x", "force_clean_thumb_z", "normal_index_y", "px_per_m"):
        assert cfg[col].isna().all()
    assert set(cfg["split"]) <= {"train", "val", "test"}
    for cid, plateaus in PLATEAUS.items():
        rows = prs[prs["config_id"] == cid]
        assert rows["repeat"].tolist() == list(range(len(plateaus)))
        for (_, r), p in zip(rows.iterrows(), plateaus, strict=True):
            want = direction(p)
            for k, f in enumerate(("index", "thumb")):
                got = np.array([r[f"r_y_{f}"], r[f"r_z_{f}"]])
                assert np.degrees(np.arccos(np.clip(got @ want[k], -1, 1))) < 1.0
            # the sample sits near the peak: force in N close to the plateau (+ overshoot)
            assert r["force_index_z"] == pytest.approx(p[0][2] / 1000 * 1.05, rel=0.03)
    assert (out / "images" / "000007.png").read_bytes() == (img / "000007.png").read_bytes()
    assert pd.read_csv(out / "rejected.csv").empty


def test_ingest_lists_rejected_grasps(tmp_path):
    rec, img = recordings_with_rejections(tmp_path)
    out = tmp_path / "ds"
    man = ingest(IngestSources(images=img, recordings=rec), out)
    assert man["rejected"]["by_reason"] == {"saturated": 2}
    assert man["dropped_configs"] == [{"config_id": 2, "name": "000002",
                                       "reason": "no_usable_grasp"}]
    rej = pd.read_csv(out / "rejected.csv")
    assert rej[["source", "config_id", "repeat", "reason"]].values.tolist() == [
        ["000001.csv", 1, 1, "saturated"], ["000002.csv", 2, 0, "saturated"]]
    assert (rej["line"] >= 2).all() and (rej["end_line"] > rej["line"]).all()
    prs = pd.read_parquet(out / "presses.parquet")
    assert prs["repeat"].tolist() == [0, 2]  # repeats keep their segment number
    assert not (out / "images" / "000002.png").exists()


def test_non_numeric_names_objects_and_split_by_object(tmp_path):
    rng = np.random.default_rng(3)
    rec, img = tmp_path / "rec", tmp_path / "img"
    rec.mkdir()
    img.mkdir()
    names = ["mug_a", "mug_b", "box_a", "box_b", "can_a", "can_b"]
    for n in names:
        write_csv(rec / f"{n}.csv", press_series([[[0, 100, -1000], [0, 50, -900]]] * 2, rng))
        cv2.imwrite(str(img / f"{n}.jpg"), np.full((40, 60, 3), 90, np.uint8))
    objs = tmp_path / "objects.csv"
    objs.write_text("name,object_id\n" + "".join(f"{n},{n.split('_')[0]}\n" for n in names))
    out = tmp_path / "ds"
    ingest(IngestSources(images=img, recordings=rec, objects_csv=objs, split=SplitCfg("object"),
                         image_size=32), out)
    cfg = pd.read_parquet(out / "configs.parquet")
    assert cfg["config_id"].tolist() == list(range(6))  # name order: box_a, box_b, can_a, ...
    assert cfg["recording"].tolist() == sorted(f"{n}.csv" for n in names)
    assert cfg.groupby("object_id")["split"].nunique().max() == 1
    assert cv2.imread(str(out / "images" / "box_a.png")).shape == (32, 32, 3)


# ------------------------------------------------------------------------------ the errors
def _expect_error(tmp_path, rec, img, *needles, **kw):
    out = tmp_path / "ds"
    with pytest.raises(UserError) as exc:
        ingest(IngestSources(images=img, recordings=rec, **kw), out)
    for n in needles:
        assert n in str(exc.value), str(exc.value)
    no_leftovers(out)
    return str(exc.value)


def test_error_image_without_recording_and_recording_without_image(folders, tmp_path):
    rec, img = folders
    write_png(img / "000099.png")
    (rec / "000003.csv").rename(rec / "000004.csv")
    msg = _expect_error(tmp_path, rec, img, "000099.png: image without a recording",
                        "000003.png: image without a recording",
                        "000004.csv: recording without an image")
    assert msg.startswith("3 problem(s)")


@pytest.mark.parametrize("mutate, needles", [
    (lambda lines: lines.__setitem__(5, lines[5] + ",7"), ["000007.csv", "line 6", "saw 21"]),
    (lambda lines: lines.__setitem__(9, lines[9].replace(",", ",x", 1).rsplit(",", 1)[0]
                                     + ",abc"), ["000007.csv: line 10", "'abc'", "column 19"]),
    (lambda lines: lines.__setitem__(12, ",".join(lines[12].split(",")[:16])),
     ["000007.csv: line 13", "missing field", "only 16 fields"]),
    (lambda lines: lines.__setitem__(0, ",".join(f"h{i}" for i in range(15))),
     ["000007.csv: line 1", "missing columns", "15 fields"]),
    (lambda lines: lines.__setitem__(20, ""), ["000007.csv: line 21"]),
    (lambda lines: lines.__setitem__(slice(0, None), []), ["000007.csv: line 1", "empty"]),
    (lambda lines: lines.__setitem__(slice(1, None), []), ["000007.csv: line 2", "no data"]),
])
def test_error_bad_rows_name_file_and_line(folders, tmp_path, mutate, needles):
    rec, img = folders
    path = rec / "000007.csv"
    lines = path.read_text().splitlines()
    mutate(lines)
    path.write_text("\n".join(lines) + ("\n" if lines else ""))
    _expect_error(tmp_path, rec, img, *needles)


def test_error_unreadable_file_and_folders(folders, tmp_path):
    rec, img = folders
    (rec / "000012.csv").write_bytes(b"\xff\xfe\x00binary")
    _expect_error(tmp_path, rec, img, "000012.csv: unreadable")
    _expect_error(tmp_path, tmp_path / "nope", img, "no such recording folder")
    (img / "000003.png").write_bytes(b"not a png")
    (rec / "000012.csv").unlink()
    (img / "000012.png").unlink()
    _expect_error(tmp_path, rec, img, "000003.png: unreadable image")


def test_error_out_in_use_and_object_split_without_mapping(folders, tmp_path):
    rec, img = folders
    out = tmp_path / "ds"
    out.mkdir()
    (out / "x").write_text("keep me")
    with pytest.raises(UserError, match=r"not empty and holds no dataset \(it holds x\)"):
        ingest(IngestSources(images=img, recordings=rec), out)
    assert (out / "x").read_text() == "keep me"
    (out / "x").unlink()
    out.rmdir()
    _expect_error(tmp_path, rec, img, "--objects-csv", split=SplitCfg("object"))


def test_failure_while_writing_leaves_nothing(folders, tmp_path, monkeypatch):
    from vistac.dataset import files

    rec, img = folders
    out = tmp_path / "ds"

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(files, "atomic_write_json", boom)
    with pytest.raises(OSError, match="disk full"):
        ingest(IngestSources(images=img, recordings=rec), out)
    no_leftovers(out)


def test_cli_reports_errors_in_one_line(folders, tmp_path, capsys):
    from vistac.cli import main

    rec, img = folders
    (rec / "000003.csv").unlink()
    rc = main(["ingest", "--recordings", str(rec), "--images", str(img), "--out",
               str(tmp_path / "ds")])
    assert rc == 2
    assert "000003.png: image without a recording" in capsys.readouterr().err
    (img / "000003.png").unlink()
    rc = main(["ingest", "--recordings", str(rec), "--images", str(img), "--out",
               str(tmp_path / "ds"), "--threshold", "0.2", "--columns", "14", "15", "16", "17",
               "18", "19"])
    assert rc == 0
    man = json.loads((tmp_path / "ds" / "manifest.json").read_text())
    assert man["config"]["ingest"]["threshold"] == 0.2


# -------------------------------------------------------------------------- spreadsheets
def write_xlsx(path: Path, rows, header=True) -> Path:
    import openpyxl

    wb = openpyxl.Workbook()
    ws = wb.active
    if header:
        ws.append(["image", "r_y index", "r_z index", "r_y thumb", "r_z thumb"])
    for r in rows:
        ws.append(list(r))
    wb.save(path)
    return path


def test_labels_spreadsheet_alone(tmp_path):
    img = tmp_path / "img"
    img.mkdir()
    for n in ("a", "b"):
        write_png(img / f"{n}.png")
    s = 1 / np.sqrt(2)
    xlsx = write_xlsx(tmp_path / "labels.xlsx", [
        ("a.png", s, -s, 0.0, -1.0), ("a.png", 0.6, -0.8, 0.1, -0.99),
        ("b", 0.0, 0.0, 0.0, -1.0), ("b", 0.3, -0.9539392, -0.2, -0.9797959)])
    out = tmp_path / "ds"
    man = ingest(IngestSources(images=img, labels=xlsx), out)
    prs = pd.read_parquet(out / "presses.parquet")
    assert len(prs) == 3 and man["rejected"]["by_reason"] == {"zero_label": 1}
    norms = np.hypot(prs["r_y_thumb"], prs["r_z_thumb"])
    assert np.allclose(norms, 1)
    assert prs["force_index_z"].isna().all()
    rej = pd.read_csv(out / "rejected.csv")
    assert rej[["line", "reason"]].values.tolist() == [[4, "zero_label"]]


def test_labels_spreadsheet_errors(tmp_path):
    img = tmp_path / "img"
    img.mkdir()
    write_png(img / "a.png")
    xlsx = write_xlsx(tmp_path / "l.xlsx", [("a.png", 0.6, "oops", 0, -1),
                                            ("zz.png", 0, -1, 0, -1)])
    with pytest.raises(UserError) as exc:
        ingest(IngestSources(images=img, labels=xlsx), tmp_path / "ds")
    assert "l.xlsx: sheet 'Sheet', row 2: non-numeric cell 'oops' in column C" in str(exc.value)
    xlsx = write_xlsx(tmp_path / "l2.xlsx", [("zz.png", 0, -1, 0, -1)])
    with pytest.raises(UserError) as exc:
        ingest(IngestSources(images=img, labels=xlsx), tmp_path / "ds")
    msg = str(exc.value)
    assert "l2.xlsx: row 2: image 'zz.png' not in" in msg and "a.png: image without label" in msg
    (tmp_path / "bad.xlsx").write_text("no zip")
    with pytest.raises(UserError, match="bad.xlsx: not a readable xlsx"):
        ingest(IngestSources(images=img, labels=tmp_path / "bad.xlsx"), tmp_path / "ds")
    no_leftovers(tmp_path / "ds")


def test_labels_spreadsheet_checked_against_recordings(folders, tmp_path):
    rec, img = folders
    rows = []
    for cid, plateaus in PLATEAUS.items():
        for p in plateaus[:2]:  # the operator kept only two grasps
            d = direction(p)
            rows.append((f"{cid:06d}.png", *d[0], *d[1]))
    xlsx = write_xlsx(tmp_path / "l.xlsx", rows, header=False)
    out = tmp_path / "ds"
    man = ingest(IngestSources(images=img, recordings=rec, labels=xlsx), out)
    check = man["labels_check"]
    assert check["configs_compared"] == 3 and check["grasp_count_mismatch"] == 3
    assert check["median_angle_index_deg"] < 1.0
    cfg = pd.read_parquet(out / "configs.parquet")
    assert cfg["sheet_grasps"].tolist() == [2, 2, 2]


# ----------------------------------------------------------------------------- round trip
def test_round_trip_generate_recordings_then_ingest(tmp_path):
    """generate --recordings (lab preset) -> ingest: labels agree on (config_id, repeat)."""
    from vistac.cli import main

    gen, ing = tmp_path / "gen", tmp_path / "ing"
    assert main(["generate", "--n", "6", "--out", str(gen), "--workers", "1", "--no-progress",
                 "--recordings", "--preset", "lab", "--n-objects", "3", "--seed", "4"]) == 0
    assert main(["ingest", "--recordings", str(gen / "recordings"), "--images",
                 str(gen / "images"), "--out", str(ing)]) == 0
    a = pd.read_parquet(gen / "presses.parquet")
    b = pd.read_parquet(ing / "presses.parquet")
    m = a.merge(b, on=["config_id", "repeat"], suffixes=("_g", "_i"))
    rejected = pd.read_csv(ing / "rejected.csv")
    assert len(m) + len(rejected) == len(a)
    assert len(m) >= 0.8 * len(a)
    for f in ("index", "thumb"):
        ga = np.arctan2(m[f"r_y_{f}_g"], -m[f"r_z_{f}_g"])
        ia = np.arctan2(m[f"r_y_{f}_i"], -m[f"r_z_{f}_i"])
        ang = np.degrees(np.abs(np.angle(np.exp(1j * (ga - ia)))))
        assert np.median(ang) <= 1.0


def test_a_number_name_keeps_its_id_whatever_the_other_names():
    """Issue 22: one odd name used to renumber every configuration 0..N-1 in name order."""
    from vistac.dataset.ingest.readers import config_ids

    numbers = {"000003": 3, "000010": 10, "7": 7}
    assert config_ids(list(numbers)) == numbers
    with_odd = config_ids([*numbers, "zeta", "alpha", "\u0661\u0662", "9" * 30])
    assert {n: with_odd[n] for n in numbers} == numbers  # unchanged by the odd names
    odd = sorted(["zeta", "alpha", "\u0661\u0662", "9" * 30])  # after the largest number, 10
    assert [with_odd[n] for n in odd] == [11, 12, 13, 14]
    assert config_ids(["b", "a"]) == {"b": 1, "a": 0}  # no number: 0..N-1 in name order
    with pytest.raises(UserError, match="'007' and '7' give the same configuration id 7"):
        config_ids(["7", "007"])
