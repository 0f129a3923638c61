"""One writer per output folder, and checkpoints that cannot run code (issue 22).

Two real processes race for one dataset folder; every writing command refuses a folder another
process holds (one line naming the holder) and works once it is free; a stale lock of a killed
process is taken over; a checkpoint carrying a pickled call is refused by `evaluate` and
`train --init` without running it.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
import torch
from bad_input_env import EVAL_OK, GEN_OK, ING_OK, TRAIN_OK

from vistac.cli import main
from vistac.errors import UserError
from vistac.folder_lock import hold, lock_path

VISTAC = [str(Path(sys.executable).parent / "vistac")]


def _one_error_line(capsys, *needles: str) -> str:
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err


def _wait_for(path: Path, timeout: float = 60.0) -> None:
    t0 = time.monotonic()
    while not path.exists():
        assert time.monotonic() - t0 < timeout, f"{path} never appeared"
        time.sleep(0.02)


def test_two_generate_processes_into_one_folder(tmp_path):
    """The second process is refused while the first works; the first's dataset is whole."""
    out = tmp_path / "d"
    argv = ["generate", "--out", str(out), "--n", "150", "--image-size", "32", "--repeats", "2",
            "--n-objects", "2", "--chunk-size", "10", "--workers", "1", "--no-progress"]
    first = subprocess.Popen(VISTAC + argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True)
    try:
        _wait_for(lock_path(out))
        second = subprocess.run(VISTAC + argv[:-1] + ["--seed", "7", "--no-progress"],
                                capture_output=True, text=True, timeout=120)
        assert first.poll() is None, "the first run ended before the race could be tested"
    finally:
        _, first_err = first.communicate(timeout=300)
    assert first.returncode == 0, first_err
    assert second.returncode == 2, second.stderr
    line = second.stderr.strip()
    assert line.count("\n") == 0 and "Traceback" not in line, line
    assert f"pid {first.pid}" in line and "in use by" in line, line
    configs = pd.read_parquet(out / "configs.parquet")
    assert len(configs) == 150 and configs["config_id"].is_unique
    assert sorted(p.name for p in (out / "images").iterdir()) == sorted(configs["image"])
    assert not lock_path(out).exists()  # released and removed


def test_a_killed_holders_lock_is_taken_over(tmp_path):
    out = tmp_path / "run"
    code = ("import sys, time\nfrom vistac.folder_lock import hold\n"
            "with hold(sys.argv[1], 'sleeper'):\n    print('held', flush=True)\n"
            "    time.sleep(600)\n")
    proc = subprocess.Popen([sys.executable, "-c", code, str(out)], stdout=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stdout.readline().strip() == "held"
        with pytest.raises(UserError, match=rf"in use by pid {proc.pid} on .*'sleeper'"):
            with hold(out):
                pass
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert lock_path(out).exists()  # a kill -9 leaves the file ...
    with hold(out, "me") as path:  # ... but not the lock
        assert f'"pid": {os.getpid()}' in path.read_text()
    assert not lock_path(out).exists()


def test_one_process_cannot_hold_a_folder_twice(tmp_path):
    with hold(tmp_path / "x", "outer"):
        with pytest.raises(UserError, match="--out .*x: in use by pid"):
            with hold(tmp_path / "x", "inner"):
                pass
        with hold(tmp_path / "y"):  # another folder is free
            pass


TUNE_OK = "tune --data {data} --out {out} --trials 1 --epochs 1 --size 16 --quiet"
LN_OK = ("experiment label-noise --data {data} --out {out} --levels 0 --seeds 1 --epochs 1 "
         "--size 16 --quiet")


@pytest.mark.parametrize("template", [GEN_OK, ING_OK, TRAIN_OK, TUNE_OK, LN_OK],
                         ids=["generate", "ingest", "train", "tune", "experiment"])
def test_every_writing_command_refuses_a_held_folder(template, env, tmp_path, capsys):
    paths = env["paths"]
    out = tmp_path / "out"
    argv = template.format(out=out, data=paths["data"], rec=paths["rec"],
                           img=paths["img"], run=paths["run"]).split()
    with hold(out, "holder"):
        assert main(argv) == 2
        _one_error_line(capsys, f"--out {out}: in use by pid {os.getpid()}", "'holder'")
        assert not out.exists()  # nothing written into a folder somebody else holds
    if template in (GEN_OK, ING_OK, TRAIN_OK):  # and free again once released
        assert main(argv) == 0


def _evil_checkpoint(run: Path, marker: Path) -> None:
    class Payload:
        def __reduce__(self):
            return os.system, (f"touch {marker}",)

    good = torch.load(run / "checkpoints" / "best.pt", weights_only=True)
    torch.save(good | {"note": Payload()}, run / "checkpoints" / "best.pt")


@pytest.mark.parametrize("command", ["evaluate", "init", "api"])
def test_a_checkpoint_carrying_code_is_refused_unrun(command, env, tmp_path, capsys):
    run, marker = tmp_path / "run", tmp_path / "pwned"
    shutil.copytree(env["paths"]["run"], run)
    _evil_checkpoint(run, marker)
    if command == "api":  # vistac.Run.open reads the best checkpoint too
        import vistac

        with pytest.raises(UserError, match="best.pt: holds pickled objects"):
            vistac.Run.open(run)
        assert not marker.exists()
        return
    if command == "evaluate":
        argv = EVAL_OK.format(run=run, out=tmp_path / "eval").split()
    else:
        argv = TRAIN_OK.format(data=env["paths"]["data"], out=tmp_path / "ft").split() \
            + ["--init", str(run)]
    assert main(argv) == 2
    _one_error_line(capsys, "best.pt", "pickled objects")
    assert not marker.exists()


def test_checkpoints_hold_plain_data_only(env):
    """Every checkpoint a run writes loads with weights_only=True (resume included)."""
    for name in ("best.pt", "last.pt"):
        ck = torch.load(Path(env["paths"]["run"]) / "checkpoints" / name, weights_only=True)
        assert isinstance(ck["model"], dict) and isinstance(ck["epoch"], int)


def test_a_refused_generate_leaves_the_holders_files_alone(tmp_path):
    """The clean-up of an unstarted run happens under the lock, never on another's run."""
    import vistac

    out = tmp_path / "d"
    (out / ".partial").mkdir(parents=True)
    (out / ".partial" / "run.json").write_text("{}")
    (out / "images").mkdir()
    (out / "images" / "000000.png").write_bytes(b"in the making")
    with hold(out, "holder"):
        with pytest.raises(UserError, match="in use by pid"):
            vistac.generate(vistac.GenerateCfg(n=2), out, workers=1)
    assert (out / ".partial" / "run.json").exists()
    assert (out / "images" / "000000.png").read_bytes() == b"in the making"


def test_evaluate_refuses_a_held_output_folder(env, tmp_path, capsys):
    out = tmp_path / "eval"
    with hold(out, "holder"):
        assert main(EVAL_OK.format(run=env["paths"]["run"], out=out).split()) == 2
        _one_error_line(capsys, "in use by pid")
    assert main(EVAL_OK.format(run=env["paths"]["run"], out=out).split()) == 0
