"""Checkpoint files of a run: atomic saves, safe loads, the loop's state, starting from another run.

``checkpoints/last.pt`` (`save_last`, `restore_last`) holds what continuing needs: the model,
optimiser and schedule states, the torch RNG state and the `LoopState` (position, running loss,
history, best so far); ``checkpoints/best.pt`` (`save_best`) the weights of the best epoch.

A checkpoint holds tensors and plain data only (dicts, lists, numbers, strings): `atomic_save`
turns NumPy scalars and arrays, tuples' contents and paths into plain values before saving, and
`load_checkpoint` reads with ``torch.load(weights_only=True)``, which refuses any pickled object
that is not one of those. A checkpoint from somebody else's run therefore cannot run code: a file
carrying a pickled call (``os.system`` and the like) is refused with a one-line error.

`init_from_run` (``vistac train --init RUN``) copies RUN's best weights into a new model: every
tensor whose name and shape match is copied; any other (a head for another number of fingers, a
different input) keeps its fresh initialisation and is reported. A RUN that shares no tensor
with the new model, or that is not a run, is a clear error. ``--freeze features`` then keeps
every parameter of the feature layers (names containing ``features``) fixed.
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from vistac.dataset.files import atomic_write_bytes, check_file
from vistac.errors import UserError
from vistac_learn.train.run_files import read_run_config

LAST_KEYS = ("model", "optimizer", "schedule", "torch_rng", "epoch", "batch", "run_sum",
             "run_n", "history", "best_value", "best_epoch")
BEST_KEYS = ("model", "epoch")
RESTART = "rerun without --resume to start the run over"


@dataclass
class LoopState:
    """Where a training run stands (saved in ``last.pt``).

    Attributes:
        epoch: Epochs finished (the epoch under way, 0-based).
        batch: Batches of that epoch done.
        run_sum: Sum of the epoch's training losses so far, weighted by batch size.
        run_n: Samples behind `run_sum`.
        history: One metrics row per finished epoch.
        best_value: The selection quantity of the best epoch so far.
        best_epoch: The best epoch so far (1-based).
    """

    epoch: int = 0
    batch: int = 0
    run_sum: float = 0.0
    run_n: int = 0
    history: list[dict] = field(default_factory=list)
    best_value: float | None = None
    best_epoch: int | None = None

    def improves(self, value: float, higher: bool) -> bool:
        """Whether `value` beats the best so far (the first value always does)."""
        return self.best_value is None or (value > self.best_value if higher
                                           else value < self.best_value)


def save_last(path: Path, model: torch.nn.Module, opt, sched, state: LoopState, cfg,
              device: torch.device) -> None:
    """Write ``last.pt``: model, optimiser, schedule, RNG states, `state` and the settings."""
    atomic_save({
        "model": model.state_dict(), "optimizer": opt.state_dict(),
        "schedule": sched.state_dict(), "torch_rng": torch.get_rng_state(),
        "cuda_rng": torch.cuda.get_rng_state_all() if device.type == "cuda" else None,
        **asdict(state), "cfg": asdict(cfg),
    }, path)


def restore_last(ck: dict, path: Path, model: torch.nn.Module, opt, sched,
                 device: torch.device) -> LoopState:
    """Load a `load_checkpoint` of ``last.pt`` into model, optimiser, schedule and the torch RNG;
    return the loop's state.

    Raises:
        UserError: states that do not fit (a damaged or foreign file).
    """
    load_weights(model, ck["model"], path, RESTART)
    try:
        opt.load_state_dict(ck["optimizer"])
        sched.load_state_dict(ck["schedule"])
        torch.set_rng_state(ck["torch_rng"])
    except (ValueError, TypeError, KeyError, RuntimeError) as exc:
        raise UserError(f"{path}: damaged state ({exc}); {RESTART}") from None
    if device.type == "cuda" and ck.get("cuda_rng") is not None:
        torch.cuda.set_rng_state_all(ck["cuda_rng"])
    return LoopState(ck["epoch"], ck["batch"], ck["run_sum"], ck["run_n"], ck["history"],
                     ck["best_value"], ck["best_epoch"])


def save_best(path: Path, model: torch.nn.Module, epoch: int, select: str, value: float,
              cfg) -> None:
    """Write ``best.pt``: the weights of the best epoch, which it was and by what."""
    atomic_save({"model": model.state_dict(), "epoch": epoch, "select": select,
                 "value": value, "cfg": asdict(cfg)}, path)


def plain(obj):
    """`obj` with NumPy values, tuples and paths turned into plain Python (tensors kept)."""
    if isinstance(obj, torch.Tensor | str | int | float | bool) or obj is None:
        return obj
    if isinstance(obj, dict):
        return {plain(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [plain(v) for v in obj]
    if isinstance(obj, np.ndarray | np.generic):
        return obj.tolist()
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"checkpoint: {type(obj).__name__} is not plain data")


def atomic_save(obj: dict, path: Path) -> None:
    """`torch.save` of `obj` as plain data (see `plain`) through a temporary file and a rename
    (a kill leaves the old file).

    The checkpoint is serialised in memory first, so that a failing write (a full disk) is the
    `OSError` of Python's own file write, not an error from inside torch's writer.
    """
    buf = io.BytesIO()
    torch.save(plain(obj), buf)
    atomic_write_bytes(path, buf.getvalue())


def load_checkpoint(path: Path, keys: Sequence[str], fix: str, map_location="cpu") -> dict:
    """A checkpoint written by `atomic_save`, read safely and checked: a dict holding `keys`.

    ``weights_only=True``: tensors and plain data load, any other pickled object is refused
    unrun.

    Args:
        path: The ``.pt`` file.
        keys: Entries it must hold.
        fix: What the user can do about a damaged file (the end of the error's line).
        map_location: Where tensors go.

    Raises:
        UserError: the file is missing, truncated, not a checkpoint, lacks an entry or
            carries pickled objects other than tensors and plain data.
    """
    check_file(path)
    try:
        ck = torch.load(path, map_location=map_location, weights_only=True)
    except FileNotFoundError:
        raise UserError(f"{path}: missing; {fix}") from None
    except Exception as exc:  # truncated or foreign bytes: zipfile, pickle and torch errors
        reason = " ".join(str(exc).split())
        if "weights_only" in reason or "Unsupported global" in reason:
            raise UserError(f"{path}: holds pickled objects other than tensors and plain data "
                            f"(refused: loading them could run code); {fix}") from None
        reason = reason[:120] or type(exc).__name__
        raise UserError(f"{path}: not a readable checkpoint ({reason}); {fix}") from None
    missing = [k for k in keys if not isinstance(ck, dict) or k not in ck]
    if missing:
        raise UserError(f"{path}: not a checkpoint of this kind (no {', '.join(missing)}); "
                        f"{fix}")
    return ck


def nonfinite_weight(state: object) -> str | None:
    """The name of the first floating-point tensor of `state` holding NaN or infinity, or None;
    a model with such weights predicts NaN everywhere, so it is not loaded to be scored or to
    start another run from."""
    if not isinstance(state, dict):
        return None
    for name, value in state.items():
        if isinstance(value, torch.Tensor) and value.is_floating_point() \
                and not bool(torch.isfinite(value).all()):
            return str(name)
    return None


def load_weights(model: torch.nn.Module, state: dict, path: Path, fix: str) -> None:
    """`model.load_state_dict(state)`, a mismatch (other model, damaged tensors) or weights that
    are not finite one line."""
    bad = nonfinite_weight(state)
    if bad is not None:
        raise UserError(f"{path}: weight {bad} is not finite (NaN or infinite); {fix}")
    try:
        model.load_state_dict(state)
    except (RuntimeError, TypeError, AttributeError) as exc:
        reason = " ".join(str(exc).split())[:120]
        raise UserError(f"{path}: weights do not fit the run's model ({reason}); {fix}") \
            from None


def is_frozen(name: str, freeze: str) -> bool:
    """Whether parameter `name` stays fixed under a ``--freeze`` setting."""
    return freeze == "features" and "features" in name.split(".")


def trainable_parameters(model: torch.nn.Module) -> list[torch.nn.Parameter]:
    """The parameters the optimiser updates."""
    return [p for p in model.parameters() if p.requires_grad]


def init_from_run(model: torch.nn.Module, cfg) -> dict:
    """Load ``cfg.init``'s best weights into `model` where they fit; freeze as asked.

    Returns:
        A note for ``config.json``: source run and checkpoint, copied and re-initialised tensor
        names, frozen parameter count and a one-line summary.

    Raises:
        UserError: ``cfg.init`` is not a run with a best checkpoint, or shares no tensor.
    """
    run = Path(cfg.init)
    path = run / "checkpoints" / "best.pt"
    if not (run / "config.json").exists() or not path.exists():
        raise UserError(f"--init {run}: not a finished run (needs config.json and "
                        "checkpoints/best.pt)")
    try:
        saved = load_checkpoint(path, ("model",), "choose another --init run")["model"]
        src = read_run_config(run, "choose another --init run")["train"]
    except UserError as exc:
        raise UserError(f"--init {exc}") from None
    if not isinstance(saved, dict):
        raise UserError(f"--init {path}: not a checkpoint of model weights; choose another run")
    if nonfinite_weight(saved) is not None:
        raise UserError(f"--init {path}: weight {nonfinite_weight(saved)} is not finite (NaN or "
                        "infinite); choose another --init run")
    own = model.state_dict()
    copied = [k for k, v in saved.items()
              if k in own and isinstance(v, torch.Tensor) and own[k].shape == v.shape]
    fresh = [k for k in own if k not in copied]
    if not copied:
        raise UserError(f"--init {run}: its model ({src.get('model')}, {src.get('variant')}) "
                        f"shares no weights with --model {cfg.model} --variant {cfg.variant}")
    own.update({k: saved[k] for k in copied})
    model.load_state_dict(own)
    frozen = 0
    for name, p in model.named_parameters():
        if is_frozen(name, cfg.freeze):
            p.requires_grad_(False)
            frozen += p.numel()
    params = [k for k in fresh if not k.endswith(("running_mean", "running_var",
                                                  "num_batches_tracked"))]
    summary = (f"{len(copied)} tensors from {path}"
               + (f"; re-initialised (shape differs or new): {', '.join(params)}"
                  if params else "") + (f"; {frozen} feature parameters frozen" if frozen else ""))
    return {"run": str(run.resolve()), "checkpoint": str(path.resolve()), "copied": copied,
            "reinitialised": fresh, "frozen_params": frozen, "summary": summary}
