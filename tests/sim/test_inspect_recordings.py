"""`vistac inspect` on an ingested dataset: one recordings page per recording, rejected grasps
first (with the dropped recording), segments and reasons as `vistac ingest` found them."""

from __future__ import annotations

from ingest_fixtures import recordings_with_rejections

from vistac.cli import main
from vistac.dataset.ingest.config import IngestSources
from vistac.dataset.ingest.run import ingest
from vistac_learn.inspect.config import InspectCfg
from vistac_learn.inspect.report import inspect_dataset


def _sources(tmp_path):
    return recordings_with_rejections(tmp_path, with_good=True)


def _index(report_md):
    return [line for line in report_md.read_text().splitlines()
            if line.startswith("| ") and "csv" in line]


def test_recordings_pages_list_rejected_grasps_first(tmp_path):
    rec, img = _sources(tmp_path)
    data = tmp_path / "ds"
    ingest(IngestSources(images=img, recordings=rec), data)
    assert (data / "README.md").is_file()  # ingest writes the card
    rep = inspect_dataset(data, InspectCfg(out=str(tmp_path / "r")))
    table = _index(tmp_path / "r" / "report.md")
    assert [row.split(" | ")[1] for row in table] == ["000001.csv", "000002.csv", "000000.csv"]
    assert "#1 saturated" in table[0] and "#0 saturated" in table[1] and table[2].endswith(
        "| 2 | 2 | - | [page](recordings/000000.png) |")
    for i in range(3):
        assert (tmp_path / "r" / "recordings" / f"{i:06d}.png").is_file()
    assert any(line.startswith("rejected recorded grasps: 2 (saturated 2)")
               for line in rep.lines)
    assert any(line.startswith("recordings: 3 (2 with rejected grasps)") for line in rep.lines)


def test_ingest_report_writes_the_pages(tmp_path, capsys):
    rec, img = _sources(tmp_path)
    args = ["ingest", "--recordings", str(rec), "--images", str(img), "--out"]
    assert main([*args, str(tmp_path / "ds"), "--report", str(tmp_path / "ds" / "r")]) == 2
    assert "inside the dataset" in capsys.readouterr().err
    assert main([*args, str(tmp_path / "ds"), "--report", str(tmp_path / "r")]) == 0
    assert "recordings: 3 (2 with rejected grasps)" in capsys.readouterr().out
    assert [row.split(" | ")[1] for row in _index(tmp_path / "r" / "report.md")] == [
        "000001.csv", "000002.csv", "000000.csv"]
    assert (tmp_path / "r" / "recordings" / "000001.png").is_file()
