"""`vistac generate`: the dataset contract, determinism across workers, kill -9 and resume."""

import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter

import cv2
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from vistac.cli import main
from vistac.dataset import FORMAT_VERSION, open_tables
from vistac.dataset.schema import (
    FAILED_OBJECTS_TYPE,
    REDRAWS_TYPE,
    failed_object_counts,
    redraw_counts,
)
from vistac.errors import UserError
from vistac_sim.generate.shards import SHARD

FINGERS = ("index", "thumb")
CONFIG_COLUMNS = (
    ["config_id", "object_id", "image", "split"]
    + [f"bbox_{f}_{c}" for f in FINGERS for c in "xywh"]
    + [f"force_clean_{f}_{c}" for f in FINGERS for c in "xyz"]
    + [f"normal_{f}_{c}" for f in FINGERS for c in "xyz"]
)
PRESS_COLUMNS = (["config_id", "repeat"] + [f"force_{f}_{c}" for f in FINGERS for c in "xyz"]
                 + ["r_y_index", "r_z_index", "r_y_thumb", "r_z_thumb"])


def _gen(out, *extra):
    return main(["generate", "--out", str(out), "--no-progress", *extra])


def test_redraw_columns_are_native_and_add_up(small_dataset):
    """The nested bookkeeping columns read back as counts that sum to the manifest's."""
    t = open_tables(small_dataset)
    schema = pq.read_schema(small_dataset / "configs.parquet")
    assert schema.field("redraw_reasons").type == REDRAWS_TYPE
    assert schema.field("failed_objects").type == FAILED_OBJECTS_TYPE
    counts = [redraw_counts(c) for c in t.configs["redraw_reasons"]]
    assert [sum(c.values()) for c in counts] == t.configs["redraws"].tolist()
    total = sum(counts, Counter())
    for cell in t.configs["failed_objects"]:
        for c in failed_object_counts(cell).values():
            total += c
    by_object = Counter()
    for o in t.manifest["per_object"]:
        if o["status"] == "used":
            by_object.update(o["rejections"])
    assert dict(by_object) == dict(total)
    assert t.manifest["redraws"]["total"] == t.configs["redraws"].sum()


def test_dataset_matches_contract(small_dataset):
    t = open_tables(small_dataset)
    manifest, configs, presses = t.manifest, t.configs, t.presses
    assert manifest["complete"] and manifest["format_version"] == FORMAT_VERSION
    assert manifest["config"]["effects"]["noise"] == 0.05 and manifest["seed"] == 1
    assert {"mujoco", "numpy", "vistac"} <= set(manifest["versions"])
    assert [e["name"] for e in manifest["effects"]] == ["force_noise"]
    assert manifest["counts"]["configs"] == 24 and manifest["counts"]["presses"] == 24 * 6
    assert set(CONFIG_COLUMNS) <= set(configs.columns)
    assert set(PRESS_COLUMNS) <= set(presses.columns)
    assert configs["config_id"].tolist() == list(range(24))
    assert set(configs["split"]) <= {"train", "val", "test"}
    assert not configs.select_dtypes("number").isna().any().any()
    assert not presses.isna().any().any()
    for f in FINGERS:
        r = presses[[f"r_y_{f}", f"r_z_{f}"]].to_numpy()
        np.testing.assert_allclose(np.linalg.norm(r, axis=1), 1.0, atol=1e-12)
        assert (r[:, 1] < 0).all()
        assert (configs[f"force_clean_{f}_z"] < 0).all()
        n = configs[[f"normal_{f}_{c}" for c in "xyz"]].to_numpy()
        np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-9)
    for name in configs["image"]:
        img = cv2.imread(str(small_dataset / "images" / name), cv2.IMREAD_UNCHANGED)
        assert img.shape == (227, 227, 3) and img.dtype == np.uint8
    # Noise: repeats of one configuration differ, but only by a few percent.
    spread = presses.groupby("config_id")["force_index_y"].std()
    assert (spread > 0).all()


