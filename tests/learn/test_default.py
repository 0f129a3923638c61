"""The default learning recipe on real generated data: it fits, it generalises, it is safe.

- The standard sanity check: a model trained on a few dozen samples drives its training loss
  close to zero (the default model on ~64; a study net, under the study's own protocol, on 18:
  it failed with PyTorch's default initialisation, see `models.study.init_signal_preserving`).
- End to end: a few hundred generated configurations, default settings: the model beats a mean
  predictor on held-out configurations (an assertion on accuracy, not on time).
- `--init` loads weights; a diverging run stops with a message; a run killed before its first
  checkpoint restarts; a run is never resumed or scored on another dataset by accident.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from vistac.cli import main
from vistac.dataset import open_tables
from vistac.errors import UserError
from vistac_learn.data.fingertip_table import fingertip_table
from vistac_learn.evaluate.config import EvaluateCfg
from vistac_learn.evaluate.run import evaluate_run
from vistac_learn.metrics import cone_metrics
from vistac_learn.models.tipnet import apply_model
from vistac_learn.train.build import build_model, build_samples, input_size, subset_rows
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.loop import masked_mse, train_run_folder


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """320 configurations of `vistac generate` (about 10 s), by-object split."""
    out = tmp_path_factory.mktemp("default") / "ds"
    assert main(["generate", "--n", "320", "--noise", "0.05", "--seed", "11", "--workers", "2",
                 "--no-progress", "--split-by", "object", "--out", str(out)]) == 0
    return out


def _train_loss(run, split: str = "train") -> float:
    """MSE of the run's last weights on a split, without augmentation."""
    cfg = protocol_cfg("default", "", "")
    meta = json.loads((run / "config.json").read_text())
    cfg = type(cfg)(**meta["train"])
    t = open_tables(cfg.data)
    model = build_model(cfg)
    model.load_state_dict(torch.load(run / "checkpoints" / "last.pt", weights_only=True)["model"])
    model.eval()
    tips = fingertip_table(t, cache_dir=cfg.cache_dir)
    ds = build_samples(cfg, t, split, input_size(cfg, model), tips)
    rows = t.rows(split)
    if split == cfg.train_split:  # only the rows it trained on (its `train_fraction`)
        rows = np.searchsorted(rows, subset_rows(rows, cfg.train_fraction, cfg.seed))
    else:
        rows = np.arange(len(rows))
    b = ds.batch(rows)
    with torch.no_grad():
        return float(masked_mse(apply_model(model, b, "cpu"), b["target"], b["found"]))


def _mean_predictor_loss(data, fingers=("index", "thumb"), split="train",
                         fraction: float = 1.0, seed: int = 0) -> float:
    t = open_tables(data)
    rows = subset_rows(t.rows(split), fraction, seed)
    y = np.concatenate([t.mean_label(f)[rows] for f in fingers], axis=1)
    return float(((y - y.mean(0)) ** 2).mean())


@pytest.mark.parametrize("protocol,model,epochs,fraction",
                         [("default", "pinchnet", 12, 1.0),
                          ("study", "schoeconv100-v3-fc160", 30, 0.35)])
def test_sanity_a_model_fits_its_training_samples(generated, tmp_path, protocol, model, epochs,
                                                  fraction):
    """Training loss on the configurations it trained on (the ~64 of the validation split; the
    study net, 5x the cost of a sample, a seeded third of them) falls to a small fraction of
    what the best constant prediction leaves (the test fails if data, labels and model do not
    line up)."""
    kw = dict(model=model, epochs=epochs, train_split="val", val_split="test", mirror=False,
              jitter=0.0, appearance=0.0, select="loss", device="cpu", train_fraction=fraction,
              cache_dir=str(tmp_path / "cache"))
    kw |= dict(batch_size=8) if protocol == "default" else dict(rotations="none")
    cfg = protocol_cfg(protocol, str(generated), str(tmp_path / "run"), **kw)
    n = len(open_tables(generated).rows("val"))
    assert 50 <= n <= 90, n  # the ~64 samples of the standard check
    run = train_run_folder(cfg, progress=False)
    fingers = ("index", "thumb") if protocol == "default" else ("index",)
    ratio = _train_loss(run, "val") / _mean_predictor_loss(generated, fingers, "val", fraction,
                                                           cfg.seed)
    assert ratio < 0.05, ratio


# Appearance augmentation (on in the recipe) is left out of the longer trainings below: it
# triples the cost of a sample and is tested on its own (test_samples.py, test_perturb.py).
NO_APPEARANCE = dict(appearance=0.0)


def test_default_training_beats_a_mean_predictor(generated, tmp_path):
    run = train_run_folder(protocol_cfg("default", str(generated), str(tmp_path / "run"),
                                        epochs=15, batch_size=16, device="cpu", **NO_APPEARANCE),
                           progress=False)
    res = evaluate_run(EvaluateCfg(run=str(run), no_plots=True))
    t = open_tables(generated)
    for f in ("index", "thumb"):
        mean = t.mean_label(f)[t.rows("train")].mean(0)
        rows = t.rows("test")
        const = cone_metrics(np.tile(mean, (len(rows), 1)), np.arange(len(rows)),
                             [t.cones[f][r] for r in rows])
        learned = res["metrics"][f]["angle_to_mean_median_deg"]
        assert learned < 0.6 * const["angle_to_mean_median_deg"], (f, learned, const)
        assert res["metrics"][f]["correct_y_pct"] > const["correct_y_pct"]


