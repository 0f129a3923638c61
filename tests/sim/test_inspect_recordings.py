"""`vistac inspect` on an ingested dataset: one recordings page per recording, rejected grasps
first (with the dropped recording), segments and reasons as `vistac ingest` found them."""

from __future__ import annotations

import numpy as np
from ingest_fixtures import press_series, write_csv, write_png

from vistac.dataset.ingest.config import IngestSources
from vistac.dataset.ingest.run import ingest
from vistac_learn.inspect.config import InspectCfg
from vistac_learn.inspect.report import inspect_dataset


def test_recordings_pages_list_rejected_grasps_first(tmp_path):
    rng = np.random.default_rng(2)
    rec, img = tmp_path / "rec", tmp_path / "img"
    rec.mkdir()
    img.mkdir()
    good = [[0, 300, -1500], [0, -200, -1200]]
    sat = [[0, 300, -9990], [0, -200, -1200]]
    write_csv(rec / "000000.csv", press_series([good, good], rng))
    write_csv(rec / "000001.csv", press_series([good, sat, good], rng))
    write_csv(rec / "000002.csv", press_series([sat], rng))  # nothing usable: dropped
    for i in range(3):
        write_png(img / f"{i:06d}.png")
    data = tmp_path / "ds"
    ingest(IngestSources(images=img, recordings=rec), data)
    assert (data / "README.md").is_file()  # ingest writes the card
    rep = inspect_dataset(data, InspectCfg(out=str(tmp_path / "r")))
    md = (tmp_path / "r" / "report.md").read_text()
    table = [line for line in md.splitlines() if line.startswith("| ") and "csv" in line]
    assert [row.split(" | ")[1] for row in table] == ["000001.csv", "000002.csv", "000000.csv"]
    assert "#1 saturated" in table[0] and "#0 saturated" in table[1] and table[2].endswith(
        "| 2 | 2 | - | [page](recordings/000000.png) |")
    for i in range(3):
        assert (tmp_path / "r" / "recordings" / f"{i:06d}.png").is_file()
    assert any(line.startswith("rejected recorded grasps: 2 (saturated 2)")
               for line in rep.lines)
    assert any(line.startswith("recordings: 3 (2 with rejected grasps)") for line in rep.lines)
