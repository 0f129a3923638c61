"""Learning runs under hard conditions (issue 22), beside the table of damaged inputs in
test_hostile_learn.py: a damaged run repaired or started over, the fingertip count and the
fingerprint a run reports, a full disk while saving, scoring or tuning, the memory estimate
behind `--size`, divergence, and a tuning killed at any write recording each trial once.
"""

from __future__ import annotations

import errno
import itertools
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch
from bad_input_env import EVAL_OK, TRAIN_OK
from test_hostile_learn import TUNE_OK, _argv, _bad_data, _data_copy, _shown, half, image

from vistac.cli import main
from vistac.errors import UserError

T = TRAIN_OK
E = EVAL_OK


def test_a_damaged_run_is_repaired_or_started_over(env, tmp_path, capsys):
    """--resume rewrites a damaged metrics.csv from the checkpoint; a finished run is nothing
    to do; a plain rerun over a damaged checkpoint starts the run over."""
    out = tmp_path / "run"
    shutil.copytree(env["paths"]["run"], out)
    good = (out / "metrics.csv").read_text()
    (out / "metrics.csv").write_text(good[:-9])
    assert main(_argv(T + " --resume", env["paths"], out)) == 0
    assert "nothing to do" in capsys.readouterr().out
    assert (out / "metrics.csv").read_text() == good
    (out / "checkpoints" / "last.pt").write_bytes(b"x")
    assert main(_argv(T, env["paths"], out)) == 0
    assert "run written to" in capsys.readouterr().out


def test_train_says_how_many_fingertips_were_found(env, tmp_path, capsys):
    out = tmp_path / "run"
    paths = env["paths"] | {k: str(v) for k, v in image("black")(env, tmp_path, out).items()}
    assert main(_argv(_bad_data(T) + " --max-missing-pct 50", paths, out)) == 0
    said = capsys.readouterr().out
    assert "fingertips not found in 1 of" in said and "of the train split" in said
    assert "fingertips found in all" in said  # the val split
    meta = json.loads((out / "config.json").read_text())
    assert meta["fingertips"]["train"]["missing"] == 1


def test_the_fingerprint_covers_the_labels(env, tmp_path, capsys):
    """Labels changed after training are not the run's dataset any more."""
    from vistac.dataset import open_tables

    data = _data_copy(env, tmp_path)
    before = open_tables(data)
    fingerprint, images = before.fingerprint(), before.image_fingerprint()
    presses = pd.read_parquet(data / "presses.parquet")
    presses[["r_y_index", "r_z_index"]] = presses[["r_z_index", "r_y_index"]].to_numpy()
    presses.to_parquet(data / "presses.parquet", index=False)
    after = open_tables(data)
    assert after.fingerprint() != fingerprint
    assert after.image_fingerprint() == images  # the fingertip cache still holds
    run = tmp_path / "run"
    shutil.copytree(env["paths"]["run"], run)
    meta = json.loads((run / "config.json").read_text())
    meta["dataset"] |= {"path": str(data), "fingerprint": fingerprint}
    (run / "config.json").write_text(json.dumps(meta))
    assert main(["evaluate", "--run", str(run), "--no-plots"]) == 2
    assert "has changed since training" in capsys.readouterr().err


def _enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device", "somewhere")


def test_a_full_disk_while_saving_a_checkpoint_is_one_line(env, tmp_path, monkeypatch, capsys):
    import vistac_learn.train.checkpoints as ck

    out = tmp_path / "run"
    monkeypatch.setattr(ck, "atomic_write_bytes", _enospc)
    assert main(_argv(T, env["paths"], out)) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "No space left on device" in err and "Traceback" not in err
    monkeypatch.undo()
    assert main(_argv(T, env["paths"], out)) == 0


@pytest.mark.parametrize("where", ["evaluate", "tune"])
def test_a_full_disk_while_scoring_or_tuning_is_one_line(env, tmp_path, monkeypatch, capsys,
                                                         where):
    """Scores and tuning tables are written through `atomic_write_bytes`: a full disk there is
    one line, and the command again (a tuning: with --resume) then works."""
    import vistac_learn.evaluate.run as ev
    import vistac_learn.tune.driver as tu

    out = tmp_path / where
    cmd = _argv(E if where == "evaluate" else TUNE_OK, env["paths"], out)
    monkeypatch.setattr(ev if where == "evaluate" else tu, "atomic_write_bytes", _enospc)
    assert main(cmd) == 2
    lines = _shown(capsys.readouterr().err)
    assert len(lines) == 1 and "No space left on device" in lines[0], lines
    monkeypatch.undo()
    assert main(cmd + (["--resume"] if where == "tune" else [])) == 0


