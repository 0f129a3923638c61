"""`vistac inspect`: arrows in the image from the finger frame, the report of a good, a damaged
and an older dataset (its card), a run's worst configurations, the command line."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from learn_fixtures import make_dataset

from vistac.cli import main
from vistac.dataset.reader import DatasetTables
from vistac.errors import UserError
from vistac_learn.inspect.arrows import finger_arrows
from vistac_learn.inspect.config import InspectCfg
from vistac_learn.inspect.report import inspect_dataset, inspect_path
from vistac_learn.inspect.runs import worst_configurations

SIZE, PPM = 100, 1000.0  # a 0.1 m wide view


def _hand_built(r_y: float) -> DatasetTables:
    """One configuration: the index finger comes from the left (its axis world +x, image
    right), the thumb from the right (world -x); both labels (r_y, -0.8) with |r_y| 0.6."""
    row = {"config_id": 0, "image": "000000.png", "split": "test", "camera_x": 0.0,
           "camera_y": 0.0, "px_per_m": PPM,
           "tip_index_x": -0.01, "tip_index_y": 0.0, "approach_index_x": 1.0,
           "approach_index_y": 0.0,
           "tip_thumb_x": 0.01, "tip_thumb_y": 0.02, "approach_thumb_x": -1.0,
           "approach_thumb_y": 0.0}
    label = np.array([[r_y, -0.8]])
    return DatasetTables(Path("."), {"config": {"render": {"image_size": SIZE}}},
                         pd.DataFrame([row]), pd.DataFrame(),
                         {"index": [label], "thumb": [label]})


@pytest.mark.parametrize("r_y", [0.6, -0.6])
def test_arrows_follow_the_sensor_frames_into_the_image(r_y):
    found = finger_arrows(_hand_built(r_y), 0, None, simulated=True)
    index, thumb = found["index"], found["thumb"]
    # tips: world (x, y) -> pixel ((x - cx) ppm + W/2, H/2 - (y - cy) ppm), centres at integers
    np.testing.assert_allclose(index.tip, [-10 + 50 - 0.5, 50 - 0.5])
    np.testing.assert_allclose(thumb.tip, [10 + 50 - 0.5, -20 + 50 - 0.5])
    np.testing.assert_allclose(index.axis, [1, 0], atol=1e-12)
    # index: z = axis (world +x), y = axis turned counter-clockwise seen from above (world +y,
    # image up): F = r_y (0, 1) - 0.8 (1, 0) in the world; image v runs down
    np.testing.assert_allclose(index.mean, [-0.8, -r_y], atol=1e-12)
    # thumb, y mirrored: z = world -x, y = axis turned clockwise = world +y again
    # F = r_y (0, 1) - 0.8 (-1, 0) = (0.8, r_y) in the world
    np.testing.assert_allclose(thumb.mean, [0.8, -r_y], atol=1e-12)
    np.testing.assert_allclose(index.presses, [index.mean], atol=1e-12)


def test_arrows_point_away_from_the_contact_on_a_dataset(tmp_path):
    """The fixture draws each finger against an edge and labels the force from the geometry
    (normal plus at most 0.3 of it sideways): the arrow is within atan(0.3) (+ noise) of the
    direction from the contact to the fingertip, in the image."""
    from vistac.dataset import open_tables

    tables = open_tables(make_dataset(tmp_path / "d", n=6, repeats=3, noise=0.01))
    c = tables.configs
    for row in range(len(c)):
        for f, a in finger_arrows(tables, row, None, simulated=True).items():
            out = np.array([c[f"tip_{f}_x"][row] - c[f"target_{f}_x"][row],
                            -(c[f"tip_{f}_y"][row] - c[f"target_{f}_y"][row])])
            out /= np.linalg.norm(out)
            angle = np.degrees(np.arccos(np.clip(a.mean @ out, -1, 1)))
            assert angle < np.degrees(np.arctan(0.3)) + 3, (row, f, angle)


def _digests(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def test_report_of_a_dataset_and_its_card(tmp_path):
    root = make_dataset(tmp_path / "d", n=8, repeats=3, size=64)
    before = _digests(root)
    rep = inspect_dataset(root, InspectCfg(out=str(tmp_path / "r"), per_group=2))
    after = _digests(root)
    assert rep.card == root / "README.md"  # the older dataset gets its card, nothing else
    assert {k: v for k, v in after.items() if k != "README.md"} == before
    for name in ("report.md", "contact_sheet.png", "labels_by_family.png", "labels_by_split.png"):
        assert (tmp_path / "r" / name).is_file(), name
    md = (tmp_path / "r" / "report.md").read_text()
    assert "![contact sheet](contact_sheet.png)" in md
    assert any(line.startswith("configurations: 8 (train 4, val 2, test 2)")
               for line in rep.lines)
    assert not any(line.startswith("note:") for line in rep.lines)


def test_damaged_dataset_is_inspected_as_far_as_readable(tmp_path):
    root = make_dataset(tmp_path / "d", n=8, repeats=3, size=64)
    (root / "presses.parquet").write_bytes(b"PAR1 truncated")
    (root / "images" / "000003.png").unlink()
    (root / "images" / "000005.png").write_bytes(b"not a png")
    before = _digests(root)
    rep = inspect_dataset(root, InspectCfg(out=str(tmp_path / "r")))
    notes = [line for line in rep.lines if line.startswith("note:")]
    assert any("presses.parquet: unreadable" in n for n in notes), notes
    assert any("1 of 8 images missing (first: 000003.png)" in n for n in notes), notes
    assert any("1 of the contact sheet's images unreadable (first: 000005.png)" in n
               for n in notes), notes
    assert all("\n" not in n for n in notes)
    assert (tmp_path / "r" / "contact_sheet.png").is_file()  # the images are still shown
    after = _digests(root)
    assert {k: v for k, v in after.items() if k != "README.md"} == before


def test_unfinished_dataset_without_anything_readable_is_one_line(tmp_path, capsys):
    (tmp_path / "d" / ".partial").mkdir(parents=True)
    assert main(["inspect", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("vistac inspect: error:") and "\n" not in err
    assert "nothing of a dataset" in err


def test_command_prints_the_summary(tmp_path, capsys):
    root = make_dataset(tmp_path / "d", n=6, repeats=2, size=48)
    assert main(["inspect", str(root), "--out", str(tmp_path / "r"), "--tile", "64"]) == 0
    out = capsys.readouterr().out
    assert "configurations: 6" in out and f"report: {tmp_path / 'r' / 'report.md'}" in out
    assert main(["inspect", str(root), "--out", str(root / "inside")]) == 2


def test_run_report_shows_the_worst_configurations_first(tmp_path):
    data = make_dataset(tmp_path / "d", n=6, repeats=2, size=48)
    run = tmp_path / "run"
    ev = run / "eval" / "test"
    ev.mkdir(parents=True)
    (run / "config.json").write_text(json.dumps(
        {"train": {}, "dataset": {"path": str(data), "fingerprint": "x"}}))
    errors = {4: 30.0, 5: 2.0}  # the fixture's test split: configurations 4 and 5
    pred = pd.DataFrame([{"config_id": cid, "rotation": k, "pred_index_y": 0.0,
                          "pred_index_z": -1.0, "index_angle_to_mean_deg": e + k}
                         for cid, e in errors.items() for k in range(2)])
    pred.to_parquet(ev / "predictions.parquet")
    (ev / "metrics.json").write_text(json.dumps(
        {"data": str(data), "fingers": ["index"], "table": "metric table"}))
    worst = worst_configurations(pred, ["index"], 5)
    assert worst.index.tolist() == [4, 5] and worst["error_deg"].tolist() == [30.5, 2.5]
    rep = inspect_path(run, InspectCfg(out=str(tmp_path / "r"), tile=64))
    assert (tmp_path / "r" / "worst.png").is_file()
    assert "worst 2 configurations (angle to the mean label, deg): 4 30.5, 5 2.5" in rep.lines
    (ev / "metrics.json").unlink()
    with pytest.raises(UserError, match="vistac evaluate --run"):
        inspect_path(run, InspectCfg(out=str(tmp_path / "r2")))


def test_unfinished_dataset_gets_no_card(tmp_path):
    root = make_dataset(tmp_path / "d", n=4, repeats=2, size=48, complete=False)
    rep = inspect_dataset(root, InspectCfg(out=str(tmp_path / "r")))
    assert rep.card is None and not (root / "README.md").exists()
    assert any(line.startswith("note: not a complete, valid dataset:") and "not complete" in line
               for line in rep.lines)
    assert any(line.startswith("configurations: 4") for line in rep.lines)


def test_python_api_inspects_a_dataset(tmp_path):
    import vistac

    root = make_dataset(tmp_path / "d", n=4, repeats=2, size=48)
    rep = vistac.open_dataset(root).inspect(tmp_path / "r", per_group=1)
    assert rep.out == tmp_path / "r" and "report.md" in rep.files
    assert "presses: 8 (2 per configuration)" in rep.lines
