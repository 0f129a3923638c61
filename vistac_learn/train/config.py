"""A training run's settings (`TrainCfg`, written to ``config.json``) and what they build."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from vistac.config import Config, param
from vistac.errors import UserError
from vistac_learn.data.cache import variant_images
from vistac_learn.data.pairs import (
    FINGER_CHOICES,
    ROTATION_MODES,
    TARGETS,
    PairDataset,
    RotationCfg,
    fingers_of,
)
from vistac_learn.data.variants import VARIANTS, VariantCfg
from vistac_learn.models import create_model

DEVICES = ("auto", "cpu", "cuda")


@dataclass
class TrainCfg(Config):
    """Everything a training run depends on (written to ``config.json``).

    The study's defaults (thesis.md section 8): MSE loss, Adam, lr 1e-4, weight decay 1e-5,
    batch 5, 20 epochs. Every field but `eval_batch_size` is an option of `vistac train`.
    """

    data: str = param(help="dataset directory")
    out: str = param(help="run folder to create (or continue)")
    model: str = param("schoeconv100-v3-fc160", help="registered model name (`vistac models`)")
    variant: str = param("edge-index", choices=VARIANTS,
                         help="image variant (`vistac_learn.data.variants`)")
    finger: str = param("index", choices=FINGER_CHOICES,
                        help="finger(s) whose labels are the target (2 outputs per finger)")
    epochs: int = param(20, ge=1, help="epochs to train")
    batch_size: int = param(5, ge=1, help="pairs per optimiser step")
    lr: float = param(1e-4, gt=0, help="Adam learning rate")
    weight_decay: float = param(1e-5, ge=0, help="Adam weight decay")
    seed: int = param(0, help="seed of initial weights, pair order and press draws")
    target: str = param("mean", choices=TARGETS,
                        help="training target from the repeats: mean unit label (default), one "
                        "random press per pair and epoch, or every press")
    rotations: str = param("fixed", choices=ROTATION_MODES, help="rotation set of the images")
    n_rotations: int = param(20, ge=1, help="angles per configuration (training and "
                             "validation)")
    rotation_step: float = param(18.0, help="degrees between fixed angles")
    margin: float = param(0.05, help="finger-box margin as a fraction of the image side")
    size: int | None = param(None, help="input side (default: the model's)")
    select: str = param("loss", help="validation quantity choosing the best epoch: loss (MSE "
                        "against the mean unit labels) or a summary metric name of "
                        "`cone_metrics` (e.g. error_median_pct, lower is better; in_cone_pct, "
                        "higher is better), averaged over the fingers with both")
    train_split: str = param("train", help="split to train on")
    val_split: str = param("val", help="split to select on")
    device: str = param("auto", choices=DEVICES,
                        help="auto (CUDA when present, else CPU), cpu or cuda")
    cache_dir: str | None = param(None, help="variant cache (default <data>/cache/variants)")
    checkpoint_every: int = param(0, help="also checkpoint every N batches (0: at epoch ends "
                                  "only)")
    eval_batch_size: int = param(64, ge=1, help="pairs per forward pass when scoring")

    def rotation_cfg(self) -> RotationCfg:
        """The rotation set of training and validation."""
        return RotationCfg(self.rotations, self.n_rotations, self.rotation_step, self.seed)


def resolve_device(name: str) -> torch.device:
    """``auto`` -> CUDA when available, else CPU."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise UserError("--device cuda: no CUDA device available")
    return torch.device(name)


def build_model(cfg: TrainCfg) -> torch.nn.Module:
    """The run's model, freshly initialised from the seed."""
    channels = VariantCfg(cfg.variant).channels
    n_out = 2 * len(fingers_of(cfg.finger))
    torch.manual_seed(cfg.seed)
    try:
        return create_model(cfg.model, in_channels=channels, out_features=n_out)
    except (KeyError, ValueError) as exc:
        raise UserError(f"--model {cfg.model!r}: {exc}") from exc


def build_pairs(cfg: TrainCfg, tables, split: str, input_size: int, progress: bool = False,
                target: str | None = None, rotations: RotationCfg | None = None) -> PairDataset:
    """The pair dataset of one split in the run's variant (cached images)."""
    vcfg = VariantCfg(cfg.variant, cfg.size or input_size, cfg.margin)
    images = variant_images(tables, vcfg, rotations or cfg.rotation_cfg(), cfg.cache_dir,
                            progress=progress)
    return PairDataset(tables, tables.rows(split), images, fingers_of(cfg.finger),
                       target or cfg.target, cfg.seed)
