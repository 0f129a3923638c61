"""A full disk, for real (issue 31): a small tmpfs is mounted where the test may mount one
(skipped otherwise), a command writes into it until the disk is full, and the one line it ends
with names the file and says what to do (the system's own error names neither); nothing is
left half-written, and the command works once there is room.
"""

from __future__ import annotations

import contextlib
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from bad_input_env import EVAL_OK, GEN_OK

from vistac.cli import main

FULL = "cannot be written: "
ADVICE = "No space left on device; free some space there and run the command again"


@contextlib.contextmanager
def tmpfs(where: Path, size: str) -> Iterator[Path]:
    where.mkdir(parents=True, exist_ok=True)
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs",
                              str(where)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


def _one_line(capsys, folder: Path) -> str:
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    assert err.startswith("vistac") and f"{folder}/" in err and FULL in err and ADVICE in err, err
    return err


@pytest.mark.skipif(shutil.which("mount") is None, reason="no mount command")
def test_a_full_disk_names_the_file(env, tmp_path, capsys):
    with tmpfs(tmp_path / "small", "24k") as disk:
        out = disk / "d"
        capsys.readouterr()
        assert main(GEN_OK.format(out=out).split()) == 2
        _one_line(capsys, out)
        assert not out.exists()  # it had committed nothing: nothing is left

        ev = disk / "eval"
        argv = EVAL_OK.format(run=env["paths"]["run"], out=ev).split()
        shutil.rmtree(out, ignore_errors=True)
        (disk / "filler").write_bytes(b"x" * 16384)  # what is left: room for the marker only
        assert main(argv) == 2
        _one_line(capsys, ev)
        assert sorted(p.name for p in ev.iterdir()) == [".vistac-kind"]  # no torn file
        (disk / "filler").unlink()
    with tmpfs(tmp_path / "roomy", "64m") as disk:
        assert main(GEN_OK.format(out=disk / "d").split()) == 0
        assert main(EVAL_OK.format(run=env["paths"]["run"], out=disk / "eval").split()) == 0