def test_the_recipe_says_whether_evaluation_averages_the_mirrored_view(generated, tmp_path):
    """The default recipe is evaluated with its mirrored view averaged in (`TrainCfg.tta`);
    ``tta="off"`` (--tta off) turns it off, ``"on"`` on for a run whose recipe has it off, a
    run written before the setting existed is evaluated as it was (without); each choice has
    its own default folder, and a value other than the three is refused."""
    import vistac

    run = train_run_folder(protocol_cfg("default", str(generated), str(tmp_path / "run"), epochs=1,
                                        batch_size=16, device="cpu"), progress=False)
    on = evaluate_run(EvaluateCfg(run=str(run), no_plots=True, no_references=True))
    off = vistac.evaluate(run, tta="off", no_plots=True, no_references=True)
    assert on["tta"] and not off.result["tta"]
    assert on["metrics"]["index"] != off.result["metrics"]["index"]  # the mirror changes them
    forced = vistac.evaluate(run, tta="on", no_plots=True, no_references=True)
    assert forced.metrics == on["metrics"]
    assert (run / "eval" / "test" / "metrics.json").is_file()
    assert (off.path.name, forced.path.name) == ("test-no-tta", "test-tta")
    with pytest.raises(UserError, match="tta: expected one of 'recipe', 'on', 'off'"):
        vistac.evaluate(run, tta=True)
    meta = json.loads((run / "config.json").read_text())
    del meta["train"]["tta"], meta["train"]["appearance"]  # a run of an earlier version
    (run / "config.json").write_text(json.dumps(meta))
    assert not evaluate_run(EvaluateCfg(run=str(run), no_plots=True, no_references=True))["tta"]
    from vistac_learn.train.run_files import read_run_config, run_settings

    assert run_settings(run, read_run_config(run, ""), "").appearance == 0.0  # trained without


def test_init_loads_the_weights_it_names(generated, tmp_path):
    """A run started from another run's weights begins where that one ended: its first-epoch
    loss is far below the same run's from scratch."""
    kw = dict(epochs=1, lr=1e-4, schedule="constant", device="cpu")
    src = train_run_folder(protocol_cfg("default", str(generated), str(tmp_path / "src"), epochs=8,
                                        device="cpu", **NO_APPEARANCE), progress=False)
    tuned = train_run_folder(protocol_cfg("default", str(generated), str(tmp_path / "ft"),
                                          init=str(src), **kw), progress=False)
    scratch = train_run_folder(protocol_cfg("default", str(generated), str(tmp_path / "sc"), **kw),
                               progress=False)
    first = [json.loads(json.dumps(_first_row(r))) for r in (tuned, scratch)]
    assert first[0]["train_loss"] < 0.5 * first[1]["train_loss"]
    meta = json.loads((tuned / "config.json").read_text())
    assert meta["init"]["run"] == str(src.resolve()) and not meta["init"]["reinitialised"]
    frozen = train_run_folder(protocol_cfg("default", str(generated), str(tmp_path / "fz"),
                                           init=str(src), freeze="features", **kw),
                              progress=False)
    a = torch.load(src / "checkpoints" / "best.pt", weights_only=True)["model"]
    b = torch.load(frozen / "checkpoints" / "last.pt", weights_only=True)["model"]
    assert all(torch.equal(a[k], b[k]) for k in a if ".features." in f".{k}")
    assert not all(torch.equal(a[k], b[k]) for k in a if "head" in k)
    with pytest.raises(UserError, match="not a finished run"):
        train_run_folder(protocol_cfg("default", str(generated), str(tmp_path / "x"),
                                      init=str(tmp_path / "nowhere")), progress=False)


def _first_row(run):
    import csv

    with (run / "metrics.csv").open() as fh:
        return {k: float(v) for k, v in next(csv.DictReader(fh)).items()}


