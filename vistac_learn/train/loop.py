"""The training loop: train a registered model on one image variant of a dataset.

The study's defaults (thesis.md section 8) are those of `TrainCfg`. After each epoch the model is
scored on the validation split (never on the test split) and the best epoch by the selection
metric is kept as `best.pt`.

Run folder (``--out``):

- ``config.json``: the full `TrainCfg`, the model's size, the dataset fingerprint, versions.
- ``metrics.csv``: append-only, one row per finished epoch (train loss, validation loss and
  the validation metrics of each finger, seconds).
- ``checkpoints/last.pt``: model, optimizer, torch RNG state, position (epoch, batch), history;
  written atomically at the end of every epoch and every ``checkpoint_every`` batches.
- ``checkpoints/best.pt``: the model weights of the best validation epoch.

Repeatability: weights are initialised after ``torch.manual_seed(seed)``; the order of the
training pairs in epoch e is a permutation drawn from ``numpy.random.default_rng([seed, e])``,
independent of what ran before, and the torch RNG state travels in the checkpoint. A run killed
at any point and continued with ``--resume`` therefore replays exactly the batches the
uninterrupted run would have seen; on CPU its metrics are bit-identical (tests assert equality
at atol 1e-7 on every metrics column except time).
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from vistac.dataset import open_dataset
from vistac.errors import UserError
from vistac_learn.data.pairs import PairDataset, fingers_of
from vistac_learn.data.variants import VariantCfg
from vistac_learn.metrics.scoring import predict, score_predictions
from vistac_learn.models import model_info
from vistac_learn.train.config import TrainCfg, build_model, build_pairs, resolve_device

HIGHER_IS_BETTER = frozenset({"correct_y_pct", "in_cone_pct", "n_in_cone"})


def _atomic_save(obj, path: Path) -> None:
    tmp = path.with_suffix(f".tmp{os.getpid()}")
    torch.save(obj, tmp)
    os.replace(tmp, path)


def _selection_value(row: dict, select: str, fingers: tuple[str, ...]) -> tuple[float, bool]:
    """(value, higher_is_better) of the selection quantity in an epoch's metrics row."""
    if select == "loss":
        return row["val_loss"], False
    keys = [f"val_{f}_{select}" for f in fingers]
    if not all(k in row for k in keys):
        names = sorted({k.split("_", 2)[2] for k in row if k.startswith(f"val_{fingers[0]}_")})
        raise UserError(f"--select {select!r}: not a metric; choose loss or one of {names}")
    higher = select in HIGHER_IS_BETTER
    return float(np.mean([row[k] for k in keys])), higher