def test_memory_estimate_grows_with_the_square_of_the_size():
    from vistac_learn.train.build import build_model
    from vistac_learn.train.config import protocol_cfg
    from vistac_learn.train.memory import check_fits, estimate_bytes

    model = build_model(protocol_cfg("default", "d", "o"))
    small = estimate_bytes(model, 3, 64, 32, 256)
    large = estimate_bytes(model, 3, 256, 32, 256)
    assert 12 < large[0] / small[0] < 17 and 12 < large[1] / small[1] < 17
    assert check_fits(model, 3, 48, 32, 256, torch.device("cpu"), available=2**34)
    with pytest.raises(UserError, match=r"--size 1024 --batch-size 32: .* GiB"):
        check_fits(model, 3, 1024, 32, 256, torch.device("cpu"), available=2**30)


def test_a_loss_past_the_bound_is_divergence():
    from vistac_learn.train.loop import DIVERGED_LOSS, diverged

    assert not diverged(2.0) and diverged(DIVERGED_LOSS * 1.01) and diverged(float("nan"))
    assert diverged(2.5e47) and diverged(float("inf"))


class _Killed(BaseException):
    """A SIGKILL at a chosen write (nothing after it runs)."""


def _killing(k: int, after: bool) -> Callable:
    """A wrapper of write functions that kills the process at the k-th write of any of them,
    just before or just after it."""
    calls = itertools.count(1)

    def wrap(f: Callable) -> Callable:
        def write(*args, **kwargs):
            n = next(calls)
            if n == k and not after:
                raise _Killed
            f(*args, **kwargs)
            if n == k and after:
                raise _Killed
        return write
    return wrap


@pytest.mark.parametrize("after", [False, True], ids=["before-a-write", "after-a-write"])
def test_a_trial_is_recorded_once_whatever_the_moment_of_the_kill(tmp_path, monkeypatch, after):
    """The tuning is killed at every one of its writes in turn (just before it, or just after)
    and resumed: trials.csv holds each trial once (the old driver wrote a trial twice when
    killed while it was in flight)."""
    import vistac_learn.tune.driver as D
    from vistac_learn.train.config import protocol_cfg
    from vistac_learn.train.job import JobResult, LocalJobRunner
    from vistac_learn.tune.space import load_space

    def job(cfg):
        return JobResult(cfg.train.out, abs(np.log10(cfg.train.lr) + 2.5), 1, 1, 1.0)

    monkeypatch.setattr("vistac_learn.tune.plots.plot_convergence", lambda rows, path: None)
    base, space = protocol_cfg("default", "data", "out"), load_space(None)
    originals = {name: getattr(D, name) for name in ("atomic_write_bytes", "atomic_write_json")}
    kills = 0
    for k in itertools.count(1):
        cfg = D.TuneCfg(out=str(tmp_path / f"kill-{k}"), trials=4, seed=0)
        wrap = _killing(k, after)
        for name, f in originals.items():
            monkeypatch.setattr(D, name, wrap(f))
        try:
            D.run_tune(cfg, base, space, runner=LocalJobRunner(job), progress=False)
        except _Killed:
            kills += 1
        else:
            break  # k is past the last write: nothing was killed
        finally:
            for name, f in originals.items():
                monkeypatch.setattr(D, name, f)
        res = D.run_tune(cfg, base, space, resume=(Path(cfg.out) / "config.json").exists(),
                         runner=LocalJobRunner(job), progress=False)
        assert [r["trial"] for r in res.rows] == [0, 1, 2, 3], k
        rows = pd.read_csv(Path(cfg.out) / "trials.csv")
        assert rows["trial"].tolist() == [0, 1, 2, 3], k
    assert kills >= 12


def test_a_damaged_trials_table_is_replayed_as_it_was(env, tmp_path, capsys):
    """--resume over a cut trials.csv scores the trials again from their run folders: the same
    trials, options and objectives."""
    out = tmp_path / "tune"
    cmd = _argv(TUNE_OK.replace("--trials 1", "--trials 2"), env["paths"], out)
    assert main(cmd) == 0
    before = pd.read_csv(out / "trials.csv")
    (out / "trials.csv").write_bytes(half((out / "trials.csv").read_bytes()))
    assert main([*cmd, "--resume"]) == 0
    after = pd.read_csv(out / "trials.csv")
    keep = [c for c in before.columns if c != "seconds"]
    pd.testing.assert_frame_equal(after[keep], before[keep])
