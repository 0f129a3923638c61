"""`vistac tune --engine ray`: the files of the local engine, resume after a cap and a kill,
options checked before Ray starts."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time

import pytest
from learn_fixtures import make_dataset

from vistac.cli import main

TRIALS = 3
# init_points >= TRIALS: every suggestion is the optimiser's seeded random point for (seed,
# trial), whatever finished before, so both engines try the same options in every trial.
SPACE = {"init_points": TRIALS, "params": {"weight_decay": None, "jitter": None,
                                           "batch_size": {"low": 2, "high": 6}}}
RUN = ["--protocol", "study", "--model", "smallconv", "--epochs", "1", "--n-rotations", "2",
       "--device", "cpu", "--tune-seed", "3"]
OUTPUTS = {"config.json", "trials.csv", "pending.json", "best.json", "convergence.png"}


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """The dataset, the tune options and a finished local tuning to compare with."""
    root = tmp_path_factory.mktemp("tune")
    data = make_dataset(root / "ds", n=8, repeats=3, size=64)
    (root / "space.json").write_text(json.dumps(SPACE))
    args = ["--data", str(data), "--space", str(root / "space.json"), *RUN,
            "--cache-dir", str(root / "cache")]
    assert main(["tune", "--out", str(root / "local"), "--trials", str(TRIALS), "--quiet",
                 *args]) == 0
    return args, root / "local"


def _tune(out, args, *extra, trials=TRIALS):
    return main(["tune", "--out", str(out), "--trials", str(trials), "--quiet", *args, *extra])


def _rows(out):
    with (out / "trials.csv").open() as fh:
        return list(csv.DictReader(fh))


def _assert_same_tuning(ref, out):
    """The files of `ref`, the same trials with the same options and outcomes."""
    assert {p.name for p in out.iterdir()} == OUTPUTS | {"trials"}
    trials = sorted(p.name for p in (ref / "trials").iterdir())
    assert sorted(p.name for p in (out / "trials").iterdir()) == trials
    for t in trials:
        assert (out / "trials" / t / "checkpoints" / "best.pt").is_file()
    a, b = _rows(ref), _rows(out)
    assert [r["trial"] for r in b] == [str(t) for t in range(TRIALS)]
    assert [list(r) for r in b] == [list(r) for r in a]
    for x, y in zip(a, b, strict=True):
        assert all(y[k] != "" for k in y), y  # complete rows
        for k in ("trial", "lr", "batch_size", "status", "best_epoch", "run"):
            assert y[k] == x[k], k
        # the same training; Ray's one-thread workers may round differently in the last bits
        assert float(y["objective"]) == pytest.approx(float(x["objective"]), rel=1e-4, abs=1e-6)
    assert json.loads((out / "pending.json").read_text()) == {}
    best_a, best_b = (json.loads((d / "best.json").read_text()) for d in (ref, out))
    assert best_b["trial"] == best_a["trial"] and best_b["params"] == best_a["params"]
    assert best_b["n_trials"] == TRIALS and best_b["run"] == str(out / "trials" / best_b["run"]
                                                                     .split("/")[-1])


def test_ray_engine_writes_what_the_local_engine_writes(ray_local, setup, tmp_path, capsys):
    args, ref = setup
    out = tmp_path / "ray"
    assert main(["tune", "--out", str(out), "--trials", str(TRIALS), *args, "--engine", "ray"]) \
        == 0
    assert "tune on Ray: 2 trials at once (1 CPU, 0 GPU each)" in capsys.readouterr().out
    _assert_same_tuning(ref, out)


def test_ray_engine_resumes_after_a_trial_cap(ray_local, setup, tmp_path, capsys):
    args, ref = setup
    out = tmp_path / "capped"
    assert main(["tune", "--out", str(out), "--trials", "1", *args, "--engine", "ray",
                 "--trial-cpus", "2"]) == 0
    assert "1 trial at once (2 CPU, 0 GPU each)" in capsys.readouterr().out  # of 2 CPUs
    assert [r["trial"] for r in _rows(out)] == ["0"]
    assert _tune(out, args, "--engine", "ray", "--resume") == 0
    _assert_same_tuning(ref, out)


def test_trials_asking_for_more_than_the_cluster_has_are_refused(ray_local, setup, tmp_path,
                                                                 capsys):
    args, _ = setup
    assert _tune(tmp_path / "t", args, "--engine", "ray", "--trial-gpus", "1") == 2
    assert "a task asks for 1 CPU and 1 GPU, the cluster has 2 CPU and 0 GPU" \
        in capsys.readouterr().err


# A driver that kills itself (SIGKILL) once its first finished trial is on disk (trials.csv,
# pending.json and the outputs written): the same point of the tuning whatever the load.
KILLED_AFTER_FIRST_TRIAL = """
import os, signal, sys
from vistac.cli import main
from vistac_learn.tune import driver
write = driver._write_outputs
def write_then_die(out, rows, *args):
    write(out, rows, *args)
    if rows:
        os.kill(os.getpid(), signal.SIGKILL)
