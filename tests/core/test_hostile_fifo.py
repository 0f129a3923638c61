"""Only regular files are read where data is read (issue 31): a named pipe (FIFO) where a file
is expected (an image of the dataset, ``manifest.json``, ``--space``, a texture, an ``--init`` run's
``config.json`` or ``best.pt``) used to block the command forever, waiting for a writer. Each
row now ends in exit status 2 and one line naming the file; the folder is as it was, and once
the pipe is replaced by the real file the good command works.

An alarm turns a hang back into a failure of the test instead of a stuck suite.
"""

from __future__ import annotations

import os
import shutil
import signal
from collections.abc import Callable
from pathlib import Path

import pytest
from bad_input_env import GEN_OK, TRAIN_OK

import vistac
from vistac.cli import main
from vistac.errors import UserError

T = TRAIN_OK
TUNE = "tune --data {data} --out {out} --trials 1 --epochs 1 --size 16 --quiet --space {space}"


@pytest.fixture(autouse=True)
def _no_hang():
    def hung(*_):
        raise TimeoutError("hung reading a named pipe")

    previous = signal.signal(signal.SIGALRM, hung)
    signal.alarm(120)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def _pipe(path: Path) -> Path:
    """`path` replaced by a named pipe (its file kept beside it, to put back)."""
    if path.exists():
        path.rename(path.with_name(path.name + ".real"))
    os.mkfifo(path)
    return path


def _put_back(path: Path) -> None:
    path.unlink()
    path.with_name(path.name + ".real").rename(path)


def data_image(env, case: Path) -> dict:
    data = case / "data"
    shutil.copytree(env["paths"]["data"], data)
    return {"data": data, "pipe": _pipe(data / "images" / "000000.png")}


def data_manifest(env, case: Path) -> dict:
    data = case / "data"
    shutil.copytree(env["paths"]["data"], data)
    return {"data": data, "pipe": _pipe(data / "manifest.json")}


def space_file(env, case: Path) -> dict:
    case.mkdir(parents=True)
    (case / "space.json").write_text('{"init_points": 1}')
    return {"space": case / "space.json", "pipe": _pipe(case / "space.json")}


def init_file(name: str) -> Callable:
    def setup(env, case: Path) -> dict:
        init = case / "init"
        shutil.copytree(env["paths"]["run"], init)
        return {"init": init, "pipe": _pipe(init / name)}
    return setup


def texture(env, case: Path) -> dict:
    folder = case / "textures"
    folder.mkdir(parents=True)
    shutil.copy(Path(env["paths"]["data2"]) / "images" / "000000.png", folder / "a.png")
    return {"tex": folder, "pipe": _pipe(folder / "a.png")}


def finished_dataset_image(env, case: Path) -> dict:
    out = case / "out"
    shutil.copytree(env["paths"]["data2"], out)
    return {"pipe": _pipe(out / "images" / "000000.png")}


PIPE = "{pipe}: is a named pipe (FIFO), not a regular file"
CASES = {
    "train-image": (T, data_image, PIPE),
    "train-manifest": (T, data_manifest, PIPE),
    "tune-space": (TUNE, space_file, "--space " + PIPE),
    "train-init-config": (T + " --init {init}", init_file("config.json"), PIPE),
    "train-init-best": (T + " --init {init}", init_file("checkpoints/best.pt"),
                        "--init {init}: not a finished run (no checkpoints/best.pt)"),
    "generate-texture": (GEN_OK + " --preset photo --textures {tex}", texture,
                         "--textures " + PIPE),
    "generate-resume-image": (GEN_OK + " --resume", finished_dataset_image,
                              "{pipe}: a named pipe (FIFO), not a file"),
}


@pytest.mark.parametrize("case", CASES)
def test_a_named_pipe_is_refused_not_waited_on(case, env, capsys):
    template, setup, needle = CASES[case]
    case_dir = env["root"] / "fifo" / case
    paths = {**env["paths"], **{k: str(v) for k, v in setup(env, case_dir).items()}}
    argv = template.format(out=case_dir / "out", **paths).split()
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    assert needle.format(**paths) in err, err
    _put_back(Path(paths["pipe"]))
    assert main(argv) == 0, capsys.readouterr().err
    capsys.readouterr()


def test_the_api_refuses_a_named_pipe_image(env):
    ds = vistac.open_dataset(env["paths"]["data2"])
    path = ds.image_path(ds.config_ids[0])
    copy = env["root"] / "fifo" / "api"
    shutil.copytree(env["paths"]["data2"], copy)
    ds = vistac.open_dataset(copy)
    pipe = _pipe(copy / "images" / path.name)
    with pytest.raises(UserError, match=r"is a named pipe \(FIFO\), not a regular file"):
        ds.image(ds.config_ids[0])
    _put_back(pipe)
    assert ds.image(ds.config_ids[0]).ndim == 3


def _looping_checkpoints(env, case: Path) -> Path:
    run = case / "run"
    shutil.copytree(env["paths"]["run"], run)
    shutil.rmtree(run / "checkpoints")
    (run / "checkpoints").symlink_to(run / "checkpoints")  # a link to itself
    return run


@pytest.mark.parametrize("command", ["train", "evaluate"])
def test_a_looping_checkpoints_link_is_one_clear_line(command, env, capsys):
    """A run's ``checkpoints`` a symbolic link to itself used to be "[Errno 17] File exists"
    (train) or "best.pt: missing" (evaluate); the line now says what it is. Once the link is
    gone, training the run again works."""
    run = _looping_checkpoints(env, env["root"] / "fifo" / f"loop-{command}")
    argv = (T.format(out=run, **env["paths"]) if command == "train"
            else f"evaluate --run {run} --no-plots").split()
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    assert f"{run}/checkpoints: a symbolic link that cannot be followed" in err, err
    (run / "checkpoints").unlink()
    assert main(T.format(out=run, **env["paths"]).split()) == 0
