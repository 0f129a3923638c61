"""Hostile input to the learning commands (issue 22): damaged datasets, run folders and caches,
images without fingertips, diverging losses, failed tunings.

Each case runs `vistac.cli.main` in-process (as tests/core/test_bad_input.py does) and asserts
the exit status, exactly one line on stderr naming what is wrong, no traceback, and that a good
command into the same `--out` then works. The shared data are `bad_input_env.env`'s (a tiny
generated dataset and a one-epoch run on it); a case damages its own copy.
"""

from __future__ import annotations

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
        from vistac.dataset import open_tables
        from vistac_learn.data.fingertip_table import fingertip_table

        data = _data_copy(env, case_dir)
        fingertip_table(open_tables(data))
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
