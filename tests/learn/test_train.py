"""vistac_learn.train / evaluate: a tiny run, repeatability, resume after a kill, the CLI."""

from __future__ import annotations

import csv
import json

import numpy as np
import pandas as pd
import pytest
import torch
from learn_fixtures import make_dataset

from vistac.cli import main
from vistac.errors import UserError
from vistac_learn.evaluate.config import EvaluateCfg
from vistac_learn.evaluate.run import evaluate_baseline, evaluate_run
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.loop import train_run_folder

TIME_COLUMNS = ("train_s", "epoch_s")


@pytest.fixture(scope="module")
def ds_dir(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("train") / "ds", n=8, repeats=3, size=64,
                        splits=(0.5, 0.25, 0.25))


def _cfg(ds_dir, out, **kw):
    """A study-protocol run of SmallConv (the default protocol is tested in test_default.py)."""
    base = dict(model="smallconv", epochs=2, n_rotations=3, batch_size=4, lr=1e-3,
                device="cpu", cache_dir=str(ds_dir.parent / "cache"))
    return protocol_cfg("study", str(ds_dir), str(out), **(base | kw))


def _rows(run):
    with (run / "metrics.csv").open() as fh:
        return list(csv.DictReader(fh))


def _same_metrics(a, b, atol=1e-7):
    ra, rb = _rows(a), _rows(b)
    assert len(ra) == len(rb)
    for x, y in zip(ra, rb, strict=True):
        assert x.keys() == y.keys()
        for k in x:
            if k not in TIME_COLUMNS:
                assert float(x[k]) == pytest.approx(float(y[k]), abs=atol, rel=0), k


def test_run_folder_and_repeatability(ds_dir, tmp_path):
    a = train_run_folder(_cfg(ds_dir, tmp_path / "a"), progress=False)
    assert (a / "config.json").exists()
    assert (a / "checkpoints" / "last.pt").exists() and (a / "checkpoints" / "best.pt").exists()
    rows = _rows(a)
    assert [r["epoch"] for r in rows] == ["1", "2"]
    assert {"train_loss", "val_loss", "val_index_in_cone_pct", "val_index_error_median_pct"} <= set(
        rows[0])
    meta = json.loads((a / "config.json").read_text())
    assert meta["train"]["model"] == "smallconv" and meta["dataset"]["n_train_configs"] == 4
    # the same seed gives the same run, whether the samples are rendered here or in workers
    b = train_run_folder(_cfg(ds_dir, tmp_path / "b", loader_workers=2), progress=False)
    _same_metrics(a, b, atol=0)
    with pytest.raises(UserError, match="already holds a run"):
        train_run_folder(_cfg(ds_dir, tmp_path / "a"), progress=False)


@pytest.mark.parametrize("kill_at", [(0, 1), (1, 0), (1, 1)])
def test_killed_and_resumed_run_ends_identical(ds_dir, tmp_path, kill_at):
    """A run interrupted mid-epoch and resumed ends with the uninterrupted run's metrics."""
    ref = train_run_folder(_cfg(ds_dir, tmp_path / "ref", epochs=3, checkpoint_every=1),
                           progress=False)

    def killer(epoch, batch):
        if (epoch, batch) == kill_at:
            raise KeyboardInterrupt

    cut = _cfg(ds_dir, tmp_path / "cut", epochs=3, checkpoint_every=1)
    with pytest.raises(KeyboardInterrupt):
        train_run_folder(cut, progress=False, on_batch=killer)
    train_run_folder(cut, resume=True, progress=False)
    _same_metrics(ref, tmp_path / "cut", atol=1e-7)
    wa = torch.load(ref / "checkpoints" / "last.pt", weights_only=True)["model"]
    wb = torch.load(tmp_path / "cut" / "checkpoints" / "last.pt", weights_only=True)["model"]
    for k in wa:
        torch.testing.assert_close(wa[k], wb[k], rtol=0, atol=1e-7)


def test_resume_without_intermediate_checkpoints_reruns_the_epoch(ds_dir, tmp_path):
    ref = train_run_folder(_cfg(ds_dir, tmp_path / "ref", target="press"), progress=False)

    def killer(epoch, batch):
        if (epoch, batch) == (1, 0):
            raise KeyboardInterrupt

    cut = _cfg(ds_dir, tmp_path / "cut", target="press")
    with pytest.raises(KeyboardInterrupt):
        train_run_folder(cut, progress=False, on_batch=killer)
    assert len(_rows(tmp_path / "cut")) == 1
    train_run_folder(cut, resume=True, progress=False)
    _same_metrics(ref, tmp_path / "cut", atol=1e-7)
    with pytest.raises(UserError, match="different settings"):
        train_run_folder(_cfg(ds_dir, tmp_path / "cut", target="press", lr=0.5), resume=True,
                         progress=False)


