"""Interrupted runs and full disks: a damaged shard is made again on resume, a full disk is one
line and a rerun works, and a killed writer's temporaries do not outlive a rerun (issue 11).
"""

from __future__ import annotations

import errno
import os

import pytest
from bad_input_env import GEN_OK, ING_OK, TRAIN_OK

from vistac.cli import main
from vistac_sim.generate.shards import SHARD


def _one_error_line(capsys, needle: str) -> None:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in err, err


def _enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device", "somewhere")


def test_a_truncated_shard_is_made_again_on_resume(env, monkeypatch, capsys):
    from vistac_sim.generate.chunks import ChunkWork

    root = env["root"] / "truncated"
    args = ["--n", "4", "--image-size", "32", "--n-objects", "1", "--repeats", "1",
            "--chunk-size", "1", "--workers", "1", "--no-progress"]
    assert main(["generate", "--out", str(root / "ref"), *args]) == 0
    out = root / "d"
    original, done = ChunkWork.run_chunk, []

    def stops_after_two(work, chunk):
        if len(done) == 2:
            raise KeyboardInterrupt
        done.append(chunk)
        return original(work, chunk)

    monkeypatch.setattr(ChunkWork, "run_chunk", stops_after_two)
    assert main(["generate", "--out", str(out), *args]) == 130
    monkeypatch.setattr(ChunkWork, "run_chunk", original)
    shards = sorted((out / ".partial" / "shards").glob(f"*.configs{SHARD}"))
    assert len(shards) == 2
    shards[0].write_bytes(shards[0].read_bytes()[:40])  # a damaged shard
    (out / "images" / ".000003.png.999999999.tmp").write_bytes(b"half")  # a killed writer's
    capsys.readouterr()
    assert main(["generate", "--out", str(out), "--resume", *args]) == 0
    for name in ("configs.parquet", "presses.parquet"):
        assert (out / name).read_bytes() == (root / "ref" / name).read_bytes()
    assert not list(out.rglob("*.tmp")) and not (out / ".partial").exists()


def test_a_full_disk_is_one_line_and_a_rerun_works(env, monkeypatch, capsys):
    from vistac.dataset import files

    out = env["root"] / "full" / "gen"
    monkeypatch.setattr(files, "atomic_write_bytes", _enospc)
    assert main(GEN_OK.format(out=out).split()) == 2
    _one_error_line(capsys, "No space left on device")
    assert not out.exists()  # it had committed nothing: nothing is left
    monkeypatch.undo()
    assert main(GEN_OK.format(out=out).split()) == 0  # stopped before its first shard

    import vistac_learn.train.checkpoints as checkpoints

    run = env["root"] / "full" / "run"
    monkeypatch.setattr(checkpoints, "atomic_save", _enospc)
    assert main(TRAIN_OK.format(data=env["paths"]["data"], out=run).split()) == 2
    _one_error_line(capsys, "No space left on device")
    monkeypatch.undo()
    assert main(TRAIN_OK.format(data=env["paths"]["data"], out=run).split()) == 0

    ing = env["root"] / "full" / "ing"
    monkeypatch.setattr(files, "write_table", _enospc)
    assert main(ING_OK.format(out=ing, **env["paths"]).split()) == 2
    _one_error_line(capsys, "No space left on device")
    assert not ing.exists() and not list(ing.parent.glob(f".{ing.name}*"))
    monkeypatch.undo()
    assert main(ING_OK.format(out=ing, **env["paths"]).split()) == 0


def test_a_killed_writers_temporaries_do_not_outlive_a_rerun(env, tmp_path):
    from vistac.dataset.files import atomic_write_bytes, remove_stale_temporaries

    live = tmp_path / f".a.{os.getpid()}.tmp"  # this process's: still being written
    dead = tmp_path / ".b.999999999.tmp"
    live.write_bytes(b"x")
    dead.write_bytes(b"x")
    assert remove_stale_temporaries(tmp_path) == 1
    assert live.exists() and not dead.exists()
    (tmp_path / "sub").mkdir()
    # a failed write leaves no temporary, and its error names the file (an OSError still)
    with pytest.raises(OSError, match="sub: cannot be written: Is a directory"):
        atomic_write_bytes(tmp_path / "sub", b"x")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([live.name, "sub"])


def test_resume_checks_masks_too(tmp_path, capsys):
    """A finished dataset with --masks whose mask is gone is not 'complete'; one line names it."""
    out = tmp_path / "m"
    argv = GEN_OK.format(out=out).split() + ["--masks"]
    assert main(argv) == 0
    (out / "masks" / "000001.png").unlink()
    capsys.readouterr()
    assert main(argv + ["--resume"]) == 2
    _one_error_line(capsys, "000001.png: missing")
    (out / "masks" / "000001.png").write_bytes((out / "masks" / "000000.png").read_bytes())
    assert main(argv + ["--resume"]) == 0  # whole again: nothing to do
    assert "nothing to do" in capsys.readouterr().out
