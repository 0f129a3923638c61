"""Checkpoint files of a run: atomic saves, stale temporaries, starting from another run.

`init_from_run` (``vistac train --init RUN``) copies RUN's best weights into a new model: every
tensor whose name and shape match is copied; any other (a head for another number of fingers, a
different input) keeps its fresh initialisation and is reported. A RUN that shares no tensor
with the new model, or that is not a run, is a clear error. ``--freeze features`` then keeps
every parameter of the feature layers (names containing ``features``) fixed.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import torch

from vistac.dataset.files import temporary_path
from vistac.errors import UserError


def atomic_save(obj, path: Path) -> None:
    """`torch.save` through a temporary file and a rename (a kill leaves the old file)."""
    tmp = temporary_path(path)
    try:
        torch.save(obj, tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


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
        saved = torch.load(path, map_location="cpu", weights_only=False)["model"]
    except Exception as exc:  # a truncated or foreign file
        raise UserError(f"--init {path}: unreadable checkpoint ({exc})") from None
    own = model.state_dict()
    copied = [k for k, v in saved.items() if k in own and own[k].shape == v.shape]
    fresh = [k for k in own if k not in copied]
    if not copied:
        src = json.loads((run / "config.json").read_text())["train"]
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
