"""The training loop: one function, `train(cfg)`, shared by `vistac train`, tuning and experiments.

After each epoch the model is scored on the validation split (never on the test split) and the
best epoch by the selection metric is kept as `best.pt`.

Run folder (``--out``):

- ``config.json``: the full `TrainCfg`, the model's size, the dataset's absolute path and
  fingerprint, where `--init` weights came from, versions, the fingertips not found per split.
- ``metrics.csv``: append-only, one row per finished epoch (train loss, validation loss and
  the validation metrics of each finger, seconds); a resume makes it match the checkpoint's
  history again (a row a kill kept from being appended, a cut or edited table).
- ``checkpoints/last.pt``: model, optimizer, schedule, torch RNG state, position (epoch, batch),
  history; written atomically at the end of every epoch and every ``checkpoint_every`` batches.
- ``checkpoints/best.pt``: the model weights of the best validation epoch.

Repeatability: weights are initialised after ``torch.manual_seed(seed)``; the order of the
training samples in epoch e is a permutation drawn from ``numpy.random.default_rng([seed, e])``
and every sample's augmentation from (seed, e, sample), independent of what ran before; the torch
RNG state travels in the checkpoint. A run killed at any point and continued with ``--resume``
therefore replays exactly the batches the uninterrupted run would have seen; on CPU its metrics
are bit-identical. A run killed before its first checkpoint is simply started again.

Before any work: the memory a batch needs is estimated (`vistac_learn.train.memory`) and
the fingertips not found counted per split (`vistac_learn.data.tip_coverage`); either over
its bound refuses the run. A loss that is not finite or above `DIVERGED_LOSS` stops the run
(`TrainingDiverged`) and marks it; a plain rerun into a diverged run, or into one whose
``config.json`` or checkpoints are damaged (`damage`), starts it over, while ``--resume`` of a
damaged run says which file and that a plain rerun starts over.
"""

from __future__ import annotations

import csv
import io
import json
import math
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from vistac.dataset import open_dataset
from vistac.dataset.files import atomic_write_bytes, atomic_write_json, remove_stale_temporaries
from vistac.errors import UserError
from vistac.folder_lock import hold
from vistac_learn.data.fingertips import fingertip_table
from vistac_learn.data.samples import fingers_of
from vistac_learn.metrics.scoring import predict, score_predictions
from vistac_learn.train.checkpoints import (
    atomic_save,
    init_from_run,
    load_checkpoint,
    load_weights,
    trainable_parameters,
)
from vistac_learn.train.config import (
    TrainCfg,
    build_model,
    build_samples,
    build_view,
    input_size,
    resolve_device,
    run_coverage,
)
from vistac_learn.train.losses import batch_loss, masked_mse  # noqa: F401  (masked_mse: API)
from vistac_learn.train.memory import check_fits
from vistac_learn.train.run_files import read_run_config, run_settings

HIGHER_IS_BETTER = frozenset({"correct_y_pct", "in_cone_pct", "n_in_cone"})
RUN_FILES = frozenset({"config.json", "metrics.csv", "checkpoints", "eval"})


LAST_KEYS = ("model", "optimizer", "schedule", "torch_rng", "epoch", "batch", "run_sum",
             "run_n", "history", "best_value", "best_epoch")
BEST_KEYS = ("model", "epoch")
RESTART = "rerun without --resume to start the run over"
DIVERGED_LOSS = 100.0
"""A loss above this is divergence. Targets are unit vectors: a model that predicts the
opposite direction everywhere has an MSE of 2, one predicting zero of 0.5; a loss of 100 needs
predictions about ten times longer than any label, which no converging run makes."""


def diverged(loss: float) -> bool:
    """Whether a loss is not finite or above `DIVERGED_LOSS`."""
    return not math.isfinite(loss) or loss > DIVERGED_LOSS