def test_a_diverging_run_stops_with_a_message(generated, tmp_path, capsys):
    argv = ["train", "--data", str(generated), "--out", str(tmp_path / "run"), "--lr", "1e6",
            "--optimizer", "adam", "--schedule", "constant", "--epochs", "2", "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "training loss is" in err and "lower --lr" in err and "Traceback" not in err
    assert main(argv[:5] + ["--epochs", "1", "--quiet"]) == 0  # a good rerun into the folder


def test_a_run_killed_before_its_first_checkpoint_restarts(generated, tmp_path):
    cfg = protocol_cfg("default", str(generated), str(tmp_path / "run"), epochs=1, device="cpu")

    def killer(epoch, batch):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train_run_folder(cfg, progress=False, on_batch=killer)
    assert not (tmp_path / "run" / "checkpoints" / "last.pt").exists()
    # no --resume needed, nothing lost
    assert train_run_folder(cfg, progress=False) == tmp_path / "run"
    assert not list((tmp_path / "run" / "checkpoints").glob(".*tmp"))


def test_a_run_is_tied_to_its_dataset(generated, tmp_path, capsys):
    from learn_fixtures import make_dataset

    run = train_run_folder(protocol_cfg("default", str(generated), str(tmp_path / "run"), epochs=1,
                                        device="cpu"), progress=False)
    other = make_dataset(tmp_path / "other", n=8, size=96)
    with pytest.raises(UserError, match="not the dataset this run started on"):
        train_run_folder(protocol_cfg("default", str(other), str(run), epochs=2, device="cpu"),
                         resume=True, progress=False)
    with pytest.raises(UserError, match="--cross-dataset"):
        evaluate_run(EvaluateCfg(run=str(run), data=str(other), no_plots=True))
    res = evaluate_run(EvaluateCfg(run=str(run), data=str(other), no_plots=True,
                                   cross_dataset=True))
    assert res["data"] == str(other.resolve())


@pytest.fixture(scope="module")
def pinch_run(generated, tmp_path_factory):
    """The default recipe (pinch view, contact targets), 6 epochs on the generated data."""
    out = tmp_path_factory.mktemp("pinch") / "run"
    return train_run_folder(protocol_cfg("default", str(generated), str(out), epochs=6,
                                         batch_size=16, device="cpu", **NO_APPEARANCE),
                            progress=False)


def _val_batch(cfg, data: str):
    t = open_tables(data)
    ds = build_samples(cfg, t, "val", 48, fingertip_table(t, cache_dir=cfg.cache_dir))
    b = ds.batch(np.arange(len(ds)))
    return t, b


def test_the_auxiliary_path_trains_and_beats_a_mean_predictor(generated, pinch_run):
    """Generated data carries contact targets; training brings the predicted contact geometry
    close to the simulator's (auxiliary loss far below the untrained model's) and the labels
    beat a constant prediction."""
    cfg = protocol_cfg("default", str(generated), str(pinch_run))
    t, b = _val_batch(cfg, str(generated))
    assert torch.isfinite(b["aux"]).all()
    fresh, trained = build_model(cfg), build_model(cfg)
    trained.load_state_dict(torch.load(pinch_run / "checkpoints" / "best.pt",
                                       weights_only=False)["model"])
    losses, angles = [], []
    with torch.no_grad():
        for m in (fresh.eval(), trained.eval()):
            pred, geo = m(b["image"], b["side"], aux=True)
            losses.append(float(m.aux_loss(geo, b["aux"])))
            cos = (pred.reshape(-1, 2, 2) * b["target"].reshape(-1, 2, 2)).sum(-1)
            angles.append(np.degrees(np.arccos(np.clip(cos.numpy(), -1, 1))).mean())
    assert losses[1] < 0.3 * losses[0], losses
    rows = t.rows("val")
    for i, f in enumerate(("index", "thumb")):
        mean = t.mean_label(f)[t.rows("train")].mean(0)
        mean /= np.linalg.norm(mean)
        const = np.degrees(np.arccos(np.clip(t.mean_label(f)[rows] @ mean, -1, 1))).mean()
        cos = (trained(b["image"], b["side"]).detach().reshape(-1, 2, 2)[:, i]
               * b["target"].reshape(-1, 2, 2)[:, i]).sum(-1).numpy()
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))).mean() < 0.3 * const, (f, angles)


def test_init_from_a_sim_run_onto_data_without_contacts(generated, pinch_run, tmp_path):
    """Fine-tuning on data whose configs carry only what `vistac ingest` writes (no contact
    points, normals or finger directions, no projection): every tensor is copied, the run
    trains on the force labels alone."""
    import shutil

    from vistac_learn.train.losses import batch_loss

    real = tmp_path / "real"
    shutil.copytree(generated, real, ignore=shutil.ignore_patterns("cache"))
    c = open_tables(real).configs
    drop = [k for k in c if k.startswith(("target_", "approach_", "normal_", "tip_", "push_"))]
    c = c.drop(columns=drop).assign(camera_x=np.nan, camera_y=np.nan, px_per_m=np.nan)
    c.to_parquet(real / "configs.parquet")
    cfg = protocol_cfg("default", str(real), str(tmp_path / "ft"), init=str(pinch_run),
                       epochs=1, device="cpu")
    run = train_run_folder(cfg, progress=False)
    meta = json.loads((run / "config.json").read_text())
    assert not meta["init"]["reinitialised"]
    row = _first_row(run)
    assert np.isfinite(row["train_loss"]) and np.isfinite(row["val_loss"])
    _, b = _val_batch(cfg, str(real))
    assert torch.isnan(b["aux"]).all()
    model = build_model(cfg).eval()
    with torch.no_grad():
        plain = masked_mse(apply_model(model, b, "cpu"), b["target"], b["found"])
        assert float(batch_loss(model, b, "cpu")) == pytest.approx(float(plain))
