"""vistac_learn.train.label_lean: a run whose training labels lean to one side says that its
mirroring would hide it, and records the lean in config.json."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from learn_fixtures import make_dataset

from vistac.dataset.schema import force_columns, label_columns
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.label_lean import label_lean, lean_note, leaning
from vistac_learn.train.loop import train_run_folder


def _labels(lean_deg: float, n: int, rng) -> np.ndarray:
    """Unit (r_y, r_z) labels spread 10 degrees around (0, -1) turned by `lean_deg`."""
    a = np.radians(lean_deg + 10.0 * rng.standard_normal(n))
    return np.stack([np.sin(a), -np.cos(a)], axis=1)


def test_a_lean_is_found_only_when_large_and_certain():
    rng = np.random.default_rng(0)
    lean = label_lean({"index": _labels(8.0, 500, rng), "thumb": _labels(0.0, 500, rng)})
    assert lean["index"]["mean_r_y"] == pytest.approx(np.sin(np.radians(8.0)), abs=0.02)
    assert lean["index"]["n"] == 500 and lean["index"]["stderr"] < 0.01
    assert leaning(lean) == ["index"]
    # a certain lean of 1 degree is not large; a large lean of two labels not certain
    assert leaning(label_lean({"index": _labels(1.0, 100_000, rng)})) == []
    few = label_lean({"index": np.array([[0.2, -0.98], [-0.1, -0.99]])})
    assert leaning(few) == []


def test_the_note_names_the_options_that_hide_the_lean():
    rng = np.random.default_rng(1)
    lean = label_lean({"index": _labels(8.0, 400, rng)})
    line = lean_note(lean, mirror=True, tta=True)
    assert "index mean r_y +0.1" in line and "--mirror and --tta" in line
    assert "--no-mirror --no-tta" in line
    assert "--tta flip" in lean_note(lean, mirror=False, tta=True)
    assert lean_note(lean, mirror=False, tta=False) is None
    assert lean_note(label_lean({"index": _labels(0.0, 400, rng)}), True, True) is None


def test_non_finite_labels_are_left_out():
    lean = label_lean({"index": np.array([[np.nan, np.nan], [0.1, -0.99], [0.3, -0.95]])})
    assert lean["index"]["n"] == 2
    assert lean["index"]["mean_r_y"] == pytest.approx(0.2)


def _leaning_dataset(path, pull: float):
    """A small dataset whose measured forces get a sideways pull of `pull` x |F_z| (sensor y),
    as the simulator's `finger_pull` adds it."""
    ds = make_dataset(path, n=40, repeats=3, size=64, splits=(0.5, 0.25, 0.25))
    presses = pd.read_parquet(ds / "presses.parquet")
    for f in ("index", "thumb"):
        _, y, z = force_columns(f)
        presses[y] = presses[y] + pull * presses[z].abs()
        norm = np.hypot(presses[y], presses[z])
        ry, rz = label_columns(f)
        presses[ry], presses[rz] = presses[y] / norm, presses[z] / norm
    presses.to_parquet(ds / "presses.parquet")
    return ds


def test_a_run_records_the_lean_and_says_when_mirroring_hides_it(tmp_path, capsys):
    ds = _leaning_dataset(tmp_path / "ds", pull=1.0)
    base = dict(model="smallconv", epochs=1, n_rotations=1, batch_size=4, device="cpu",
                cache_dir=str(tmp_path / "cache"))
    run = train_run_folder(protocol_cfg("study", str(ds), str(tmp_path / "mirrored"),
                                        mirror=True, **base), progress=True)
    meta = json.loads((run / "config.json").read_text())
    assert meta["label_lean"]["index"]["n"] == meta["dataset"]["n_train_configs"]
    assert meta["label_lean"]["index"]["mean_r_y"] > 0.4
    assert "the training labels lean to one side (index mean r_y +" in capsys.readouterr().err
    run = train_run_folder(protocol_cfg("study", str(ds), str(tmp_path / "plain"),
                                        mirror=False, tta=False, **base), progress=True)
    assert "lean to one side" not in capsys.readouterr().err
