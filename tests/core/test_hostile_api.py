"""Hostile calls of the Python API and values at the edge of the arithmetic (issue 31).

Each API row calls a `vistac` function with a wrong type, None or a config changed after it was
made, and asserts a `vistac.UserError` whose one-line message names the argument (or the
field), no other exception, and nothing written. Each CLI row gives a value beyond what keeps
the arithmetic finite and asserts exit status 2, one line naming the option, nothing written;
the good command into the same folder then works. Stored labels are checked before a dataset is
declared written or "checked", and `Run.open` checks what it reports.
"""

from __future__ import annotations

import dataclasses
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch
from bad_input_env import GEN_OK, TRAIN_OK

import vistac
from vistac.cli import main
from vistac.config import apply
from vistac.errors import UserError


def _tiny() -> vistac.GenerateCfg:
    return apply(vistac.GenerateCfg(n=2, repeats=1), {"objects": {"n_objects": 1},
                                                       "render": {"image_size": 32}})


def _changed(cfg, path: str, value):
    """`cfg` with one nested field set behind the frozen dataclass's back."""
    *parents, name = path.split(".")
    target = cfg
    for p in parents:
        target = getattr(target, p)
    object.__setattr__(target, name, value)
    return cfg


API_CASES: dict[str, tuple[Callable[[dict, Path], object], str]] = {
    "train-out-none": (lambda p, out: vistac.train(vistac.TrainCfg(epochs=1), data=p["data"],
                                                   out=None), "out: expected a path"),
    "train-data-number": (lambda p, out: vistac.train(vistac.TrainCfg(), data=3, out=out),
                          "data: expected a path (str or pathlib.Path), got 3"),
    "train-cfg-dict": (lambda p, out: vistac.train({"epochs": 1}, data=p["data"], out=out),
                       "cfg: expected a TrainCfg"),
    "train-epochs-set-to-nan": (lambda p, out: vistac.train(
        _changed(vistac.TrainCfg(), "epochs", float("nan")), data=p["data"], out=out),
        "epochs: expected an integer"),
    "generate-workers-text": (lambda p, out: vistac.generate(_tiny(), out, workers="2"),
                              "workers: expected an integer, got '2'"),
    "generate-workers-float": (lambda p, out: vistac.generate(_tiny(), out, workers=2.0),
                               "workers: expected an integer"),
    "generate-cfg-dict": (lambda p, out: vistac.generate({"n": 2}, out),
                          "cfg: expected a GenerateCfg"),
    "generate-out-none": (lambda p, out: vistac.generate(_tiny(), None), "out: expected a path"),
    "generate-noise-set-to-nan": (lambda p, out: vistac.generate(
        _changed(_tiny(), "effects.noise", float("nan")), out, workers=1),
        "effects.noise: must be a finite number"),
    "generate-friction-set-huge": (lambda p, out: vistac.generate(
        _changed(_tiny(), "physics.friction", 1e300), out, workers=1),
        "physics.friction: must be <= 10"),
    "generate-replaced-n-negative": (lambda p, out: vistac.generate(
        _changed(dataclasses.replace(_tiny()), "n", -1), out, workers=1), "n: must be >= 1"),
    "evaluate-a-number": (lambda p, out: vistac.evaluate(42), "target: expected a Run"),
    "evaluate-none": (lambda p, out: vistac.evaluate(None), "target: expected a Run"),
    "tune-trials-text": (lambda p, out: vistac.tune(vistac.TrainCfg(), p["data"], out,
                                                    trials="3"), "trials: expected an integer"),
    "tune-base-none": (lambda p, out: vistac.tune(None, p["data"], out), "base: expected a "
                       "TrainCfg"),
    "ingest-sources-dict": (lambda p, out: vistac.ingest({"images": p["img"]}, out),
                            "sources: expected an IngestSources"),
    "dataset-image-of-text-id": (lambda p, out: vistac.open_dataset(p["data"]).image("0"),
                                 "config_id: expected an integer"),
}


@pytest.mark.parametrize("case", API_CASES)
def test_hostile_api_call(case, env):
    call, needle = API_CASES[case]
    out = env["root"] / "api" / case
    with pytest.raises(UserError) as info:
        call(env["paths"], out)
    message = str(info.value)
    assert needle in message and "\n" not in message, message
    assert not out.exists()  # refused before anything was written


def test_numpy_scalars_are_numbers(env):
    """``n=np.int64(5)`` used to be "expected an integer"; NumPy numbers are plain numbers in
    the config (its JSON in the manifest stays valid)."""
    cfg = apply(vistac.GenerateCfg(n=np.int64(2), repeats=np.int32(1), seed=np.uint8(3)),
                {"objects": {"n_objects": np.int64(1)}, "render": {"image_size": 32},
                 "physics": {"friction": np.float32(0.5)}})
    assert (cfg.n, cfg.seed, cfg.physics.friction) == (2, 3, 0.5)
    assert type(cfg.n) is int and type(cfg.physics.friction) is float
    ds = vistac.open_dataset(env["paths"]["data"])
    assert ds.image(np.int64(ds.config_ids[0])).ndim == 3


# ------------------------------------------------------------------- values bounded (the CLI)
G = GEN_OK
CLI_CASES = {
    "noise-1e300": (G + " --noise 1e300", "--noise: must be <= 10"),
    "friction-1e300": (G + " --friction 1e300", "--friction: must be <= 10"),
    "footprint-1e-9": (G + " --footprint 1e-9 1e-9", "--footprint: must be >= 0.001"),
}