def _children_cpu() -> float:
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def test_same_seed_same_bytes_whatever_the_workers(tmp_path):
    args = ["--n", "16", "--seed", "3", "--noise", "0.05", "--n-objects", "6", "--chunk-size", "4"]
    assert _gen(tmp_path / "w1", *args, "--workers", "1") == 0
    cpu_before = _children_cpu()
    assert _gen(tmp_path / "w2", *args, "--workers", "2") == 0
    # The run left no process behind (its fork server stopped and was waited for, so the
    # workers' CPU time counts among this process's children).
    from multiprocessing import active_children

    assert not active_children()
    assert _children_cpu() > cpu_before
    for name in ("presses.parquet", "configs.parquet"):
        assert (tmp_path / "w1" / name).read_bytes() == (tmp_path / "w2" / name).read_bytes()
    for img in sorted((tmp_path / "w1" / "images").iterdir()):
        assert img.read_bytes() == (tmp_path / "w2" / "images" / img.name).read_bytes()


@pytest.mark.parametrize("merge_rows, max_buckets", [(7, 256), (2, 4)])
def test_the_final_merge_holds_one_bucket_of_ids_at_a_time(tmp_path, small_dataset,
                                                           monkeypatch, merge_rows, max_buckets):
    """With buckets of 7 configuration ids (or of 2, but at most 4 buckets: 6 ids each), the 24
    configurations of `small_dataset` (made in chunks of 5 that interleave ids across objects)
    are merged into the same tables, sorted, one row group per bucket, and nothing of the merge
    is left behind."""
    import pyarrow.parquet as pq

    from vistac_sim.generate import shards

    monkeypatch.setattr(shards, "MERGE_ROWS", merge_rows)
    monkeypatch.setattr(shards, "MAX_BUCKETS", max_buckets)
    assert _gen(tmp_path / "d", "--n", "24", "--noise", "0.05", "--seed", "1", "--workers",
                "1", "--n-objects", "8", "--chunk-size", "5") == 0
    for name in ("configs.parquet", "presses.parquet"):
        merged = pq.ParquetFile(tmp_path / "d" / name)
        assert merged.metadata.num_row_groups == 4  # ids 0-6, 7-13, 14-20, 21-23 (or 6 each)
        pd.testing.assert_frame_equal(merged.read().to_pandas(),
                                      pd.read_parquet(small_dataset / name))
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == [
        "README.md", "configs.parquet", "images", "manifest.json", "presses.parquet"]
    made = json.loads((tmp_path / "d" / "manifest.json").read_text())
    reference = json.loads((small_dataset / "manifest.json").read_text())
    for key in ("counts", "redraws", "per_object"):
        assert made[key] == reference[key]


def test_the_driver_imports_no_simulator(tmp_path):
    """With worker processes, `vistac generate` itself only plans: MuJoCo, trimesh, SciPy and
    pandas (the final merge's) are imported by the workers' fork server, not by the `vistac`
    process."""
    code = ("import sys; from vistac.cli import main; "
            f"rc = main(['generate', '--out', {str(tmp_path / 'd')!r}, '--n', '4', '--workers', "
            "'2', '--image-size', '32', '--n-objects', '2', '--repeats', '1', '--chunk-size', "
            "'2', '--no-progress']); "
            "print(rc, sorted(m for m in ('mujoco', 'trimesh', 'scipy', 'pandas') "
            "if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip().splitlines()[-1] == "0 []", done.stdout + done.stderr


def test_kill_9_then_resume_equals_uninterrupted(tmp_path):
    args = ["--n", "40", "--seed", "5", "--noise", "0.05", "--n-objects", "4", "--chunk-size",
            "4", "--workers", "1"]
    assert _gen(tmp_path / "ref", *args) == 0
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "vistac.cli", "generate", "--out", str(out), "--no-progress",
           *args]
    proc = subprocess.Popen(cmd)
    shards = out / ".partial" / "shards"
    deadline = time.time() + 120
    while time.time() < deadline and len(list(shards.glob(f"*.configs{SHARD}"))) < 3:
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not (out / "manifest.json").exists()
    with pytest.raises(UserError, match="interrupted run"):
        open_tables(out)
    assert _gen(out, *args, "--resume") == 0
    for name in ("presses.parquet", "configs.parquet"):
        assert (out / name).read_bytes() == (tmp_path / "ref" / name).read_bytes()
    ref_images = sorted(p.name for p in (tmp_path / "ref" / "images").iterdir())
    assert sorted(p.name for p in (out / "images").iterdir()) == ref_images
    for name in ref_images:
        assert (out / "images" / name).read_bytes() == (tmp_path / "ref" / "images" / name
                                                        ).read_bytes()
    manifest = json.loads((out / "manifest.json").read_text())
    ref = json.loads((tmp_path / "ref" / "manifest.json").read_text())
    assert manifest["redraws"] == ref["redraws"] and manifest["counts"] == ref["counts"]
    assert not (out / ".partial").exists()


