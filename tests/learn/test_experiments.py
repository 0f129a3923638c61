"""`vistac experiment sim2real` and `label-noise` on tiny data: outputs, resume after a kill,
the noise model shared with the simulator, and bad input as one line.

(That `--init` loads the weights it names is tested in test_default.py.)
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
import torch
from learn_fixtures import make_dataset

from vistac.cli import main
from vistac.dataset import open_tables
from vistac_learn.experiments.label_noise import noisy_presses

TRAIN = ["--protocol", "study", "--model", "smallconv", "--epochs", "1", "--n-rotations", "2",
         "--batch-size", "4", "--device", "cpu", "--quiet"]
MEASURED = ("test_angle_deg", "test_in_cone_pct", "val_angle_deg", "sim_test_angle_deg")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("exp")
    return {"root": root,
            "sim": make_dataset(root / "sim", n=8, repeats=3, size=64, seed=0, noise=0.05),
            "real": make_dataset(root / "real", n=8, repeats=3, size=64, seed=1, noise=0.1)}


def _rows(path):
    with path.open() as fh:
        return list(csv.DictReader(fh))


def _sim2real_argv(data, out, seeds="2"):
    return ["experiment", "sim2real", "--sim", str(data["sim"]), "--real", str(data["real"]),
            "--fractions", "0.5", "1", "--seeds", seeds, "--out", str(out), *TRAIN]


@pytest.fixture(scope="module")
def sim2real(data):
    out = data["root"] / "s2r"
    assert main(_sim2real_argv(data, out)) == 0
    return out


def test_sim2real_writes_every_output(sim2real):
    rows = _rows(sim2real / "cells.csv")
    assert len(rows) == 2 * (1 + 2 * 2) and all(r["status"] == "ok" for r in rows)
    assert {r["arm"] for r in rows} == {"sim-only", "scratch", "finetune"}
    for r in rows:
        assert np.isfinite(float(r["test_angle_deg"]))
    summary = _rows(sim2real / "results.csv")
    assert [(r["arm"], float(r["fraction"])) for r in summary] == [
        ("sim-only", 0.0), ("scratch", 0.5), ("finetune", 0.5), ("scratch", 1.0),
        ("finetune", 1.0)]
    assert all(r["n"] == "2" and float(r["test_angle_deg_std"]) >= 0 for r in summary)
    report = (sim2real / "report.md").read_text()
    assert "sim only (zero-shot)" in report and "**Domain gap**" in report
    assert "**Finding**" in report and "± " in report
    assert (sim2real / "sim2real.png").stat().st_size > 10_000
    # a fine-tuned run starts from the sim run of its own seed, on the scratch run's subset
    meta = json.loads((sim2real / "runs/finetune/fraction-0.5/seed-1/config.json").read_text())
    assert meta["init"]["run"] == str((sim2real / "runs/sim/seed-1").resolve())
    scratch = json.loads((sim2real / "runs/scratch/fraction-0.5/seed-1/config.json").read_text())
    assert meta["train"]["train_fraction"] == scratch["train"]["train_fraction"] == 0.5
    assert meta["train"]["seed"] == scratch["train"]["seed"] == 1


def test_sim2real_other_settings_in_the_same_folder_are_refused(data, sim2real, capsys):
    before = (sim2real / "cells.csv").read_bytes()
    assert main(_sim2real_argv(data, sim2real, seeds="3")) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "other settings (settings.seeds)" in err
    assert (sim2real / "cells.csv").read_bytes() == before


def test_a_killed_experiment_continues_where_it_stopped(data, sim2real, tmp_path):
    """SIGKILL after the first finished cell; a rerun skips the finished cells, --max-cells
    stops early, and the result is the clean run's (same cells, same numbers)."""
    out = tmp_path / "cut"
    argv = _sim2real_argv(data, out, seeds="1")
    # the killed part runs in a child: same torch threads as here (float sums depend on them)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path),
               OMP_NUM_THREADS=str(torch.get_num_threads()))
    proc = subprocess.Popen([sys.executable, "-m", "vistac.cli", *argv], env=env,
                            stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None:
        if (out / "cells.csv").exists():
            break
        time.sleep(0.02)
    assert proc.poll() is None, "the experiment finished before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    first = _rows(out / "cells.csv")
    assert 1 <= len(first) < 5
    best = out / "runs/sim/seed-0/checkpoints/best.pt"
    stamp = best.stat().st_mtime_ns
    assert main([*argv, "--max-cells", "1"]) == 0
    assert len(_rows(out / "cells.csv")) == len(first) + 1
    assert main(argv) == 0
    rows = _rows(out / "cells.csv")
    assert rows[:len(first)] == first and best.stat().st_mtime_ns == stamp  # not retrained
    clean = [r for r in _rows(sim2real / "cells.csv") if r["seed"] == "0"]
    assert [r["cell"] for r in rows] == [r["cell"] for r in clean]
    for a, b in zip(rows, clean, strict=True):
        for k in MEASURED:
            assert float(a[k]) == pytest.approx(float(b[k]), abs=1e-6, nan_ok=True), k
    assert len(_rows(out / "results.csv")) == 5


def test_label_noise_end_to_end(data, tmp_path):
    out = tmp_path / "ln"
    argv = ["experiment", "label-noise", "--data", str(data["real"]), "--levels", "0", "0.2",
            "--seeds", "2", "--out", str(out), *TRAIN]
    assert main(argv) == 0
    rows = _rows(out / "cells.csv")
    assert [(float(r["level"]), int(r["seed"])) for r in rows] == [(0, 0), (0, 1), (0.2, 0),
                                                                   (0.2, 1)]
    for r in rows[:2]:  # no noise: the noisy cones are the clean labels
        assert float(r["clean_angle_deg"]) == pytest.approx(float(r["noisy_angle_deg"]))
        assert float(r["label_angle_deg"]) < 1e-3
    assert all(float(r["label_angle_deg"]) > 1.0 for r in rows[2:])
    summary = _rows(out / "results.csv")
    assert [float(r["level"]) for r in summary] == [0.0, 0.2]
    report = (out / "report.md").read_text()
    assert "**Finding**" in report and "angle to clean label" in report
    assert (out / "label_noise.png").stat().st_size > 10_000
    # the labels: drawn reproducibly from the clean forces, per level and seed
    src = open_tables(data["real"])
    noisy = open_tables(out / "data" / "noise-0.2-seed-1")
    again = noisy_presses(src.configs, src.presses, 0.2, 1)
    assert np.allclose(noisy.presses[again.columns].to_numpy(float), again.to_numpy(float))
    other = noisy_presses(src.configs, src.presses, 0.2, 0)
    assert not np.allclose(other["r_y_index"], again["r_y_index"])
    assert noisy.image_fingerprint() == src.image_fingerprint()  # same images and configs
    assert noisy.fingerprint() != src.fingerprint()  # other labels
    assert main(argv) == 0 and _rows(out / "cells.csv") == rows  # nothing left to do


def test_the_simulator_and_the_experiment_share_one_noise_model():
    from vistac.noise import relative_force_noise
    from vistac_sim.effects.noise import ForceNoise

    forces = np.random.default_rng(0).normal(size=(4, 3, 2, 3))
    a = ForceNoise(relative_std=0.1)(forces, np.random.default_rng(5))
    b = relative_force_noise(forces, 0.1, np.random.default_rng(5))
    assert np.array_equal(a, b)
    assert np.array_equal(relative_force_noise(forces, 0.0, np.random.default_rng(5)), forces)


@pytest.mark.parametrize("args,message", [
    (["sim2real", "--fractions", "0", "0.5"], "--fractions: must be > 0, got 0.0"),
    (["sim2real", "--fractions", "1.5"], "--fractions: must be <= 1, got 1.5"),
    (["sim2real", "--fractions", "0.5", "0.5"], "--fractions: a fraction appears twice"),
    (["sim2real", "--seeds", "0"], "--seeds: must be >= 1"),
    (["sim2real", "--real", "SIM"], "--real: must be another dataset than --sim"),
    (["sim2real", "--sim", "MISSING"], "--sim MISSING: not a dataset directory"),
    (["sim2real", "--epochs", "0"], "--epochs: must be >= 1"),
    (["sim2real", "--max-cells", "0"], "--max-cells: must be >= 1"),
    (["label-noise", "--levels", "-0.1", "0.2"], "--levels: must be >= 0, got -0.1"),
    (["label-noise", "--data", "MISSING"], "--data MISSING: not a dataset directory"),
    (["label-noise", "--data", "NOCLEAN"], "has no clean forces"),
    (["label-noise", "--seed", "1"], "unrecognized arguments: --seed"),
])
def test_bad_input_is_one_line(data, tmp_path, capsys, args, message):
    noclean = tmp_path / "noclean"
    if "NOCLEAN" in args:
        make_dataset(noclean, n=4, repeats=1, size=32)
        cfg = pd.read_parquet(noclean / "configs.parquet")
        cfg.drop(columns=[c for c in cfg if c.startswith("force_clean")]).to_parquet(
            noclean / "configs.parquet", index=False)
    paths = {"SIM": str(data["sim"]), "MISSING": str(tmp_path / "missing"),
             "NOCLEAN": str(noclean)}
    message = message.replace("MISSING", paths["MISSING"])
    args = [paths.get(a, a) for a in args]
    kind = args[0]
    given = {a for a in args if a.startswith("--")}
    need = (["--sim", str(data["sim"]), "--real", str(data["real"])] if kind == "sim2real"
            else ["--data", str(data["real"])])
    need = [x for i, x in enumerate(need) if not (i % 2 == 0 and x in given)
            and not (i % 2 == 1 and need[i - 1] in given)]
    out = tmp_path / "out"
    assert main(["experiment", kind, *TRAIN, *args[1:], *need, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err and message in err, err
    assert not out.exists()  # nothing written


def test_a_cell_whose_pretrained_run_diverged_is_skipped(tmp_path):
    """Phases run in order; a diverged job is a row, and a cell that starts from it is not
    trained (a fake job stands in for training)."""
    from vistac_learn.experiments.cells import Cell, run_cells
    from vistac_learn.train.config import protocol_cfg
    from vistac_learn.train.job import JobCfg, JobResult, LocalJobRunner
    from vistac_learn.train.loop import TrainingDiverged

    ran = []

    def job(cfg):
        ran.append(cfg.train.out)
        if cfg.train.out.endswith("a"):
            raise TrainingDiverged(1, "training loss", float("nan"), 1.0)
        return JobResult(cfg.train.out, 1.0, 1, 1, 0.5)

    def cell(key, phase=0, needs=None):
        return Cell(key, {"name": key}, JobCfg(protocol_cfg("default", "d", key)), phase, needs)

    cells = [cell("b", 1, needs="a"), cell("a"), cell("c", 1, needs="d"), cell("d")]
    rows = run_cells(tmp_path, cells, ("x",), lambda c, r: {"x": r.objective}, lambda rows: None,
                     LocalJobRunner(job, (TrainingDiverged,)), progress=False)
    assert ran == ["a", "d", "c"]
    assert [(r["cell"], r["status"]) for r in rows] == [
        ("b", "skipped"), ("a", "diverged"), ("c", "ok"), ("d", "ok")]
    assert [r["cell"] for r in _rows(tmp_path / "cells.csv")] == ["b", "a", "c", "d"]


def test_sim2real_pretraining_has_its_own_epochs_and_rotations(tmp_path):
    """--sim-epochs / --sim-rotations / --sim-n-rotations set the sim-only runs alone (a large
    simulated dataset at one random rotation, the real runs at the study's 20 fixed ones)."""
    from vistac.errors import UserError
    from vistac_learn.experiments.sim2real import Sim2RealCfg, make_cells
    from vistac_learn.train.config import protocol_cfg

    base = protocol_cfg("study", "", "", epochs=20)
    cfg = Sim2RealCfg(sim=str(tmp_path / "sim"), real=str(tmp_path / "real"),
                      out=str(tmp_path / "x"), fractions=(0.5,), seeds=1, sim_epochs=7,
                      sim_rotations="random", sim_n_rotations=1)
    cells = {c.key: c.job.train for c in make_cells(cfg, base)}
    sim = cells["sim-only/0/0"]
    assert (sim.epochs, sim.rotations, sim.n_rotations, sim.data) == (7, "random", 1, cfg.sim)
    for key in ("scratch/0.5/0", "finetune/0.5/0"):
        assert (cells[key].epochs, cells[key].rotations, cells[key].n_rotations) == (
            20, "fixed", 20)
    plain = Sim2RealCfg(sim=cfg.sim, real=cfg.real, out=cfg.out, fractions=(0.5,), seeds=1)
    assert make_cells(plain, base)[0].job.train.epochs == 20  # default: the runs' own
    pinch = protocol_cfg("default", "", "")
    bad = Sim2RealCfg(sim=cfg.sim, real=cfg.real, out=cfg.out, sim_rotations="random")
    with pytest.raises(UserError, match="^--sim-rotations: the pinch view"):
        make_cells(bad, pinch)


def test_sim2real_pretraining_options_on_the_command_line(data, tmp_path, capsys):
    argv = ["experiment", "sim2real", "--sim", str(data["sim"]), "--real", str(data["real"]),
            "--out", str(tmp_path / "out"), "--sim-rotations", "random", "--epochs", "1"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("--sim-rotations: the pinch view turns every crop to its finger, so "
                        "rotations change nothing; choose none"), err
    assert not (tmp_path / "out").exists()


def test_the_experiments_api_takes_a_runner(data, tmp_path):
    """`vistac.label_noise(..., runner=R)` and `vistac.sim2real(..., runner=R)` train their
    cells through R (e.g. one that times each job)."""
    import vistac
    from vistac_learn.experiments.label_noise import LabelNoiseCfg
    from vistac_learn.experiments.sim2real import Sim2RealCfg
    from vistac_learn.train.job import LocalJobRunner, run_job

    ran = []

    def job(cfg):
        ran.append(cfg.train.out)
        return run_job(cfg)

    base = vistac.TrainCfg.from_protocol("study", model="smallconv", epochs=1, n_rotations=2,
                                         batch_size=4, device="cpu")
    res = vistac.label_noise(LabelNoiseCfg(data=str(data["real"]), out=str(tmp_path / "ln"),
                                           levels=(0.1,), seeds=1), base,
                             runner=LocalJobRunner(job))
    assert len(res.rows) == 1 and ran == [res.rows[0]["run"]]
    res = vistac.sim2real(Sim2RealCfg(sim=str(data["sim"]), real=str(data["real"]),
                                      out=str(tmp_path / "s2r"), fractions=(1.0,), seeds=1),
                          base, runner=LocalJobRunner(job))
    assert len(res.rows) == 3 and len(ran) == 4
