"""Hostile input to the learning commands (issue 22): damaged datasets, run folders and caches,
images without fingertips, diverging losses, failed tunings.

Each case runs `vistac.cli.main` in-process (as tests/core/test_bad_input.py does) and asserts
the exit status, exactly one line on stderr naming what is wrong, no traceback, and that a good
command into the same `--out` then works. The shared data are `bad_input_env.env`'s (a tiny
generated dataset and a one-epoch run on it); a case damages its own copy.
"""

from __future__ import annotations

import errno
import itertools
import json
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
import torch
from bad_input_env import EVAL_OK, TRAIN_OK

from vistac.cli import main
from vistac.errors import UserError

T = TRAIN_OK
E = EVAL_OK
TUNE_OK = "tune --data {data} --out {out} --trials 1 --epochs 1 --size 16 --quiet"
NOISE_OK = ("experiment label-noise --data {data} --out {out} --levels 0 --seeds 1 --epochs 1 "
            "--size 16 --quiet")
RETRAIN = T  # a plain rerun into a damaged run folder starts the run over


# ------------------------------------------------------------------------ damaging copies
def _data_copy(env, case_dir: Path) -> Path:
    """A copy of the shared dataset (no cache, no recordings) to damage."""
    src = Path(env["paths"]["data"])
    dst = case_dir / "data"
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns("cache", "recordings"))
    return dst


def _image_of(data: Path, split: str) -> Path:
    configs = pd.read_parquet(data / "configs.parquet").sort_values("config_id")
    return data / "images" / configs.loc[configs["split"] == split, "image"].iat[0]


def image(kind: str, split: str = "train") -> Callable:
    """Replace one image of `split` by a hostile one."""
    def damage(env, case_dir: Path, out: Path) -> dict:
        data = _data_copy(env, case_dir)
        path = _image_of(data, split)
        img = cv2.imread(str(path))
        new = {"black": np.zeros_like(img), "grey": np.full_like(img, 128),
               "1x1": img[:1, :1], "small": cv2.resize(img, (12, 12)),
               "white": np.full_like(img, 255)}[kind]
        cv2.imwrite(str(path), new)
        return {"bad": data}
    return damage


def every_image_black(env, case_dir: Path, out: Path) -> dict:
    data = _data_copy(env, case_dir)
    for p in (data / "images").glob("*.png"):
        cv2.imwrite(str(p), np.zeros((64, 64, 3), np.uint8))
    return {"bad": data}


def manifest(change: Callable[[dict], object]) -> Callable:
    def damage(env, case_dir: Path, out: Path) -> dict:
        data = _data_copy(env, case_dir)
        m = json.loads((data / "manifest.json").read_text())
        (data / "manifest.json").write_text(json.dumps(change(m)))
        return {"bad": data}
    return damage


def file_bytes(name: str, change: Callable[[bytes], bytes]) -> Callable:
    """Change the bytes of a dataset file."""
    def damage(env, case_dir: Path, out: Path) -> dict:
        data = _data_copy(env, case_dir)
        (data / name).write_bytes(change((data / name).read_bytes()))
        return {"bad": data}
    return damage


def table(name: str, change: Callable[[pd.DataFrame], pd.DataFrame]) -> Callable:
    """Rewrite a dataset table, changed."""
    def damage(env, case_dir: Path, out: Path) -> dict:
        data = _data_copy(env, case_dir)
        change(pd.read_parquet(data / name)).to_parquet(data / name, index=False)
        return {"bad": data}
    return damage


def _set(frame: pd.DataFrame, col: str, row: int, value) -> pd.DataFrame:
    frame = frame.copy()
    if isinstance(value, str):
        frame[col] = frame[col].astype(str)
    frame.loc[row, col] = value
    return frame


