"""A training job scores its best weights under the run's own --max-missing-pct: a run allowed
to train on images whose fingertips are partly lost (photographs) is scored on them too."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from learn_fixtures import make_dataset

from vistac.dataset import open_tables
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.job import JobCfg, ScoreCfg, run_job


@pytest.fixture(scope="module")
def blind_test_split(tmp_path_factory):
    """A tiny dataset whose test images show no fingers (every fingertip of the split lost)."""
    data = make_dataset(tmp_path_factory.mktemp("job") / "d", n=8, repeats=2, size=64)
    tables = open_tables(data)
    for row in tables.rows("test"):
        path = tables.image_path(int(row))
        cv2.imwrite(str(path), np.zeros_like(cv2.imread(str(path))))
    return data


def _job(data, out, max_missing_pct):
    run = protocol_cfg("default", str(data), str(out), epochs=1, batch_size=4, device="cpu",
                       max_missing_pct=max_missing_pct)
    return JobCfg(run, (ScoreCfg("test", "test"),))


def test_the_score_uses_the_runs_max_missing_pct(blind_test_split, tmp_path):
    res = run_job(_job(blind_test_split, tmp_path / "r", 100.0))
    assert np.isfinite(res.score("test"))