@pytest.mark.parametrize("case", CLI_CASES)
def test_values_beyond_finite_arithmetic_are_refused(case, env, capsys):
    argv, needle = CLI_CASES[case]
    out = env["root"] / "bounds" / case
    capsys.readouterr()
    assert main(argv.format(out=out).split()) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err and needle in err, err
    assert not out.exists()


# ------------------------------------------------------------------ labels checked when stored
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # the point
def test_labels_without_direction_are_never_declared_written(env, capsys):
    """The engine given a config changed behind its checks (noise 1e300: every force overflows
    to a label (0, 0)) stops before the manifest, naming the table and row; nothing says
    "wrote"."""
    from vistac_sim.generate.run import generate as run_generation

    out = env["root"] / "labels" / "overflow"
    cfg = _changed(_tiny(), "effects.noise", 1e300)
    with pytest.raises(UserError, match=r"presses.parquet: row 0: \(index\) label .* is not a "
                       r"unit vector \(length 0\)"):
        run_generation(cfg, out, workers=1)
    assert not (out / "manifest.json").exists()


def test_a_finished_dataset_with_zero_labels_is_not_checked(env, capsys):
    """`generate --resume` of a complete dataset used to call it "checked" whatever its labels;
    a label (0, 0) is now named, and the good rerun after deleting the folder works."""
    out = env["root"] / "labels" / "zeroed"
    shutil.copytree(env["paths"]["data2"], out)
    presses = pd.read_parquet(out / "presses.parquet")
    presses.loc[0, ["r_y_thumb", "r_z_thumb"]] = 0.0
    presses.to_parquet(out / "presses.parquet", index=False)
    argv = (G + " --resume").format(out=out).split()
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    assert "presses.parquet: row 0: (thumb) label (r_y, r_z) = (0, 0) is not a unit vector" in err
    shutil.rmtree(out)
    assert main(G.format(out=out).split()) == 0
    assert main(argv) == 0
    assert "nothing to do" in capsys.readouterr().out


# ------------------------------------------------------------------------------ Run.open
def _run_copy(env, name: str) -> Path:
    run = env["root"] / "runs" / name
    shutil.copytree(env["paths"]["run"], run)
    return run


def test_run_open_checks_what_it_reports(env):
    run = _run_copy(env, "nan-objective")
    good = vistac.outputs.Run.open(run)
    assert good.best_epoch == 1 and np.isfinite(good.objective)
    metrics = run / "metrics.csv"
    head, row = metrics.read_text().splitlines()[:2]
    cols = head.split(",")
    values = row.split(",")
    values[cols.index("val_index_angle_to_mean_median_deg")] = "nan"
    metrics.write_text(head + "\n" + ",".join(values) + "\n")
    with pytest.raises(UserError, match="metrics.csv: epoch 1: no finite validation objective"):
        vistac.outputs.Run.open(run)

    run = _run_copy(env, "best-epoch-99")
    best = run / "checkpoints" / "best.pt"
    torch.save(torch.load(best, weights_only=True) | {"epoch": 99}, best)
    with pytest.raises(UserError, match=r"metrics.csv: no row of epoch 99, the best "
                       r"checkpoint's \(it has 1 rows\)"):
        vistac.outputs.Run.open(run)
    torch.save(torch.load(best, weights_only=True) | {"epoch": 1.5}, best)
    with pytest.raises(UserError, match=r"best.pt: its epoch is 1.5, not a whole number"):
        vistac.outputs.Run.open(run)


# ------------------------------------------------------------- checkpoints that cannot score
def _nan_weights(ck: dict) -> dict:
    name = next(k for k, v in ck["model"].items() if v.is_floating_point())
    model = dict(ck["model"])
    model[name] = model[name].clone().fill_(float("nan"))
    return ck | {"model": model}


CHECKPOINT_CASES = {
    "evaluate-nan-weights": ("evaluate --run {run} --no-plots", _nan_weights,
                             "is not finite (NaN or infinite); train the run again"),
    "evaluate-epoch-not-a-number": ("evaluate --run {run} --no-plots",
                                    lambda ck: ck | {"epoch": "one"},
                                    "best.pt: its epoch is 'one', not a whole number"),
    "init-nan-weights": (TRAIN_OK.replace("{out}", "{run}-next") + " --init {run}",
                         _nan_weights, "--init {run}/checkpoints/best.pt: weight"),
}


@pytest.mark.parametrize("case", CHECKPOINT_CASES)
def test_a_best_checkpoint_that_cannot_score_is_refused(case, env, capsys):
    argv, change, needle = CHECKPOINT_CASES[case]
    run = _run_copy(env, case)
    best = run / "checkpoints" / "best.pt"
    original = best.read_bytes()
    torch.save(change(torch.load(best, weights_only=True)), best)
    paths = {**env["paths"], "run": str(run)}
    capsys.readouterr()
    assert main(argv.format(**paths).split()) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    assert needle.format(**paths) in err, err
    assert not (run / "eval" / "test").exists() and not Path(f"{run}-next").exists()
    best.write_bytes(original)  # the good checkpoint back: the same command works
    assert main(argv.format(**paths).split()) == 0