class TrainingDiverged(UserError):
    """A loss that is not finite or above `DIVERGED_LOSS`: the run stops, naming the epoch."""

    def __init__(self, epoch: int, what: str, value: float, lr: float):
        super().__init__(f"epoch {epoch}: the {what} is {value}; training diverged; restart "
                         f"with a lower --lr (now {lr:g}), e.g. --lr {lr / 10:g}")
        self.epoch = epoch


def _selection_value(row: dict, select: str, fingers: tuple[str, ...]) -> tuple[float, bool]:
    """(value, higher_is_better) of the selection quantity in an epoch's metrics row."""
    if select == "loss":
        return row["val_loss"], False
    keys = [f"val_{f}_{select}" for f in fingers]
    if not all(k in row for k in keys):
        names = sorted({k.split("_", 2)[2] for k in row if k.startswith(f"val_{fingers[0]}_")})
        raise UserError(f"--select {select!r}: not a metric; choose loss or one of {names}")
    return float(np.mean([row[k] for k in keys])), select in HIGHER_IS_BETTER


def _append_rows(path: Path, rows: list[dict]) -> None:
    """Append rows to the metrics CSV (header written when the file is new)."""
    new = not path.exists() or path.stat().st_size == 0
    with path.open("a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0].keys()))
        if new:
            w.writeheader()
        w.writerows(rows)


def _restore_metrics(path: Path, history: list[dict]) -> None:
    """Make the metrics CSV hold exactly the checkpoint's `history`: rows a kill kept from
    being appended are added, a cut or edited table is written again."""
    buf = io.StringIO(newline="")
    if history:
        w = csv.DictWriter(buf, fieldnames=list(history[0].keys()))
        w.writeheader()
        w.writerows(history)
    want = buf.getvalue().encode()
    if not path.exists() or path.read_bytes() != want:
        atomic_write_bytes(path, want)


def evaluate_loss(model, ds, device, batch_size: int) -> tuple[float, np.ndarray]:
    """(MSE against the mean unit labels, predictions (M, 2F)) over every sample."""
    pred = predict(model, ds, device, batch_size)
    found = np.repeat(ds.found(np.arange(len(ds))), 2, axis=1)
    err = (pred - ds.targets(np.arange(len(ds)))) ** 2
    return float((err * found).sum() / max(found.sum(), 1)), pred


def _check_resume(cfg: TrainCfg, out: Path, fingerprint: str) -> None:
    saved = read_run_config(out, RESTART)
    mine = asdict(cfg)
    diff = [k for k in mine if k not in ("epochs", "out", "data", "cache_dir", "max_missing_pct")
            and saved["train"].get(k) != mine[k]]
    if diff:
        raise UserError(f"{out / 'config.json'}: --resume with different settings "
                        f"({', '.join(diff)})")
    if saved["dataset"]["fingerprint"] != fingerprint:
        raise UserError(f"--data {cfg.data}: not the dataset this run started on (its "
                        f"fingerprint differs from {saved['dataset']['path']}'s)")
    planned = saved["train"].get("epochs")
    if cfg.schedule == "onecycle" and planned != cfg.epochs:
        raise UserError(f"--epochs {cfg.epochs}: the run's one-cycle schedule was planned for "
                        f"{planned} epochs; resume with --epochs {planned}")


def _optimizer(cfg: TrainCfg, model: torch.nn.Module, steps: int):
    params = trainable_parameters(model)
    kind = torch.optim.AdamW if cfg.optimizer == "adamw" else torch.optim.Adam
    opt = kind(params, lr=cfg.lr, weight_decay=cfg.weight_decay)
    if cfg.schedule == "onecycle" and steps >= 3:
        # torch needs a warm-up of more than one step (it divides by its length): a quarter of
        # the steps, at least 1.5 (unchanged from 6 steps on); below 3 steps, a constant lr
        sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, total_steps=steps,
                                                    pct_start=max(0.25, 1.5 / steps))
    else:
        sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda _: 1.0)
    return opt, sched


