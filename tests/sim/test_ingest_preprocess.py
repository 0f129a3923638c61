"""`vistac ingest` preprocessing: grasps, representative samples, each rejection reason, CSV
reading."""

from __future__ import annotations

import numpy as np
from ingest_fixtures import PLATEAUS, press_series, write_csv

from vistac.dataset.ingest.config import IngestCfg
from vistac.dataset.ingest.preprocess import (
    REASONS,
    preprocess,
    representative_sample,
    split_grasps,
)


# --------------------------------------------------------------------------- preprocessing
def test_split_grasps_threshold_rises_and_falls():
    fz = np.array([0, -50, -150, -300, -120, -90, 0, -200, -200, 0, 0, 120, 0]) / 1000
    assert split_grasps(fz, 0.1).tolist() == [[2, 5], [7, 9], [11, 12]]
    assert split_grasps(np.zeros(5), 0.1).shape == (0, 2)
    assert split_grasps(np.full(4, -1.0), 0.1).tolist() == [[0, 4]]


def test_representative_sample_first_extremum_beyond_mean():
    # trough at index 3 (beyond the mean), then a shallower local trough at 6
    fz = np.array([-0.2, -0.8, -1.5, -2.2, -2.0, -1.9, -2.1, -1.8, -0.5])
    assert representative_sample(fz) == 3
    # the first local extremum that is NOT beyond the mean is skipped
    fz = np.array([-0.2, -0.6, -0.5, -2.0, -2.5, -2.4, -1.0])
    assert representative_sample(fz) == 4
    # positive values: a peak; a flat top yields its first sample
    assert representative_sample(np.array([0.2, 1.0, 2.0, 2.0, 2.0, 1.0, 0.3])) == 2
    # monotonic: none; too short for an interior extremum: none
    assert representative_sample(np.linspace(-0.2, -3.0, 20)) is None
    assert representative_sample(np.array([-0.5, -1.0])) is None


def test_each_rejection_reason(tmp_path):
    rng = np.random.default_rng(1)
    good = [[0, 300, -1500], [0, -200, -1200]]
    parts = [press_series([good], rng, rest=30)]                     # 0 kept
    blip = np.zeros((33, 2, 3))
    blip[10:12, 0, 2] = -500                                          # 1 too_short
    parts.append(blip)
    parts.append(press_series([[[0, 300, -9950], [0, -200, -1200]]], rng))  # 2 saturated
    ramp = np.zeros((60, 2, 3))
    ramp[20:40, 0] = np.linspace(-200, -3000, 20)[:, None] * [0, 0.1, 1]
    ramp[20:40, 1] = [0, -100, -900]                                   # 3 no_extremum
    parts.append(ramp)
    parts.append(press_series([[[0, 300, -1500], [0, 3, -5]]], rng, noise=0))  # 4 below_res.
    parts.append(press_series([[[0, 300, -1500], [0, -200, 400]]], rng))        # 5 pulling
    parts.append(press_series([good], rng)[:-25])                      # 6 kept, 7 truncated
    parts.append(press_series([good], rng, rest=5)[:40])
    series = np.concatenate(parts)
    grasps = preprocess(series / 1000, IngestCfg())
    reasons = [g.reason for g in grasps]
    assert reasons == [None, "too_short", "saturated", "no_extremum", "below_resolution",
                       "pulling", None, "truncated"]
    assert [g.repeat for g in grasps] == list(range(8))
    assert set(reasons) - {None} == set(REASONS)
    allowed = preprocess(series / 1000, IngestCfg(allow_pulling=True))
    assert allowed[5].reason is None


def test_truncated_at_the_start():
    series = np.zeros((30, 2, 3))
    series[:15, 0, 2] = -1.0
    assert preprocess(series, IngestCfg())[0].reason == "truncated"




def test_windows_line_endings_and_float_cells(tmp_path):
    from vistac.dataset.ingest.readers import read_recording

    rng = np.random.default_rng(5)
    series = press_series(PLATEAUS[3], rng)
    path = write_csv(tmp_path / "a.csv", series)
    lines = path.read_text().splitlines()
    lines[3] = lines[3].replace(",", ", ")  # spaces after commas
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode())
    np.testing.assert_allclose(read_recording(path, IngestCfg()), series / 1000)
    np.testing.assert_allclose(read_recording(path, IngestCfg(unit="N")), series)
