"""The training loop: `train_run_folder(cfg)`, shared by `vistac train`, tuning and experiments.

`train_run_folder` holds the run folder's lock and strings the parts together: the folder's policy
(`vistac_learn.train.run_folder`), the samples and their `DataLoader`
(`vistac_learn.data.loading`), `train_one_epoch`, `validate`, the selection of the best epoch
and the checkpoints (`vistac_learn.train.checkpoints`).

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

Repeatability: weights are initialised from the seed in a seed scope (`build.build_model`);
the order of the training samples in epoch e is a permutation drawn from
``numpy.random.default_rng([seed, e])`` and every sample's augmentation from (seed, e, sample),
independent of what ran before and of the loader's workers (``loader_workers``); the torch RNG
state travels in the checkpoint. A run killed at any point and continued with ``--resume``
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

import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from vistac.dataset import open_tables
from vistac.dataset.files import remove_stale_temporaries
from vistac.errors import UserError
from vistac.folder_lock import hold
from vistac.progress import bar as progress_bar
from vistac.progress import note
from vistac_learn.data.fingertip_table import fingertip_table
from vistac_learn.data.loading import loader
from vistac_learn.data.samples import SampleSet, fingers_of
from vistac_learn.metrics.scoring import predict, score_predictions
from vistac_learn.train.build import (
    build_boxes,
    build_model,
    build_samples,
    build_view,
    input_size,
    resolve_device,
    run_coverage,
)
from vistac_learn.train.checkpoints import (
    BEST_KEYS,
    LAST_KEYS,
    RESTART,
    LoopState,
    init_from_run,
    load_checkpoint,
    restore_last,
    save_best,
    save_last,
    trainable_parameters,
)
from vistac_learn.train.config import TrainCfg
from vistac_learn.train.label_lean import label_lean, lean_note
from vistac_learn.train.losses import batch_loss, masked_mse  # noqa: F401  (masked_mse: API)
from vistac_learn.train.memory import check_fits
from vistac_learn.train.run_files import append_metrics, mark_diverged, restore_metrics
from vistac_learn.train.run_folder import RunFolder, run_meta

__all__ = ["BEST_KEYS", "DIVERGED_LOSS", "LAST_KEYS", "RESTART", "TrainingDiverged", "diverged",
           "evaluate_loss", "train_one_epoch", "train_run_folder", "validate"]

HIGHER_IS_BETTER = frozenset({"correct_y_pct", "in_cone_pct", "n_in_cone"})
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


def evaluate_loss(model, ds, device, batch_size: int, workers: int = 0
                  ) -> tuple[float, np.ndarray]:
    """(MSE against the mean unit labels, predictions (M, 2F)) over every sample."""
    pred = predict(model, ds, device, batch_size, workers)
    found = np.repeat(ds.found(np.arange(len(ds))), 2, axis=1)
    err = (pred - ds.targets(np.arange(len(ds)))) ** 2
    return float((err * found).sum() / max(found.sum(), 1)), pred


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


def train_one_epoch(model: torch.nn.Module, ds: SampleSet, opt, sched, cfg: TrainCfg,
                    device: torch.device, state: LoopState,
                    save: Callable[[], None] | None = None,
                    on_batch: Callable[[int, int], None] | None = None,
                    progress: bool = False) -> None:
    """Train epoch ``state.epoch`` from batch ``state.batch`` on, in the epoch's seeded order;
    `state` follows (batch, running loss).

    Args:
        model: The model, on `device`.
        ds: The training samples.
        opt: The optimiser.
        sched: The learning-rate schedule, stepped after every batch.
        cfg: The run's settings (batch size, seed, aux weight, checkpoint_every, workers).
        device: Where the model is.
        state: Position and running loss; updated after every step.
        save: Called after every ``cfg.checkpoint_every`` batches (but the last).
        on_batch: Called as ``on_batch(epoch, batch)`` after every optimiser step.
        progress: Show a progress bar (`vistac.progress`).

    Raises:
        TrainingDiverged: a training loss that is not finite or above `DIVERGED_LOSS`.
    """
    epoch = state.epoch
    perm = np.random.default_rng([cfg.seed, epoch]).permutation(len(ds))
    batches = loader(ds, cfg.batch_size, epoch, perm, state.batch, cfg.loader_workers)
    n_batches = batches.batch_sampler.total
    _train_mode(model, cfg.freeze)
    bar = progress_bar(total=n_batches, initial=state.batch,
                       desc=f"epoch {epoch + 1}/{cfg.epochs}", enabled=progress, leave=False,
                       unit="batch", lines="none")  # a log gets the epoch's line instead
    try:
        for b, batch in enumerate(batches, start=state.batch):
            n = len(batch["target"])
            opt.zero_grad(set_to_none=True)
            loss = batch_loss(model, batch, device, cfg.aux_weight)
            value = float(loss.detach())
            if diverged(value):
                raise TrainingDiverged(epoch + 1, "training loss", value, cfg.lr)
            loss.backward()
            opt.step()
            sched.step()
            state.run_sum += value * n
            state.run_n += n
            state.batch = b + 1
            bar.update(1)
            bar.set_postfix(loss=f"{state.run_sum / state.run_n:.4g}")
            if save is not None and cfg.checkpoint_every and \
                    (b + 1) % cfg.checkpoint_every == 0 and b + 1 < n_batches:
                save()
            if on_batch is not None:
                on_batch(epoch, b)
    finally:
        bar.close()


def validate(model: torch.nn.Module, ds: SampleSet, cfg: TrainCfg, device: torch.device,
             epoch: int) -> dict:
    """The validation part of an epoch's metrics row: loss and every finger's metrics.

    Raises:
        TrainingDiverged: predictions or a loss that are not finite, a loss above
            `DIVERGED_LOSS`.
    """
    val_loss, pred = evaluate_loss(model, ds, device, cfg.eval_batch_size, cfg.loader_workers)
    if not np.isfinite(pred).all() or diverged(val_loss):
        raise TrainingDiverged(epoch + 1, "validation loss", val_loss, cfg.lr)
    row = {"val_loss": val_loss}
    for f, m in score_predictions(pred, ds).items():
        row |= {f"val_{f}_{k}": v for k, v in m.items()}
    return row


def train_run_folder(cfg: TrainCfg, resume: bool = False, progress: bool = True,
                     on_batch: Callable[[int, int], None] | None = None) -> Path:
    """Train (or continue) a run; return the run folder.

    Args:
        cfg: The run's settings.
        resume: Continue the run in ``cfg.out`` from ``checkpoints/last.pt``.
        progress: Show progress bars and a line per epoch on stderr.
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
    folder = RunFolder(Path(cfg.out))
    started = folder.prepare(resume)
    device = resolve_device(cfg.device)
    if device.type == "cuda":  # CPU kernels are deterministic already
        torch.backends.cudnn.deterministic = True
        torch.backends.cudnn.benchmark = False
    tables = open_tables(cfg.data)
    fingerprint = tables.fingerprint()
    if started:
        folder.check_resume(cfg, fingerprint)
        ck = load_checkpoint(folder.last, LAST_KEYS, RESTART, map_location=device)
        if folder.best.exists():
            load_checkpoint(folder.best, BEST_KEYS, RESTART)
    fingers = fingers_of(cfg.finger)
    model = build_model(cfg)
    init_note = init_from_run(model, cfg) if cfg.init and not started else None
    size = input_size(cfg, model)
    view = build_view(cfg)
    check_fits(model, view.channels, size, cfg.batch_size, cfg.eval_batch_size, device)
    tips = fingertip_table(tables, cache_dir=cfg.cache_dir, progress=progress) \
        if view.needs_tips else None
    boxes = build_boxes(cfg, tables, progress)  # where the dataset has none (ingested)
    coverage = run_coverage(cfg, tables, tips, boxes)  # refuses too many fingers not found
    train_ds = build_samples(cfg, tables, cfg.train_split, size, tips, train=True, boxes=boxes)
    val_ds = build_samples(cfg, tables, cfg.val_split, size, tips, boxes=boxes)
    model.to(device)
    n_batches = math.ceil(len(train_ds) / cfg.batch_size)
    opt, sched = _optimizer(cfg, model, n_batches * cfg.epochs)

    if started:
        remove_stale_temporaries(folder.checkpoints)
        state = restore_last(ck, folder.last, model, opt, sched, device)
        restore_metrics(folder.metrics, state.history)  # a kill before an append, a damaged table
    else:  # a new run, or one killed before its first checkpoint: start (again) from scratch
        state = LoopState()
        lean = label_lean({f: tables.mean_label(f)[train_ds.rows] for f in fingers})
        folder.start(run_meta(cfg, model, tables, fingerprint, train_ds, val_ds, device,
                              init_note)
                     | {"fingertips": {c.split: c.as_dict() for c in coverage},
                        "label_lean": lean})
        if init_note and progress:
            note(f"init: {init_note['summary']}")
        lean_line = lean_note(lean, cfg.mirror, cfg.tta)
        if lean_line and progress:
            note(f"note: {lean_line}")

    def save() -> None:
        save_last(folder.last, model, opt, sched, state, cfg, device)

    try:
        while state.epoch < cfg.epochs:
            epoch = state.epoch
            t0 = time.perf_counter()
            if state.batch == 0:
                state.run_sum, state.run_n = 0.0, 0
            train_one_epoch(model, train_ds, opt, sched, cfg, device, state, save, on_batch,
                            progress)
            train_time = time.perf_counter() - t0
            row = {"epoch": epoch + 1, "train_loss": state.run_sum / max(state.run_n, 1)}
            val = validate(model, val_ds, cfg, device, epoch)
            row |= {"val_loss": val.pop("val_loss"), "lr": float(opt.param_groups[0]["lr"])}
            row |= val | {"train_s": train_time, "epoch_s": time.perf_counter() - t0}
            value, higher = _selection_value(row, cfg.select, fingers)
            improved = state.improves(value, higher)
            if improved:
                state.best_value, state.best_epoch = value, epoch + 1
                save_best(folder.best, model, epoch + 1, cfg.select, value, cfg)
            state.history.append(row)
            state.epoch, state.batch, state.run_sum, state.run_n = epoch + 1, 0, 0.0, 0
            save()
            append_metrics(folder.metrics, [row])
            if progress:
                note(f"epoch {epoch + 1}/{cfg.epochs}: train loss {row['train_loss']:.4g}, "
                     f"val loss {row['val_loss']:.4g}, {cfg.select} {value:.4g}"
                     + (" (best)" if improved else "") + f", {row['epoch_s']:.1f} s")
    except TrainingDiverged as exc:  # mark the run, so that a rerun into --out starts over
        mark_diverged(folder.path, exc.epoch, str(exc))
        raise
    return folder.path


def _train_mode(model: torch.nn.Module, freeze: str) -> None:
    """Training mode; frozen feature layers stay in evaluation mode (batch-norm statistics
    fixed)."""
    model.train()
    if freeze == "features":
        for name, module in model.named_modules():
            if name.endswith("features"):
                module.eval()