def train(cfg: TrainCfg, resume: bool = False, progress: bool = True,
          on_batch: Callable[[int, int], None] | None = None) -> Path:
    """Train (or continue) a run; return the run folder.

    Args:
        cfg: The run's settings.
        resume: Continue the run in ``cfg.out`` from ``checkpoints/last.pt``.
        progress: Show tqdm progress bars.
        on_batch: Called as ``on_batch(epoch, batch)`` after every optimiser step (tests use
            it to interrupt a run).

    Returns:
        The run folder.

    Raises:
        UserError: Bad settings or data, an existing run folder without ``resume``, a resume
            with other settings or another dataset, a training loss that is not finite, a run
            folder that another process holds.
    """
    with hold(cfg.out, "train"):
        return _train(cfg, resume, progress, on_batch)


def _train(cfg: TrainCfg, resume: bool, progress: bool,
           on_batch: Callable[[int, int], None] | None) -> Path:
    out = Path(cfg.out)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out}: exists and is not a folder")
    if out.is_dir() and not (out / "config.json").exists() \
            and any(p.name not in RUN_FILES for p in out.iterdir()):
        raise UserError(f"--out {out}: a folder that is not a run and not empty; choose another")
    ckpt_dir = out / "checkpoints"
    last_path, best_path = ckpt_dir / "last.pt", ckpt_dir / "best.pt"
    metrics_path = out / "metrics.csv"
    started = last_path.exists()
    if resume and not started and not (out / "config.json").exists():
        raise UserError(f"{out}: no run to resume (no config.json); drop --resume to start one")
    if not resume and started and (_diverged(out) or damage(out)):
        # a rerun (with a lower lr, or over damaged files) starts over
        for p in (last_path, best_path, metrics_path):
            p.unlink(missing_ok=True)
        started = False
    if not resume and started:
        raise UserError(f"{out}: already holds a run; pass --resume or choose another --out")

    device = resolve_device(cfg.device)
    if device.type == "cuda":  # CPU kernels are deterministic already
        torch.backends.cudnn.deterministic = True
        torch.backends.cudnn.benchmark = False
    tables = open_dataset(cfg.data)
    fingerprint = tables.fingerprint()
    if started:
        _check_resume(cfg, out, fingerprint)
        ck = load_checkpoint(last_path, LAST_KEYS, RESTART, map_location=device)
        if best_path.exists():
            load_checkpoint(best_path, BEST_KEYS, RESTART)
    fingers = fingers_of(cfg.finger)
    model = build_model(cfg)
    init_note = init_from_run(model, cfg) if cfg.init and not started else None
    size = input_size(cfg, model)
    view = build_view(cfg)
    check_fits(model, view.channels, size, cfg.batch_size, cfg.eval_batch_size, device)
    tips = fingertip_table(tables, cache_dir=cfg.cache_dir, progress=progress) \
        if view.needs_tips else None
    coverage = run_coverage(cfg, tables, tips)  # refuses too many fingertips not found
    train_ds = build_samples(cfg, tables, cfg.train_split, size, tips, train=True)
    val_ds = build_samples(cfg, tables, cfg.val_split, size, tips)
    model.to(device)
    n_batches = math.ceil(len(train_ds) / cfg.batch_size)
    opt, sched = _optimizer(cfg, model, n_batches * cfg.epochs)

    start_epoch, start_batch, history = 0, 0, []
    run_sum, run_n = 0.0, 0
    best_value, best_epoch = None, None
    if started:
        remove_stale_temporaries(ckpt_dir)
        try:
            load_weights(model, ck["model"], last_path, RESTART)
            opt.load_state_dict(ck["optimizer"])
            sched.load_state_dict(ck["schedule"])
            torch.set_rng_state(ck["torch_rng"])
        except (ValueError, TypeError, KeyError, RuntimeError) as exc:
            raise UserError(f"{last_path}: damaged state ({exc}); {RESTART}") from None
        if device.type == "cuda" and ck.get("cuda_rng") is not None:
            torch.cuda.set_rng_state_all(ck["cuda_rng"])
        start_epoch, start_batch = ck["epoch"], ck["batch"]
        run_sum, run_n = ck["run_sum"], ck["run_n"]
        history, best_value, best_epoch = ck["history"], ck["best_value"], ck["best_epoch"]
        _restore_metrics(metrics_path, history)  # a kill before an append, a damaged table
    else:  # a new run, or one killed before its first checkpoint: start (again) from scratch
        ckpt_dir.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(ckpt_dir)
        metrics_path.unlink(missing_ok=True)
        atomic_write_json(out / "config.json", _run_meta(cfg, model, tables, fingerprint,
                                                         train_ds, val_ds, device, init_note)
                          | {"fingertips": {c.split: c.as_dict() for c in coverage}})
        if init_note and progress:
            tqdm.write(f"init: {init_note['summary']}", file=sys.stderr)

    def save_last(epoch: int, batch: int) -> None:
        atomic_save({
            "model": model.state_dict(), "optimizer": opt.state_dict(),
            "schedule": sched.state_dict(), "torch_rng": torch.get_rng_state(),
            "cuda_rng": torch.cuda.get_rng_state_all() if device.type == "cuda" else None,
            "epoch": epoch, "batch": batch, "run_sum": run_sum, "run_n": run_n,
            "history": history, "best_value": best_value, "best_epoch": best_epoch,
            "cfg": asdict(cfg),
        }, last_path)

    try:
        for epoch in range(start_epoch, cfg.epochs):
            t0 = time.perf_counter()
            perm = np.random.default_rng([cfg.seed, epoch]).permutation(len(train_ds))
            _train_mode(model, cfg.freeze)
            first = start_batch if epoch == start_epoch else 0
            if first == 0:
                run_sum, run_n = 0.0, 0
            bar = tqdm(total=n_batches, initial=first, desc=f"epoch {epoch + 1}/{cfg.epochs}",
                       disable=not progress, leave=False, unit="batch")
            for b, batch in train_ds.batches(perm, cfg.batch_size, epoch, first):
                y = batch["target"].to(device)
                opt.zero_grad(set_to_none=True)
                loss = batch_loss(model, batch, device, cfg.aux_weight)
                if diverged(float(loss.detach())):
                    raise TrainingDiverged(epoch + 1, "training loss",
                                           float(loss.detach()), cfg.lr)
                loss.backward()
                opt.step()
                sched.step()
                run_sum += float(loss.detach()) * len(y)
                run_n += len(y)
                bar.update(1)
                bar.set_postfix(loss=f"{run_sum / run_n:.4g}")
                if cfg.checkpoint_every and (b + 1) % cfg.checkpoint_every == 0 \
                        and b + 1 < n_batches:
                    save_last(epoch, b + 1)
                if on_batch is not None:
                    on_batch(epoch, b)
            bar.close()
            train_time = time.perf_counter() - t0
            val_loss, pred = evaluate_loss(model, val_ds, device, cfg.eval_batch_size)
            if not np.isfinite(pred).all() or diverged(val_loss):
                raise TrainingDiverged(epoch + 1, "validation loss", val_loss, cfg.lr)
            row = {"epoch": epoch + 1, "train_loss": run_sum / max(run_n, 1),
                   "val_loss": val_loss, "lr": float(opt.param_groups[0]["lr"])}
            for f, m in score_predictions(pred, val_ds).items():
                row |= {f"val_{f}_{k}": v for k, v in m.items()}
            row |= {"train_s": train_time, "epoch_s": time.perf_counter() - t0}
            value, higher = _selection_value(row, cfg.select, fingers)
            improved = best_value is None or (value > best_value if higher else value < best_value)
            if improved:
                best_value, best_epoch = value, epoch + 1
                atomic_save({"model": model.state_dict(), "epoch": epoch + 1,
                             "select": cfg.select, "value": value, "cfg": asdict(cfg)},
                            best_path)
            history.append(row)
            run_sum, run_n = 0.0, 0
            save_last(epoch + 1, 0)
            _append_rows(metrics_path, [row])
            if progress:
                tqdm.write(
                    f"epoch {epoch + 1}/{cfg.epochs}: train loss {row['train_loss']:.4g}, "
                    f"val loss {val_loss:.4g}, {cfg.select} {value:.4g}"
                    + (" (best)" if improved else "") + f", {row['epoch_s']:.1f} s",
                    file=sys.stderr)
    except TrainingDiverged as exc:  # mark the run, so that a rerun into --out starts over
        meta = json.loads((out / "config.json").read_text())
        atomic_write_json(out / "config.json", meta | {"diverged": {"epoch": exc.epoch,
                                                                     "message": str(exc)}})
        raise
    finally:
        train_ds.close()
        val_ds.close()
    return out