def test_evaluate_run_tta_and_baseline(ds_dir, tmp_path, capsys):
    run = train_run_folder(_cfg(ds_dir, tmp_path / "run", variant="edge-crop", finger="both",
                                epochs=1, select="in_cone_pct"), progress=False)
    capsys.readouterr()
    res = evaluate_run(EvaluateCfg(run=str(run)))  # the study recipe: tta off
    assert capsys.readouterr().out == ""  # the library returns its results, the CLI prints
    out = run / "eval" / "test"
    for name in ("metrics.json", "predictions.parquet", "cones_index.png", "cones_thumb.png",
                 "error_hist_index.png", "rotation_spread_thumb.png"):
        assert (out / name).exists(), name
    assert res["n_predictions"] == 2 * 3 and set(res["metrics"]) == {"index", "thumb"}
    assert "| % correct y | % in cone | median err overall" in res["table"]
    tta = evaluate_run(EvaluateCfg(run=str(run), tta="on", no_plots=True))
    assert tta["n_predictions"] == 2 and tta["tta"]
    # TTA: each configuration's rotations and their mirrors (r_y negated back), averaged
    plain = pd.read_parquet(out / "predictions.parquet")
    both = pd.read_parquet(run / "eval" / "test-tta" / "predictions.parquet")
    assert not np.allclose(both["pred_index_y"], plain.groupby("config_id")["pred_index_y"]
                           .mean().loc[both["config_id"]].to_numpy())
    bl = evaluate_baseline(EvaluateCfg(baseline="geometric", data=str(ds_dir),
                                       rotations="fixed", n_rotations=20), tmp_path / "bl")
    assert bl["n_predictions"] == 2 * 20 and bl["failures"] == 0
    assert np.isfinite(list(bl["metrics"]["index"].values())).all()


def test_cli_train_and_evaluate(ds_dir, tmp_path, capsys):
    run = tmp_path / "cli"
    argv = ["train", "--data", str(ds_dir), "--out", str(run), "--protocol", "study",
            "--model", "smallconv", "--epochs", "1", "--n-rotations", "2", "--device", "cpu",
            "--quiet", "--cache-dir", str(tmp_path / "cache")]
    assert main(argv) == 0
    assert main(["evaluate", "--run", str(run), "--no-plots"]) == 0
    assert "median err overall" in capsys.readouterr().out
    assert main(["train", "--data", str(tmp_path / "nothing"), "--out", str(tmp_path / "x")]) == 2
    assert "not a dataset directory" in capsys.readouterr().err
    assert main(["evaluate", "--baseline", "geometric"]) == 2
    assert main(["evaluate", "--baseline", "geometric", "--data", str(ds_dir), "--out",
                 str(tmp_path / "bl"), "--n-rotations", "2", "--no-plots"]) == 0
    assert (tmp_path / "bl" / "metrics.json").exists()


def test_selection_direction():
    from vistac_learn.train.loop import _selection_value

    row = {"val_loss": 1.0, "val_index_error_median_pct": 5.0, "val_index_in_cone_pct": 40.0,
           "val_thumb_in_cone_pct": 20.0}
    assert _selection_value(row, "loss", ("index",)) == (1.0, False)
    assert _selection_value(row, "error_median_pct", ("index",)) == (5.0, False)
    assert _selection_value(row, "in_cone_pct", ("index", "thumb")) == (30.0, True)
    with pytest.raises(UserError, match="not a metric"):
        _selection_value(row, "bogus", ("index",))


@pytest.mark.slow
def test_sigkilled_process_resumes_identically(ds_dir, tmp_path):
    """A real `vistac train` process killed with SIGKILL mid-epoch, then `--resume`d."""
    import os
    import signal
    import subprocess
    import sys
    import time

    argv = ["--data", str(ds_dir), "--protocol", "study", "--model", "smallconv", "--epochs",
            "4", "--n-rotations",
            "6", "--batch-size", "2", "--lr", "1e-3", "--device", "cpu", "--quiet",
            "--checkpoint-every", "2", "--cache-dir", str(tmp_path / "cache")]
    ref = tmp_path / "ref"
    assert main(["train", *argv, "--out", str(ref)]) == 0
    cut = tmp_path / "cut"
    cmd = [sys.executable, "-m", "vistac.cli", "train", *argv, "--out", str(cut)]
    proc = subprocess.Popen(cmd)
    last = cut / "checkpoints" / "last.pt"
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None:
        if last.exists():
            ck = torch.load(last, weights_only=True)
            if ck["epoch"] >= 1 and ck["batch"] > 0:  # mid-epoch, after a finished epoch
                break
        time.sleep(0.05)
    assert proc.poll() is None, "run finished before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert len(_rows(cut)) < 4
    assert main(["train", *argv, "--out", str(cut), "--resume"]) == 0
    _same_metrics(ref, cut, atol=1e-7)


@pytest.mark.parametrize("epochs,batch_size", [(1, 64), (2, 64), (2, 2)])
def test_one_cycle_schedule_of_very_few_steps(ds_dir, tmp_path, epochs, batch_size):
    """A one-cycle run of 1, 2 or a few optimiser steps trains (torch's schedule needs a
    warm-up of more than one step; a tiny fraction of the data gives such runs)."""
    run = train_run_folder(_cfg(ds_dir, tmp_path / "r", schedule="onecycle", epochs=epochs,
                                batch_size=batch_size, n_rotations=1), progress=False)
    assert len(_rows(run)) == epochs
