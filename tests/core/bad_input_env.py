"""Shared data of the bad-input and interrupted-run tests (tests/core): the good command of each
sub-command and one tiny generated dataset with recordings, a second dataset and a one-epoch run.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass

import cv2
import pytest
import torch

from vistac.cli import main

GEN_OK = ("generate --out {out} --n 2 --image-size 32 --n-objects 1 --repeats 1 --workers 1 "
          "--no-progress")
ING_OK = "ingest --recordings {rec} --images {img} --out {out}"
TRAIN_OK = "train --data {data} --out {out} --epochs 1 --size 16 --quiet"
EVAL_OK = "evaluate --run {run} --no-plots --out {out}"


@dataclass
class Case:
    """One bad or hostile command of the tables in tests/core: its arguments, the text its one
    error line must contain, the exit status, what prepares its input and the good rerun."""

    id: str
    argv: str
    needle: str
    code: int = 2
    setup: str | None = None  # name of a function preparing {out} (or other state) first
    good: str | None = None  # the good rerun into {out} (default: the command's good one)
    untouched: bool = False  # {out} is somebody else's folder: left as it was, no rerun
    delete: bool = False  # the message says to delete the folder: the rerun does so first
    check: str | None = None  # a function checking {out} after a successful (code 0) case


@pytest.fixture(scope="session")
def env(tmp_path_factory):
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # tiny models: threads only add overhead
    root = tmp_path_factory.mktemp("bad_input")
    data, data2, run = root / "data", root / "data2", root / "run"
    assert main(["generate", "--out", str(data), "--n", "8", "--image-size", "64",
                 "--n-objects", "2", "--chunk-size", "8", "--repeats", "2", "--workers", "1",
                 "--no-progress", "--recordings"]) == 0
    assert main(GEN_OK.format(out=data2).split()) == 0
    assert main(TRAIN_OK.format(data=data, out=run).split()) == 0
    mixed = root / "mixed"
    shutil.copytree(data / "images", mixed)
    cv2.imwrite(str(mixed / "000001.png"), cv2.resize(cv2.imread(str(mixed / "000001.png")),
                                                      (48, 48)))
    partial = root / "partial"  # an interrupted dataset
    (partial / ".partial").mkdir(parents=True)
    (partial / ".partial" / "run.json").write_text("{}")
    (root / "file.txt").write_text("not a folder")
    scenes = {"scene_hold": "recording: {hold_s: -1}\n",
              "scene_rate": "recording: {rate_hz: 0}\n",
              "scene_nan": "effects: {fts3: {hysteresis: .nan}}\n",
              "scene_shadow": "effects: {shadows: {map_size: 0}}\n",
              "scene_jitter": "recording: {timing_jitter: 1.5}\n",
              "scene_unknown": "optics: {focus: 0.5}\n"}
    for name, text in scenes.items():
        (root / f"{name}.yaml").write_text(text)
    paths = {"data": data, "data2": data2, "run": run, "rec": data / "recordings",
             "img": data / "images", "mixed": mixed, "partial": partial,
             "file": root / "file.txt", "missing": root / "missing",
             **{name: root / f"{name}.yaml" for name in scenes}}
    torch.set_num_threads(threads)  # the tests that use it ask for one thread themselves
    yield {"root": root, "paths": {k: str(v) for k, v in paths.items()}, "reruns": {}}