def _diverged(out: Path) -> bool:
    """Whether the run in `out` stopped on a diverging loss."""
    try:
        return bool(json.loads((out / "config.json").read_text()).get("diverged"))
    except (OSError, ValueError, AttributeError):
        return False


def damage(out: Path) -> str | None:
    """Why the started run in `out` cannot be continued (a damaged config.json or checkpoint),
    or None (no run, or an intact one)."""
    if not (out / "checkpoints" / "last.pt").exists():
        return None
    try:
        run_settings(out, read_run_config(out, RESTART), RESTART)
        load_checkpoint(out / "checkpoints" / "last.pt", LAST_KEYS, RESTART)
        if (out / "checkpoints" / "best.pt").exists():
            load_checkpoint(out / "checkpoints" / "best.pt", BEST_KEYS, RESTART)
    except UserError as exc:
        return str(exc)
    return None


def finished(out: Path, epochs: int) -> bool:
    """Whether the run in `out` has trained `epochs` epochs (its last checkpoint is at the end
    of the last one); False for no run or a damaged one."""
    try:
        ck = load_checkpoint(Path(out) / "checkpoints" / "last.pt", LAST_KEYS, RESTART)
    except UserError:
        return False
    return ck["epoch"] >= epochs and ck["batch"] == 0


def _train_mode(model: torch.nn.Module, freeze: str) -> None:
    """Training mode; frozen feature layers stay in evaluation mode (batch-norm statistics
    fixed)."""
    model.train()
    if freeze == "features":
        for name, module in model.named_modules():
            if name.endswith("features"):
                module.eval()