def test_refuses_to_overwrite_or_mix_settings(tmp_path, small_dataset, capsys):
    assert _gen(small_dataset, "--n", "2") == 2
    assert "complete dataset" in capsys.readouterr().err
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "file.txt").write_text("mine")
    assert _gen(tmp_path / "busy", "--n", "2") == 2
    assert (tmp_path / "busy" / "file.txt").read_text() == "mine"
    assert _gen(tmp_path / "none", "--n", "2", "--resume") == 2
    assert "nothing to resume" in capsys.readouterr().err


def test_resume_with_other_settings_is_refused(tmp_path, capsys):
    out = tmp_path / "d"
    (out / ".partial").mkdir(parents=True)
    (out / ".partial" / "run.json").write_text(json.dumps({"config": {"n": 1}, "objects": []}))
    (out / ".partial" / "shards").mkdir()
    from vistac_sim.generate.shards import shard_paths, write_shard

    for path in shard_paths(out, 0):  # one committed shard (a run without one restarts)
        write_shard(path, [{"config_id": 0}])
    assert _gen(out, "--n", "4", "--workers", "1", "--resume") == 2
    assert "other settings" in capsys.readouterr().err


def test_split_by_object_keeps_objects_whole(tmp_path):
    out = tmp_path / "d"
    assert _gen(out, "--n", "30", "--repeats", "1", "--n-objects", "10", "--split-by", "object",
                "--workers", "1") == 0
    configs = open_tables(out).configs
    per_object = configs.groupby("object_id")["split"].nunique()
    assert (per_object == 1).all()
    assert set(configs["split"]) == {"train", "val", "test"}


def test_frictionless_angles_are_small(tmp_path):
    out = tmp_path / "d"
    assert _gen(out, "--n", "24", "--repeats", "1", "--friction", "0", "--workers", "1") == 0
    configs = open_tables(out).configs
    for f in FINGERS:
        force = configs[[f"force_clean_{f}_{c}" for c in "xyz"]].to_numpy()
        normal = configs[[f"normal_{f}_{c}" for c in "xyz"]].to_numpy()
        cos = (force * normal).sum(1) / np.linalg.norm(force, axis=1)
        assert np.median(np.degrees(np.arccos(np.clip(cos, -1, 1)))) <= 0.5


def test_pixel_mapping_columns_agree_with_manifest(small_dataset):
    t = open_tables(small_dataset)
    manifest, configs = t.manifest, t.configs
    assert np.allclose(configs["px_per_m"], manifest["render"]["px_per_m"])
    assert pd.api.types.is_integer_dtype(configs["config_id"])


def test_tasks_hold_one_object_and_cover_every_chunk_once():
    from vistac_sim.generate.plan import plan_chunks, plan_tasks

    chunks = plan_chunks(3000, 0, 7, 50)
    for workers in (1, 2, 5):
        tasks = plan_tasks(chunks, workers)
        assert [c for t in tasks for c in t] == chunks  # in order, each chunk once
        assert all(len({c.object_index for c in t}) == 1 for t in tasks)
        limit = -(-3000 // (workers * 8))
        assert all(sum(len(c.config_ids) for c in t[:-1]) < limit for t in tasks)
    assert len(plan_tasks(chunks, 2)) < len(chunks)  # chunks of an object go together


def test_a_merge_worker_that_dies_is_an_error_not_a_hang():
    """The final merge runs in a worker of its own: if it is killed (out of memory), the run
    fails with a message instead of waiting forever."""
    from vistac.engine import ForkServer, WorkerDied

    with ForkServer() as server, pytest.raises(WorkerDied, match="_exit: its worker process died"):
        server.call(os._exit, 3)