driver._write_outputs = write_then_die
sys.exit(main(sys.argv[1:]))
"""


def test_killed_ray_driver_then_resume(ray_local, setup, tmp_path):
    """A second driver joins the running instance by address and is killed with SIGKILL right
    after its first finished trial; the resumed tuning redoes the trials in flight and ends with
    the files of the local engine."""
    args, ref = setup
    address = ray_local.get_runtime_context().gcs_address
    out = tmp_path / "killed"
    cmd = [sys.executable, "-c", KILLED_AFTER_FIRST_TRIAL, "tune", "--out", str(out),
           "--trials", str(TRIALS), "--quiet", *args, "--engine", "ray", "--ray-address",
           address]
    proc = subprocess.run(cmd, timeout=600)
    assert proc.returncode == -signal.SIGKILL
    _wait_until_no_task_runs()
    assert len(_rows(out)) == 1 < TRIALS and json.loads((out / "pending.json").read_text())
    assert _tune(out, args, "--engine", "ray", "--resume") == 0
    _assert_same_tuning(ref, out)


def _wait_until_no_task_runs(timeout_s: float = 60.0) -> None:
    """Ray kills the workers running a dead driver's tasks; wait for that, so that no trial of
    the killed driver still writes while the resumed one runs (as a user restarting at once
    would, the next driver takes seconds to start)."""
    deadline = time.time() + timeout_s
    while time.time() < deadline:
        if not any(name == "ray::_call" for name in _descendants().values()):
            return
        time.sleep(0.1)
    raise AssertionError("a task of the killed driver still runs")


def _descendants() -> dict[int, str]:
    """pid -> process name of every descendant of this process (the module's Ray instance)."""
    parents, names = {}, {}
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            try:
                stat = open(os.path.join(entry.path, "stat")).read()
            except OSError:
                continue
            names[int(entry.name)] = stat[stat.index("(") + 1:stat.rindex(")")]
            parents[int(entry.name)] = int(stat[stat.rindex(")") + 2:].split()[1])
    found, frontier = {}, [os.getpid()]
    while frontier:
        parent = frontier.pop()
        for pid, ppid in parents.items():
            if ppid == parent and pid not in found:
                found[pid] = names[pid]
                frontier.append(pid)
    return found


def test_engine_options_are_checked_before_ray_starts(setup, tmp_path, capsys):
    args, _ = setup
    out = tmp_path / "t"
    assert _tune(out, args, "--ray-address", "127.0.0.1:6379") == 2
    assert "--ray-address: needs --engine ray" in capsys.readouterr().err
    assert _tune(out, args, "--max-concurrent", "2") == 2
    assert "--max-concurrent: needs --engine ray" in capsys.readouterr().err
    assert _tune(out, args, "--trial-gpus", "1") == 2
    assert "--trial-gpus: needs --engine ray" in capsys.readouterr().err
    assert _tune(out, [*args, "--device", "cuda"], "--engine", "ray") == 2
    assert "--device cuda: with --engine ray a trial sees only" in capsys.readouterr().err
    assert _tune(out, args, "--engine", "ray", "--trial-cpus", "0") == 2
    assert "--trial-cpus: must be > 0" in capsys.readouterr().err
    assert _tune(out, args, "--engine", "ray", "--max-concurrent", "0") == 2
    assert "--max-concurrent: must be >= 1" in capsys.readouterr().err
    assert _tune(out, args, "--engine", "ray", "--ray-address", "127.0.0.1:1") == 2
    assert "no Ray cluster answers there" in capsys.readouterr().err
    assert not out.exists()


def test_fingertips_are_located_once_before_the_trials(setup, tmp_path):
    """Trials running at once would each locate the fingertips of the dataset and race to write
    the cache; the driver does it first (for a view that needs them)."""
    from vistac_learn.train.config import protocol_cfg
    from vistac_learn.tune.engines import warm_fingertip_cache

    data = setup[0][1]
    study = protocol_cfg("study", data, str(tmp_path / "r"), cache_dir=str(tmp_path / "c1"))
    warm_fingertip_cache(study)
    assert not (tmp_path / "c1").exists()  # the study's views do not use them
    tip = protocol_cfg("default", data, str(tmp_path / "r"), cache_dir=str(tmp_path / "c2"))
    warm_fingertip_cache(tip)
    assert len(list((tmp_path / "c2").glob("fingertips-*.parquet"))) == 1