def _run_meta(cfg, model, tables, fingerprint, train_ds, val_ds, device, init_note) -> dict:
    from vistac_learn.models import count_macs

    size = input_size(cfg, model)
    per_sample = (*(() if not hasattr(model, "n_fingers") else (model.n_fingers,)),
                  build_view(cfg).channels, size, size)
    return {
        "train": asdict(cfg),
        "model": {"name": cfg.model, "input_size": size,
                  "params": sum(p.numel() for p in model.parameters()),
                  "trainable_params": sum(p.numel() for p in trainable_parameters(model)),
                  "macs_per_sample": _macs(model, per_sample, count_macs)},
        "dataset": {"path": str(Path(cfg.data).resolve()), "fingerprint": fingerprint,
                    "n_train_configs": len(train_ds.rows), "n_val_configs": len(val_ds.rows),
                    "n_train_samples": len(train_ds), "n_val_samples": len(val_ds)},
        "init": init_note,
        "device": str(device),
        "versions": {"torch": torch.__version__, "numpy": np.__version__,
                     "python": platform.python_version()},
    }


def _macs(model, shape, count_macs) -> int:
    """MACs of one sample (every finger's crop for per-finger models).

    Raises:
        UserError: the model cannot take inputs of this size (``--size`` too small).
    """
    try:
        if hasattr(model, "n_fingers"):
            return model.n_fingers * count_macs(model.net, shape[1:])
        return count_macs(model, shape)
    except RuntimeError as exc:
        raise UserError(f"--size {shape[-1]}: too small for this model "
                        f"({str(exc).splitlines()[0]})") from None