def _append_rows(path: Path, rows: list[dict]) -> None:
    """Append rows to the metrics CSV (header written when the file is new)."""
    new = not path.exists() or path.stat().st_size == 0
    with path.open("a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0].keys()))
        if new:
            w.writeheader()
        w.writerows(rows)


def _logged_epochs(path: Path) -> set[int]:
    if not path.exists():
        return set()
    with path.open() as fh:
        return {int(r["epoch"]) for r in csv.DictReader(fh)}


def evaluate_loss(model, ds: PairDataset, device, batch_size: int) -> tuple[float, np.ndarray]:
    """(mean MSE against the dataset's targets, predictions (M, 2F)) over every pair."""
    pred = predict(model, ds, device, batch_size)
    target = ds.targets(np.arange(len(ds)))
    return float(np.mean((pred - target) ** 2)), pred


def train(
    cfg: TrainCfg,
    resume: bool = False,
    progress: bool = True,
    on_batch: Callable[[int, int], None] | None = None,
) -> Path:
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
            without a checkpoint or with different settings.
    """
    out = Path(cfg.out)
    ckpt_dir = out / "checkpoints"
    last_path, best_path = ckpt_dir / "last.pt", ckpt_dir / "best.pt"
    metrics_path = out / "metrics.csv"
    if resume:
        if not last_path.exists():
            raise UserError(f"{last_path}: no checkpoint to resume from")
        saved = json.loads((out / "config.json").read_text())["train"]
        mine = asdict(cfg)
        diff = [k for k in mine if k not in ("epochs", "out") and saved.get(k) != mine[k]]
        if diff:
            raise UserError(
                f"{out / 'config.json'}: --resume with different settings ({', '.join(diff)})"
            )
    elif (out / "config.json").exists():
        raise UserError(f"{out}: already holds a run; pass --resume or choose another --out")

    device = resolve_device(cfg.device)
    if device.type == "cuda":  # CPU kernels are deterministic already
        torch.backends.cudnn.deterministic = True
        torch.backends.cudnn.benchmark = False
    tables = open_dataset(cfg.data)
    fingers = fingers_of(cfg.finger)
    model = build_model(cfg)
    input_size = int(getattr(model, "input_size", cfg.size or 227))
    train_ds = build_pairs(cfg, tables, cfg.train_split, input_size, progress)
    val_ds = build_pairs(cfg, tables, cfg.val_split, input_size, progress, target="mean")
    model.to(device)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    n_batches = math.ceil(len(train_ds) / cfg.batch_size)

    start_epoch, start_batch, history = 0, 0, []
    run_sum, run_n = 0.0, 0
    best_value, best_epoch = None, None
    if resume:
        ck = torch.load(last_path, map_location=device, weights_only=False)
        model.load_state_dict(ck["model"])
        opt.load_state_dict(ck["optimizer"])
        torch.set_rng_state(ck["torch_rng"])
        if device.type == "cuda" and ck.get("cuda_rng") is not None:
            torch.cuda.set_rng_state_all(ck["cuda_rng"])
        start_epoch, start_batch = ck["epoch"], ck["batch"]
        run_sum, run_n = ck["run_sum"], ck["run_n"]
        history, best_value, best_epoch = ck["history"], ck["best_value"], ck["best_epoch"]
        logged = _logged_epochs(metrics_path)
        missing = [r for r in history if r["epoch"] not in logged]
        if missing:  # killed between the checkpoint and the metrics append
            _append_rows(metrics_path, missing)
    else:
        ckpt_dir.mkdir(parents=True, exist_ok=True)
        info = model_info(cfg.model, VariantCfg(cfg.variant).channels, 2 * len(fingers))
        meta = {
            "train": asdict(cfg),
            "model": {k: v for k, v in info.items() if isinstance(v, int | float | str)},
            "dataset": {"path": str(Path(cfg.data).resolve()),
                        "fingerprint": tables.fingerprint(),
                        "n_train_configs": len(train_ds.rows), "n_val_configs": len(val_ds.rows),
                        "n_train_pairs": len(train_ds), "n_val_pairs": len(val_ds)},
            "device": str(device),
            "versions": {"torch": torch.__version__, "numpy": np.__version__,
                         "python": platform.python_version()},
        }
        (out / "config.json").write_text(json.dumps(meta, indent=2))

    def save_last(epoch: int, batch: int) -> None:
        _atomic_save({
            "model": model.state_dict(), "optimizer": opt.state_dict(),
            "torch_rng": torch.get_rng_state(),
            "cuda_rng": torch.cuda.get_rng_state_all() if device.type == "cuda" else None,
            "epoch": epoch, "batch": batch, "run_sum": run_sum, "run_n": run_n,
            "history": history, "best_value": best_value, "best_epoch": best_epoch,
            "cfg": asdict(cfg),
        }, last_path)

    loss_fn = torch.nn.MSELoss()
    for epoch in range(start_epoch, cfg.epochs):
        t0 = time.perf_counter()
        train_ds.set_epoch(epoch)
        perm = np.random.default_rng([cfg.seed, epoch]).permutation(len(train_ds))
        model.train()
        first = start_batch if epoch == start_epoch else 0
        if first == 0:
            run_sum, run_n = 0.0, 0
        bar = tqdm(range(first, n_batches), desc=f"epoch {epoch + 1}/{cfg.epochs}",
                   total=n_batches, initial=first, disable=not progress, leave=False)
        for b in bar:
            batch = train_ds.batch(perm[b * cfg.batch_size:(b + 1) * cfg.batch_size])
            x, y = batch["image"].to(device), batch["target"].to(device)
            opt.zero_grad(set_to_none=True)
            loss = loss_fn(model(x), y)
            loss.backward()
            opt.step()
            run_sum += float(loss.detach()) * len(y)
            run_n += len(y)
            bar.set_postfix(loss=f"{run_sum / run_n:.4g}")
            if cfg.checkpoint_every and (b + 1) % cfg.checkpoint_every == 0 and b + 1 < n_batches:
                save_last(epoch, b + 1)
            if on_batch is not None:
                on_batch(epoch, b)
        train_time = time.perf_counter() - t0
        val_loss, pred = evaluate_loss(model, val_ds, device, cfg.eval_batch_size)
        row = {"epoch": epoch + 1, "train_loss": run_sum / max(run_n, 1), "val_loss": val_loss}
        for f, m in score_predictions(pred, val_ds).items():
            row |= {f"val_{f}_{k}": v for k, v in m.items()}
        row |= {"train_s": train_time, "epoch_s": time.perf_counter() - t0}
        value, higher = _selection_value(row, cfg.select, fingers)
        improved = best_value is None or (value > best_value if higher else value < best_value)
        if improved:
            best_value, best_epoch = value, epoch + 1
            _atomic_save({"model": model.state_dict(), "epoch": epoch + 1,
                          "select": cfg.select, "value": value, "cfg": asdict(cfg)}, best_path)
        history.append(row)
        run_sum, run_n = 0.0, 0
        save_last(epoch + 1, 0)
        _append_rows(metrics_path, [row])
        if progress:
            tqdm.write(
                f"epoch {epoch + 1}/{cfg.epochs}: train loss {row['train_loss']:.4g}, "
                f"val loss {val_loss:.4g}, {cfg.select} {value:.4g}"
                + (" (best)" if improved else "") + f", {row['epoch_s']:.1f} s"
            )
    return out
