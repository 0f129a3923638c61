"""Shared pieces of the study-twin benchmarks (`study_curve.py`, `study_gap.py`,
`study_calibrate.py`), beside those of `study_replay.py` and `learnbench.py`: the twin's dataset
options and variant scene files."""

from __future__ import annotations

import argparse
import copy
import json
import time
from pathlib import Path

from study_replay import RESULTS, SCENE, add_grasp_options

from vistac_sim.effects.presets import load_scene

REPO = Path(__file__).resolve().parent.parent
V3 = "schoeconv100-v3-fc160"


def twin_parser(doc: str, name: str, dataset: tuple | None = None,
                grasp: bool = True) -> argparse.ArgumentParser:
    """A script's parser (its description the first paragraph of `doc`) with ``--work``
    (default ``runs/<name>``), ``--results``, ``--name``, ``--scene`` and, with `dataset` =
    (n, n_objects, split fractions), the options of the twin's dataset that
    `study_replay.dataset` reads: ``--n``, ``--n-objects``, ``--split``, ``--data-seed``,
    with `grasp`, ``--approach-spread``, ``--closing-spread``."""
    p = argparse.ArgumentParser(description=doc.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    options = [("--work", str(REPO / "runs" / name), str, None,
                "folder of the datasets and runs, kept for resuming"),
               ("--results", str(RESULTS), str, None, "where <name>.json|md|png go"),
               ("--name", name, str, None, "results file name"),
               ("--scene", str(SCENE), str, None, "the twin's scene file")]
    if dataset is not None:
        n, n_objects, split = dataset
        options += [("--n", n, int, None, "configurations generated"),
                    ("--n-objects", n_objects, int, None, "procedural objects"),
                    ("--split", list(split), float, 3, "train / val / test object fractions"),
                    ("--data-seed", 0, int, None, "the dataset's seed")]
    for flag, default, kind, nargs, text in options:
        p.add_argument(flag, default=default, type=kind, nargs=nargs, help=text)
    if dataset is not None and grasp:
        add_grasp_options(p)
    return p


def scene_file(base: Path, name: str, changes: dict, work: Path) -> Path:
    """``<work>/scenes/<name>.yaml``: the twin's scene file with `changes` over its effects
    (an effect's table replaces the twin's; JSON is YAML). Rewritten only when it changes."""
    data = load_scene(base)
    data.setdefault("effects", {}).update(copy.deepcopy(changes))
    path = work / "scenes" / f"{name}.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    text = f"# {base.name} with {json.dumps(changes)}\n" + json.dumps(data, indent=2) + "\n"
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path


def record(done: dict, key, entry: dict, seed: int, t0: float, write) -> None:
    """Keep a finished run's `entry` (with its `seed`) under `key`, print its wall time since
    `t0` and rewrite the results (`write`)."""
    entry["seed"] = seed
    done.setdefault(key, []).append(entry)
    print(f"== {entry['label']}: {time.perf_counter() - t0:.0f} s", flush=True)
    write()
