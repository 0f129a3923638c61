"""`vistac generate --engine ray`: byte-identical to the local engine, kill and resume, options."""

from __future__ import annotations

import json
import signal
import subprocess
import sys

import pytest

from vistac.cli import main
from vistac.errors import UserError
from vistac_sim.generate import on_ray
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.plan import plan_chunks
from vistac_sim.generate.shards import SHARD

ARGS = ["--n", "18", "--seed", "5", "--noise", "0.05", "--n-objects", "3", "--chunk-size", "3",
        "--repeats", "2", "--no-progress"]
N_CHUNKS = len(plan_chunks(n=18, seed=5, n_objects=3, chunk_size=3))


def _gen(out, *extra):
    return main(["generate", "--out", str(out), *ARGS, *extra])


def _assert_same_dataset(a, b):
    for name in ("presses.parquet", "configs.parquet"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    images = sorted(p.name for p in (a / "images").iterdir())
    assert images and sorted(p.name for p in (b / "images").iterdir()) == images
    for name in images:
        assert (a / "images" / name).read_bytes() == (b / "images" / name).read_bytes(), name
    ma, mb = (json.loads((d / "manifest.json").read_text()) for d in (a, b))
    assert ma["counts"] == mb["counts"] and ma["redraws"] == mb["redraws"]


@pytest.fixture(scope="module")
def local_reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("local") / "d"
    assert _gen(out, "--workers", "1") == 0
    return out


def test_ray_engine_writes_the_bytes_of_the_local_engine(ray_local, local_reference, tmp_path):
    assert _gen(tmp_path / "ray", "--engine", "ray") == 0
    _assert_same_dataset(local_reference, tmp_path / "ray")
    manifest = json.loads((tmp_path / "ray" / "manifest.json").read_text())
    assert manifest["engine"] == "ray" and manifest["complete"]


def test_workers_writing_into_the_shared_folder_write_the_same_bytes(ray_local, local_reference,
                                                                   tmp_path, monkeypatch):
    made = []
    monkeypatch.setattr(on_ray, "commit_chunk", lambda *a: made.append(a))  # not the driver's
    assert _gen(tmp_path / "w", "--engine", "ray", "--ray-writes", "workers") == 0
    assert made == []
    _assert_same_dataset(local_reference, tmp_path / "w")
    assert not (tmp_path / "w" / ".partial").exists()  # the marker went with it


def test_a_worker_writes_only_into_the_drivers_folder_with_its_versions(tmp_path):
    versions = {"mujoco": "1", "numpy": "2", "trimesh": "3"}
    (tmp_path / ".partial").mkdir()
    (tmp_path / ".partial" / "shared-ab").touch()
    job = on_ray.ChunkJob(GenerateCfg(), (), str(tmp_path), "shared-ab",
                          tuple(sorted(versions.items())))
    job.check_writable("node1", versions)
    with pytest.raises(UserError, match="node node2 runs .* this driver"):
        job.check_writable("node2", versions | {"numpy": "9"})
    other = on_ray.ChunkJob(GenerateCfg(), (), str(tmp_path), "shared-cd",
                            tuple(sorted(versions.items())))
    with pytest.raises(UserError, match="node node3 does not see the driver's --out"):
        other.check_writable("node3", versions)


# A driver that kills itself (SIGKILL) right after committing its second chunk: the kill
# lands at the same point of the run whatever the machine's load.
KILLED_AFTER_TWO_CHUNKS = """
import os, signal, sys
from vistac.cli import main
from vistac_sim.generate import on_ray
commit, done = on_ray.commit_chunk, []
def commit_then_die(*args):
    result = commit(*args)
    done.append(args[1])
    if len(done) == 2:
        os.kill(os.getpid(), signal.SIGKILL)
    return result
on_ray.commit_chunk = commit_then_die
sys.exit(main(sys.argv[1:]))
"""


def test_killed_ray_driver_then_resume_equals_local(ray_local, local_reference, tmp_path,
                                                    monkeypatch):
    """A second driver joins the running instance by address and is killed with SIGKILL right
    after its second committed chunk; resuming makes only the others, with the same bytes as
    locally."""
    address = ray_local.get_runtime_context().gcs_address
    out = tmp_path / "killed"
    cmd = [sys.executable, "-c", KILLED_AFTER_TWO_CHUNKS, "generate", "--out", str(out), *ARGS,
           "--engine", "ray", "--ray-address", address]
    proc = subprocess.run(cmd, timeout=300)
    assert proc.returncode == -signal.SIGKILL
    shards = out / ".partial" / "shards"
    before = {int(p.name[6:11]) for p in shards.glob(f"*.configs{SHARD}")}
    assert len(before) == 2 < N_CHUNKS and not (out / "manifest.json").exists()
    made = []
    commit = on_ray.commit_chunk
    monkeypatch.setattr(on_ray, "commit_chunk",
                        lambda o, index, m: made.append(index) or commit(o, index, m))
    assert _gen(out, "--engine", "ray", "--resume") == 0
    assert sorted(made) == sorted(set(range(N_CHUNKS)) - before)
    _assert_same_dataset(local_reference, out)
    assert not (out / ".partial").exists()
    assert json.loads((out / "manifest.json").read_text())["resumed"]


def test_engine_options_are_checked_before_the_output_is_touched(tmp_path, capsys):
    out = tmp_path / "d"
    assert _gen(out, "--ray-address", "127.0.0.1:6379") == 2
    assert "--ray-address: needs --engine ray" in capsys.readouterr().err
    assert _gen(out, "--ray-writes", "workers") == 2
    assert "--ray-writes: needs --engine ray" in capsys.readouterr().err
    assert _gen(out, "--engine", "ray", "--max-concurrent", "0") == 2
    assert "--max-concurrent: must be >= 1" in capsys.readouterr().err
    assert _gen(out, "--engine", "ray", "--ray-address", "127.0.0.1:1") == 2
    assert "no Ray cluster answers there" in capsys.readouterr().err
    assert not out.exists()
