"""`vistac generate --recordings`: RH8D/FTS-3 CSV layout, agreement with presses.parquet through
the study's preprocessing, and identical files after an interrupted and resumed run."""

import numpy as np
import pandas as pd
import pytest

from vistac.cli import main
from vistac.dataset.recordings import HEADER
from vistac_sim.generate.chunks import ChunkWork

ARGS = ["--n", "6", "--seed", "3", "--workers", "1", "--no-progress", "--n-objects", "3",
        "--chunk-size", "2", "--preset", "lab", "--noise", "0.02", "--recordings"]
THRESHOLD_MN = 500  # a sensible split threshold on |index F_z| for presses of ~2 N


@pytest.fixture(scope="module")
def lab_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("rec") / "d"
    assert main(["generate", "--out", str(out), *ARGS]) == 0
    return out


def _preprocess(table: np.ndarray) -> list[int]:
    """The study's steps 2-3: threshold split on |index F_z|, then per segment the first local
    extremum of index F_z beyond the segment mean (a trough: F_z < 0 in contact)."""
    z = table[:, 19]
    edges = np.flatnonzero(np.diff(np.r_[0, (np.abs(z) > THRESHOLD_MN).astype(int), 0]))
    picks = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        seg = z[a:b]
        i = next(i for i in range(1, len(seg) - 1)
                 if seg[i] < seg.mean() and seg[i] < seg[i - 1] and seg[i] <= seg[i + 1])
        picks.append(a + i)
    return picks


def test_one_csv_per_configuration_in_the_rh8d_layout(lab_run):
    configs = pd.read_parquet(lab_run / "configs.parquet")
    files = sorted(p.name for p in (lab_run / "recordings").iterdir())
    assert files == [f"{c:06d}.csv" for c in sorted(configs["config_id"])]
    for name in files:
        lines = (lab_run / "recordings" / name).read_text().splitlines()
        header = lines[0].split(",")
        assert header == HEADER and len(header) == 20
        assert header[14:20] == ["thumb_fx_mn", "thumb_fy_mn", "thumb_fz_mn",
                                 "index_fx_mn", "index_fy_mn", "index_fz_mn"]
        rows = [line.split(",") for line in lines[1:]]
        assert all(len(r) == 20 and all(v.lstrip("-").isdigit() for v in r) for r in rows)
        table = np.array(rows, dtype=np.int64)
        assert np.all(np.diff(table[:, 0]) == 20)  # 50 Hz, time in ms
        np.testing.assert_array_equal(table[:, 1], np.arange(len(table)))
        assert np.abs(table[:, 14:20]).max() <= 10_000  # the sensor's range


def test_study_preprocessing_recovers_each_press_of_presses_parquet(lab_run):
    presses = pd.read_parquet(lab_run / "presses.parquet")
    for path in sorted((lab_run / "recordings").iterdir()):
        table = pd.read_csv(path).to_numpy()
        cid = int(path.stem)
        mine = presses[presses["config_id"] == cid].sort_values("repeat")
        picks = _preprocess(table)
        assert len(picks) == len(mine) == 6  # one grasp per press
        cols = {"thumb": (14, 15, 16), "index": (17, 18, 19)}
        for (_, row), t in zip(mine.iterrows(), picks, strict=True):
            for f, c in cols.items():
                want = np.array([row[f"force_{f}_{a}"] for a in "xyz"]) * 1000.0
                np.testing.assert_allclose(table[t, list(c)], want, atol=1e-6)  # on the grid
        idle = np.abs(table[:, 19]) < THRESHOLD_MN
        assert np.abs(table[idle, 19]).min() < 100  # rest is near zero, far below threshold


def test_interrupted_run_resumes_to_identical_recordings(lab_run, tmp_path, monkeypatch):
    out = tmp_path / "d"
    original, done = ChunkWork.run_chunk, []

    def dies_on_second_chunk(work, chunk):
        if done:
            raise KeyboardInterrupt
        done.append(chunk)
        return original(work, chunk)

    monkeypatch.setattr(ChunkWork, "run_chunk", dies_on_second_chunk)
    assert main(["generate", "--out", str(out), *ARGS]) == 130
    assert not (out / "manifest.json").exists()
    monkeypatch.setattr(ChunkWork, "run_chunk", original)
    assert main(["generate", "--out", str(out), "--resume", *ARGS]) == 0
    a = sorted((lab_run / "recordings").iterdir())
    b = sorted((out / "recordings").iterdir())
    assert [p.name for p in a] == [p.name for p in b]
    assert all(x.read_bytes() == y.read_bytes() for x, y in zip(a, b, strict=True))
    pd.testing.assert_frame_equal(pd.read_parquet(lab_run / "presses.parquet"),
                                  pd.read_parquet(out / "presses.parquet"))


def test_recordings_do_not_change_the_labels(tmp_path):
    common = ["--n", "3", "--seed", "4", "--workers", "1", "--no-progress", "--n-objects", "2",
              "--noise", "0.05"]
    assert main(["generate", "--out", str(tmp_path / "a"), *common]) == 0
    assert main(["generate", "--out", str(tmp_path / "b"), *common, "--recordings"]) == 0
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "a" / "presses.parquet"),
                                  pd.read_parquet(tmp_path / "b" / "presses.parquet"))
    assert not (tmp_path / "a" / "recordings").exists()
    assert len(list((tmp_path / "b" / "recordings").iterdir())) == 3