def _ids_as_text(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.assign(config_id=frame["config_id"].astype(str))


def run_file(name: str, change: Callable[[bytes], bytes]) -> Callable:
    """A copy of the shared one-epoch run in {out}, one of its files changed."""
    def damage(env, case_dir: Path, out: Path) -> dict:
        shutil.copytree(env["paths"]["run"], out)
        (out / name).write_bytes(change((out / name).read_bytes()))
        return {}
    return damage


def damaged_init(env, case_dir: Path, out: Path) -> dict:
    """A run to start from (--init) whose best checkpoint is cut short."""
    run_file("checkpoints/best.pt", half)(env, case_dir, case_dir / "init")
    return {"bad": case_dir / "init"}


def config_value(key: str, value) -> Callable:
    def change(raw: bytes) -> bytes:
        meta = json.loads(raw)
        meta["train"][key] = value
        return json.dumps(meta).encode()
    return change


def half(raw: bytes) -> bytes:
    return raw[:len(raw) // 2]


def foreign_checkpoint(raw: bytes) -> bytes:
    import io

    buf = io.BytesIO()
    torch.save([1, 2, 3], buf)
    return buf.getvalue()


def cut_metrics_row(raw: bytes) -> bytes:
    return raw.rstrip(b"\n")[:-7]  # the last row cut in the middle


def text_in_metrics(raw: bytes) -> bytes:
    lines = raw.decode().splitlines()
    cells = lines[1].split(",")
    cells[2] = "lots"
    return "\n".join([lines[0], ",".join(cells)]).encode() + b"\n"


def cache(change: Callable[[Path], None]) -> Callable:
    """A dataset copy whose fingertip cache is located, then damaged."""
    def damage(env, case_dir: Path, out: Path) -> dict:
        from vistac.dataset import open_dataset
        from vistac_learn.data.fingertip_table import fingertip_table

        data = _data_copy(env, case_dir)
        fingertip_table(open_dataset(data))
        (path,) = (data / "cache").glob("fingertips-*.parquet")
        change(path)
        return {"bad": data}
    return damage


def finished(command: str, name: str, change: Callable[[bytes], bytes]) -> Callable:
    """A finished tuning or experiment in {out} (made by `command`), one of its files changed."""
    def damage(env, case_dir: Path, out: Path) -> dict:
        assert main(command.format(out=out, **env["paths"]).split()) == 0
        (out / name).write_bytes(change((out / name).read_bytes()))
        return {}
    return damage


def space_file(params: dict) -> Callable:
    def setup(env, case_dir: Path, out: Path) -> dict:
        case_dir.mkdir(parents=True, exist_ok=True)
        (case_dir / "space.json").write_text(json.dumps({"init_points": 1, "params": params}))
        return {"space": case_dir / "space.json"}
    return setup


# -------------------------------------------------------------------------------- the table
@dataclass
class Case:
    """A hostile command: its arguments, the text its one error line must contain, the exit
    status, how its input is made (`setup`) and the good commands then run into {out}."""

    id: str
    argv: str
    needle: str
    setup: Callable | None = None
    code: int = 2
    good: tuple[str, ...] = ()


def _bad_data(cmd: str) -> str:
    return cmd.replace("{data}", "{bad}")


EB = E + " --data {bad} --cross-dataset"  # evaluate the run on a damaged copy of its data
NOT_FOUND = "fingertips not found"

CASES = [
    # ------------------------------------------------ no score without data (train, evaluate)
    Case("train-black-image", _bad_data(T), NOT_FOUND, image("black")),
    Case("train-grey-image", _bad_data(T), NOT_FOUND, image("grey")),
    Case("train-white-image", _bad_data(T), NOT_FOUND, image("white")),
    Case("train-1x1-image", _bad_data(T), NOT_FOUND, image("1x1")),
    Case("train-mixed-image-sizes", _bad_data(T), NOT_FOUND, image("small")),
    Case("train-black-val-image", _bad_data(T), "of the val split", image("black", "val")),
    Case("train-every-image-black", _bad_data(T), NOT_FOUND, every_image_black),
    Case("train-black-image-allowed", _bad_data(T) + " --max-missing-pct 100", "", image("black"),
         code=0),
    Case("train-max-missing-pct-negative", T + " --max-missing-pct -1", "--max-missing-pct"),
    Case("train-max-missing-pct-nan", T + " --max-missing-pct nan", "--max-missing-pct"),
    Case("eval-black-test-image", EB, NOT_FOUND, image("black", "test"), good=(E,)),
    Case("eval-1x1-test-image", EB, NOT_FOUND, image("1x1", "test"), good=(E,)),
    Case("eval-max-missing-pct", E + " --max-missing-pct 101", "--max-missing-pct", good=(E,)),
    Case("eval-baseline-black-image", "evaluate --baseline geometric --data {bad} --split train "
         "--no-plots --out {out}", NOT_FOUND, image("black"), good=(E,)),
    Case("tune-black-image", _bad_data(TUNE_OK), NOT_FOUND, image("black"), good=(TUNE_OK,)),
    Case("experiment-black-image", _bad_data(NOISE_OK), NOT_FOUND, image("black"),
         good=(NOISE_OK,)),
    # ------------------------------------------------ divergence, a failed tuning, sizes
    # a regressor (the tip view) can diverge; the pinch view composes unit labels, bounded
    Case("train-lr-100", T + " --lr 100 --variant tip --model tipnet", "diverged"),
    Case("train-lr-1e4-constant", T + " --lr 1e4 --schedule constant", "diverged"),
    Case("tune-every-trial-diverges", TUNE_OK + " --space {space}", "no trial succeeded",
         space_file({"lr": {"low": 1e3, "high": 1e4, "scale": "log"}}), good=(TUNE_OK,)),
    Case("train-size-beyond-memory", T.replace("--size 16", "--size 1024")
         + " --batch-size 65536", "GiB"),
    Case("tune-trials-csv-cut", TUNE_OK + " --resume", "", finished(TUNE_OK, "trials.csv", half),
         code=0, good=(TUNE_OK + " --resume",)),
    Case("tune-pending-json-text", TUNE_OK + " --resume", "",
         finished(TUNE_OK, "pending.json", lambda b: b"{1: 2"), code=0,
         good=(TUNE_OK + " --resume",)),
    Case("tune-config-truncated", TUNE_OK + " --resume", "",
         finished(TUNE_OK, "config.json", half), code=0, good=(TUNE_OK + " --resume",)),
    Case("experiment-cells-cut", NOISE_OK, "", finished(NOISE_OK, "cells.csv", half), code=0,
         good=(NOISE_OK,)),
    Case("experiment-config-truncated", NOISE_OK, "", finished(NOISE_OK, "config.json", half),
         code=0, good=(NOISE_OK,)),
    # ------------------------------------------------ damaged datasets
    Case("data-format-version-99", _bad_data(T), "format_version",
         manifest(lambda m: m | {"format_version": 99})),
    Case("data-format-version-missing", _bad_data(T), "format_version",
         manifest(lambda m: {k: v for k, v in m.items() if k != "format_version"})),
    Case("data-format-version-0", _bad_data(T), "format_version",
         manifest(lambda m: m | {"format_version": 0})),
    Case("data-format-version-1.5", _bad_data(T), "format_version",
         manifest(lambda m: m | {"format_version": 1.5})),
    Case("data-format-version-text", _bad_data(T), "format_version",
         manifest(lambda m: m | {"format_version": "one"})),
    Case("data-manifest-a-list", _bad_data(T), "manifest.json", manifest(lambda m: [m])),
    Case("data-manifest-truncated", _bad_data(T), "manifest.json",
         file_bytes("manifest.json", half)),
    Case("data-configs-truncated", _bad_data(T), "configs.parquet",
         file_bytes("configs.parquet", half)),
    Case("data-presses-truncated", _bad_data(T), "presses.parquet",
         file_bytes("presses.parquet", half)),
    Case("data-presses-empty-file", _bad_data(T), "presses.parquet",
         file_bytes("presses.parquet", lambda b: b"")),
    Case("data-configs-not-parquet", _bad_data(T), "configs.parquet",
         file_bytes("configs.parquet", lambda b: b"config_id,image\n1,a.png\n")),
    Case("data-config-ids-as-text", _bad_data(T), "config_id",
         table("configs.parquet", _ids_as_text)),
    Case("data-label-as-text", _bad_data(T), "r_y_index",
         table("presses.parquet", lambda f: _set(f, "r_y_index", 0, "up"))),
    Case("data-label-not-unit", _bad_data(T), "not a unit vector",
         table("presses.parquet", lambda f: _set(f, "r_y_index", 0, 3.0))),
    Case("data-label-nan", _bad_data(T), "non-finite",
         table("presses.parquet", lambda f: _set(f, "r_z_thumb", 1, np.nan))),
    Case("data-presses-of-unknown-config", _bad_data(T), "unknown config_id",
         table("presses.parquet", lambda f: _set(f, "config_id", 0, 10**6))),
    Case("data-press-twice", _bad_data(T), "more than once",
         table("presses.parquet", lambda f: pd.concat([f, f.iloc[:1]], ignore_index=True))),
    Case("data-image-outside-the-folder", _bad_data(T), "not a file name",
         table("configs.parquet", lambda f: _set(f, "image", 0, "../../manifest.json"))),
    # ------------------------------------------------ damaged run folders
    Case("resume-last-truncated", T + " --resume", "last.pt", run_file("checkpoints/last.pt",
         half), good=(RETRAIN,)),
    Case("resume-last-foreign", T + " --resume", "not a checkpoint",
         run_file("checkpoints/last.pt", foreign_checkpoint), good=(RETRAIN,)),
    Case("resume-last-text", T + " --resume", "last.pt",
         run_file("checkpoints/last.pt", lambda b: b"not a checkpoint"), good=(RETRAIN,)),
    Case("resume-best-truncated", T + " --resume", "best.pt",
         run_file("checkpoints/best.pt", half), good=(RETRAIN,)),
    Case("resume-config-truncated", T + " --resume", "config.json",
         run_file("config.json", half), good=(RETRAIN,)),
    Case("resume-config-a-list", T + " --resume", "config.json",
         run_file("config.json", lambda b: b"[1, 2]"), good=(RETRAIN,)),
    Case("resume-metrics-cut", T + " --resume", "", run_file("metrics.csv", cut_metrics_row),
         code=0),
    Case("resume-metrics-text", T + " --resume", "", run_file("metrics.csv", text_in_metrics),
         code=0),
    Case("resume-finished-run", T + " --resume", "", run_file("metrics.csv", lambda b: b),
         code=0),
    Case("eval-best-truncated", "evaluate --run {out} --no-plots", "best.pt",
         run_file("checkpoints/best.pt", half), good=(RETRAIN, "evaluate --run {out} --no-plots")),
    Case("eval-config-truncated", "evaluate --run {out} --no-plots", "config.json",
         run_file("config.json", half), good=(RETRAIN, "evaluate --run {out} --no-plots")),
    Case("eval-config-bad-setting", "evaluate --run {out} --no-plots", "train settings",
         run_file("config.json", config_value("lr", -1)),
         good=(RETRAIN, "evaluate --run {out} --no-plots")),
    Case("init-best-truncated", T + " --init {bad}", "--init", damaged_init),
    # ------------------------------------------------ a damaged fingertip cache is rebuilt
    Case("cache-truncated", _bad_data(T), "", cache(lambda p: p.write_bytes(half(p.read_bytes()))),
         code=0),
    Case("cache-other-rows", _bad_data(T), "",
         cache(lambda p: pd.read_parquet(p).iloc[:2].to_parquet(p)), code=0),
]


def _shown(err: str) -> list[str]:
    """The lines of stderr as a terminal shows them: a progress bar that cleared itself with
    carriage returns (``leave=False``) leaves nothing."""
    lines = (line.split("\r")[-1] for line in err.split("\n"))
    return [line for line in lines if line.strip()]


def _argv(template: str, paths: dict, out: Path) -> list[str]:
    return template.format(out=out, **paths).split()


def test_the_table_is_large_enough():
    assert len(CASES) >= 30
    assert len({c.id for c in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_hostile_learn(case: Case, env, capsys):
    case_dir = env["root"] / "hostile" / case.id
    out = case_dir / "out"
    paths = dict(env["paths"])
    if case.setup is not None:
        paths |= {k: str(v) for k, v in case.setup(env, case_dir, out).items()}
    capsys.readouterr()
    rc = main(_argv(case.argv, paths, out))
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err + captured.out
    assert rc == case.code, captured.err
    if case.code == 2:
        lines = _shown(captured.err)
        assert len(lines) == 1, captured.err
        assert case.needle in lines[0] and lines[0].startswith("vistac"), lines[0]
    else:
        assert case.needle in captured.out
    # a good command into the same folder then works (after a success: --resume, nothing to do)
    again = case.argv if "--resume" in case.argv else case.argv + " --resume"
    for good in case.good or ((T,) if case.code else (again,)):
        assert main(_argv(good, paths, out)) == 0, f"good rerun {good!r} failed after {case.id}"
        capsys.readouterr()


# ---------------------------------------------------------------------- what the table needs
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
    from vistac.dataset import open_dataset

    data = _data_copy(env, tmp_path)
    before = open_dataset(data)
    fingerprint, images = before.fingerprint(), before.image_fingerprint()
    presses = pd.read_parquet(data / "presses.parquet")
    presses[["r_y_index", "r_z_index"]] = presses[["r_z_index", "r_y_index"]].to_numpy()
    presses.to_parquet(data / "presses.parquet", index=False)
    after = open_dataset(data)
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
    from vistac_learn.train.config import build_model, protocol_cfg
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
    from vistac_learn.train.job import JobResult, LocalRunner
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
            D.run_tune(cfg, base, space, runner=LocalRunner(job), progress=False)
        except _Killed:
            kills += 1
        else:
            break  # k is past the last write: nothing was killed
        finally:
            for name, f in originals.items():
                monkeypatch.setattr(D, name, f)
        res = D.run_tune(cfg, base, space, resume=(Path(cfg.out) / "config.json").exists(),
                         runner=LocalRunner(job), progress=False)
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
