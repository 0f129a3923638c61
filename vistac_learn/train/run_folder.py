"""The run folder's policy: what a training run may do with ``--out``, before and at its start.

- A folder that is neither a run nor empty is refused; so is a started run without
  ``--resume``, unless it diverged or its files are damaged (`damage`), in which case a plain
  rerun starts it over.
- ``--resume`` must continue the same settings (the number of epochs and where files are read
  from aside) on the same dataset (`RunFolder.check_resume`).
- A new run writes ``config.json`` (`run_meta`) and an empty ``checkpoints/`` (`RunFolder.start`).
"""

from __future__ import annotations

import platform
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from vistac.dataset.files import atomic_write_json, broken_link, remove_stale_temporaries
from vistac.errors import UserError
from vistac_learn.train.build import build_view, input_size
from vistac_learn.train.checkpoints import (
    BEST_KEYS,
    LAST_KEYS,
    RESTART,
    load_checkpoint,
    trainable_parameters,
)
from vistac_learn.train.config import TrainCfg
from vistac_learn.train.run_files import CONFIG, METRICS, is_diverged, read_run_config, run_settings

RUN_FILES = frozenset({CONFIG, METRICS, "checkpoints", "eval"})
# settings a resume may change: the length of the run and where files are read from
RESUMABLE = ("epochs", "out", "data", "cache_dir", "max_missing_pct", "loader_workers")


@dataclass(frozen=True)
class RunFolder:
    """The files of a run folder (``--out``)."""

    path: Path

    @property
    def checkpoints(self) -> Path:
        return self.path / "checkpoints"

    @property
    def last(self) -> Path:
        return self.checkpoints / "last.pt"

    @property
    def best(self) -> Path:
        return self.checkpoints / "best.pt"

    @property
    def metrics(self) -> Path:
        return self.path / METRICS

    @property
    def config(self) -> Path:
        return self.path / CONFIG

    def prepare(self, resume: bool) -> bool:
        """Check the folder for a new run or a resume; clear a diverged or damaged run that is
        rerun without `resume`. Returns whether a started run (a ``last.pt``) is to continue.

        Raises:
            UserError: not a folder, a folder of other files, nothing to resume, a started
                run without `resume`.
        """
        out = self.path
        if out.exists() and not out.is_dir():
            raise UserError(f"--out {out}: exists and is not a folder")
        why = broken_link(self.checkpoints)
        if why is not None:
            raise UserError(f"--out {self.checkpoints}: {why}; remove it (or point it at a "
                            "folder) and run again")
        if out.is_dir() and not self.config.exists() \
                and any(p.name not in RUN_FILES for p in out.iterdir()):
            raise UserError(f"--out {out}: a folder that is not a run and not empty; choose "
                            "another")
        started = self.last.exists()
        if resume and not started and not self.config.exists():
            raise UserError(f"{out}: no run to resume (no config.json); drop --resume to start "
                            "one")
        if not resume and started and (is_diverged(out) or damage(out)):
            # a rerun (with a lower lr, or over damaged files) starts over
            for p in (self.last, self.best, self.metrics):
                p.unlink(missing_ok=True)
            started = False
        if not resume and started:
            raise UserError(f"{out}: already holds a run; pass --resume or choose another --out")
        return started

    def check_resume(self, cfg: TrainCfg, fingerprint: str) -> None:
        """Refuse to continue with other settings or another dataset.

        Raises:
            UserError: naming the settings that differ, or the dataset.
        """
        saved = read_run_config(self.path, RESTART)
        mine = asdict(cfg)
        diff = [k for k in mine if k not in RESUMABLE and saved["train"].get(k) != mine[k]]
        if diff:
            raise UserError(f"{self.config}: --resume with different settings "
                            f"({', '.join(diff)})")
        if saved["dataset"]["fingerprint"] != fingerprint:
            raise UserError(f"--data {cfg.data}: not the dataset this run started on (its "
                            f"fingerprint differs from {saved['dataset']['path']}'s)")
        planned = saved["train"].get("epochs")
        if cfg.schedule == "onecycle" and planned != cfg.epochs:
            raise UserError(f"--epochs {cfg.epochs}: the run's one-cycle schedule was planned "
                            f"for {planned} epochs; resume with --epochs {planned}")

    def start(self, meta: dict) -> None:
        """Begin a run (again, if killed before its first checkpoint): an empty metrics table,
        ``checkpoints/`` without leftovers, `meta` as ``config.json``."""
        self.checkpoints.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(self.checkpoints)
        self.metrics.unlink(missing_ok=True)
        atomic_write_json(self.config, meta)


def damage(out: Path) -> str | None:
    """Why the started run in `out` cannot be continued (a damaged config.json or checkpoint),
    or None (no run, or an intact one)."""
    folder = RunFolder(Path(out))
    if not folder.last.exists():
        return None
    try:
        run_settings(out, read_run_config(out, RESTART), RESTART)
        load_checkpoint(folder.last, LAST_KEYS, RESTART)
        if folder.best.exists():
            load_checkpoint(folder.best, BEST_KEYS, RESTART)
    except UserError as exc:
        return str(exc)
    return None


def finished(out: Path, epochs: int) -> bool:
    """Whether the run in `out` has trained `epochs` epochs (its last checkpoint is at the end
    of the last one); False for no run or a damaged one."""
    try:
        ck = load_checkpoint(RunFolder(Path(out)).last, LAST_KEYS, RESTART)
    except UserError:
        return False
    return ck["epoch"] >= epochs and ck["batch"] == 0


def run_meta(cfg: TrainCfg, model: torch.nn.Module, tables, fingerprint: str, train_ds, val_ds,
             device: torch.device, init_note: dict | None) -> dict:
    """A new run's ``config.json``: settings, the model's size, the dataset and its samples,
    where `--init` weights came from, device and versions."""
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
