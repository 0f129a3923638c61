"""End to end on a real `vistac generate` dataset: variants, training, evaluation, baseline."""

from __future__ import annotations

import numpy as np
import pytest

import vistac
from vistac.dataset import open_tables
from vistac_learn.data.samples import RotationCfg
from vistac_learn.evaluate.config import EvaluateCfg
from vistac_learn.evaluate.geometric import baseline_predictions
from vistac_learn.evaluate.run import evaluate_baseline, evaluate_run
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.loop import train_run_folder


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    cfg = vistac.GenerateCfg.from_preset(noise=0.05, n=30, repeats=3, seed=7)
    return vistac.generate(cfg, tmp_path_factory.mktemp("e2e") / "ds", workers=1).path


def test_generated_dataset_trains_and_evaluates(generated, tmp_path):
    t = open_tables(generated)
    assert len(t.configs) == 30 and t.has_boxes("index") and t.has_boxes("thumb")
    cfg = protocol_cfg("study", str(generated), str(tmp_path / "run"), model="smallconv",
                       epochs=1, n_rotations=2, device="cpu", cache_dir=str(tmp_path / "cache"))
    run = train_run_folder(cfg, progress=False)
    res = evaluate_run(EvaluateCfg(run=str(run)))
    s = res["metrics"]["index"]
    assert res["n_predictions"] == 2 * res["n_configs"]
    assert all(np.isfinite(v) for v in s.values())
    assert (run / "eval" / "test" / "cones_index.png").exists()


def test_geometric_baseline_reads_the_simulated_normal(generated, tmp_path):
    """On simulated images the baseline's direction is close to the mesh normal at contact."""
    t = open_tables(generated)
    rows = t.rows(None)
    pred, item_row, _, failures = baseline_predictions(t, rows, ("index", "thumb"),
                                                       RotationCfg("none"))
    assert failures == 0
    for i, f in enumerate(("index", "thumb")):
        n = t.configs[[f"normal_{f}_y", f"normal_{f}_z"]].to_numpy()[item_row]
        p = pred[:, 2 * i:2 * i + 2]
        err = np.degrees(np.abs(np.arctan2(p[:, 0], -p[:, 1]) - np.arctan2(n[:, 0], -n[:, 1])))
        assert np.median(err) < 5.0, f
    # the largest split (a non-learned baseline has no training)
    res = evaluate_baseline(EvaluateCfg(baseline="geometric", data=str(generated),
                                        split="train", rotations="fixed", n_rotations=2,
                                        no_plots=True), tmp_path / "bl")
    assert res["metrics"]["index"]["correct_y_pct"] > 70
