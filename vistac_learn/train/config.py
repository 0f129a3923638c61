"""A training run's settings (`TrainCfg`, written to ``config.json``) and its two protocols;
what the settings build (device, view, model, samples) is `vistac_learn.train.build`.

Two protocols, each a complete set of defaults (every option overrides either):

- ``default``: the project's recipe. The ``pinch`` view (each finger's fingertip crop, found
  in the image and turned so that the finger points up, plus the numbers relating the two
  crops' frames) and `pinchnet` inside `PinchModel`: one network reads each crop's contact point
  and normal, the label is composed from them (closing axis, friction cone), and the
  simulator's contact points and normals, where the dataset has them, are auxiliary targets
  (``--aux-weight``); AdamW with a one-cycle learning-rate schedule, batches of 32, 25
  epochs; mirror and crop-jitter augmentation, and half the training images perturbed toward
  photographs (``--appearance 0.5``); the best epoch by the validation median angle to the
  cone mean; at evaluation each prediction averaged with its mirrored view's (``tta``).
- ``study``: the reference study's protocol (docs/study.md section 8): SchoeConv100-V3(FC160) on
  ``edge-index`` images at 20 fixed rotations of 18 degrees, index finger, MSE, Adam with a
  constant lr 1e-4, weight decay 1e-5, batches of 5, 20 epochs; selection by the validation
  median overall error (the study selected on its test set; we never do).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np

from vistac.config import Config, ConfigError, param
from vistac.dataset import SPLITS
from vistac.errors import UserError
from vistac_learn.data.samples import (
    FINGER_CHOICES,
    ROTATION_MODES,
    TARGETS,
    AugmentCfg,
    RotationCfg,
)
from vistac_learn.data.tip_coverage import MAX_MISSING_PCT
from vistac_learn.data.views import PINCH_VIEW, TIP_VIEW, VIEWS
from vistac_learn.models import list_models

DEVICES = ("auto", "cpu", "cuda")
OPTIMIZERS = ("adam", "adamw")
SCHEDULES = ("constant", "onecycle")
FREEZE = ("none", "features")
CROP_VIEWS = (PINCH_VIEW, TIP_VIEW)  # views of finger-aligned fingertip crops


@dataclass(frozen=True)
class TrainCfg(Config):
    """Everything a training run depends on (written to ``config.json``); defaults: the
    ``default`` protocol (see `PROTOCOLS`)."""

    data: str = param("", help="dataset directory (set by `vistac.train`'s data)")
    out: str = param("", help="run folder to create or continue (set by `vistac.train`'s out)")
    model: str = param("pinchnet", help="registered model name (`vistac models`); on the "
                       "pinch view it is the backbone of the contact-geometry model")
    variant: str = param(PINCH_VIEW, choices=VIEWS, help="what the model sees: pinch (both "
                         "fingertip crops, the label composed from contact geometry), tip "
                         "(fingertip crops, the label regressed; with --model tipnet the "
                         "previous default) or one of the study's image variants")
    finger: str = param("both", choices=FINGER_CHOICES,
                        help="finger(s) whose labels are the target (2 outputs per finger)")
    epochs: int = param(25, ge=1, le=100_000, help="epochs to train")
    batch_size: int = param(32, ge=1, le=65_536, help="samples per optimiser step")
    optimizer: str = param("adamw", choices=OPTIMIZERS, help="optimiser")
    lr: float = param(3e-3, gt=0, le=1e6, help="learning rate (the peak of a one-cycle schedule)")
    weight_decay: float = param(1e-4, ge=0, le=1, help="weight decay")
    schedule: str = param("onecycle", choices=SCHEDULES, help="learning-rate schedule")
    seed: int = param(0, ge=0, lt=2**32, help="seed of weights, sample order, draws, augmentation")
    target: str = param("mean", choices=TARGETS,
                        help="training target from the repeats: mean unit label, one random "
                        "press per sample and epoch, or every press")
    rotations: str = param("none", choices=ROTATION_MODES,
                           help="top-view rotations per configuration (study views only)")
    n_rotations: int = param(20, ge=1, le=360, help="samples per configuration with fixed or "
                             "random rotations (training and validation)")
    rotation_step: float = param(18.0, gt=0, le=360, help="degrees between fixed angles")
    mirror: bool = param(True, help="mirror half of the training samples (r_y -> -r_y)")
    jitter: float = param(1.0, ge=0, le=10, help="tip and pinch views: crop jitter as a "
                          "multiple of the default (0.1 radius, 2 deg, 5 %%); 0 switches it off")
    tta: bool = param(True, help="the recipe's test-time augmentation: `vistac evaluate` "
                      "averages each configuration's mirrored view (and rotations) unless told "
                      "otherwise (--tta on|off there)")
    appearance: float = param(0.5, ge=0, le=1, help="share of training images perturbed toward "
                              "photographs (textures, overlay style, light, tilt, camera); 0: "
                              "off")
    appearance_axes: float = param(0.5, gt=0, le=1, help="a perturbed training image: "
                                   "probability of each appearance axis (at least one)")
    margin: float = param(0.05, ge=0, le=1, help="study views: finger-box margin, fraction of "
                          "the image side")
    size: int | None = param(None, ge=16, le=1024, help="input side (default: the model's)")
    select: str = param("angle_to_mean_median_deg", help="validation quantity choosing the "
                        "best epoch: loss or a summary metric of `cone_metrics` (e.g. "
                        "angle_to_mean_median_deg or error_median_pct, lower is better; "
                        "in_cone_pct, higher is better), averaged over the fingers")
    train_split: str = param("train", choices=SPLITS, help="split to train on")
    train_fraction: float = param(1.0, gt=0, le=1, help="train on this fraction of the training "
                                  "configurations (a seeded subset; smaller fractions are "
                                  "subsets of larger ones)")
    val_split: str = param("val", choices=SPLITS, help="split to select on")
    init: str | None = param(None, help="run folder whose best weights start this run "
                             "(fine-tuning); a head of another shape is re-initialised")
    freeze: str = param("none", choices=FREEZE, help="with --init: keep the feature layers "
                        "fixed (features) or train everything (none)")
    device: str = param("auto", choices=DEVICES,
                        help="auto (CUDA when present, else CPU), cpu or cuda")
    cache_dir: str | None = param(None, help="folder of the fingertip table (default "
                                  "<data>/cache)")
    checkpoint_every: int = param(0, ge=0, help="also checkpoint every N batches (0: at epoch "
                                  "ends only)")
    eval_batch_size: int = param(256, ge=1, help="samples per forward pass when scoring")
    loader_workers: int = param(0, ge=0, le=64, help="processes rendering batches ahead of "
                                "the training step (0: rendered in the training process, the "
                                "fastest on a small CPU)")
    max_missing_pct: float = param(MAX_MISSING_PCT, ge=0, le=100, help="tip view: refuse to "
                                   "train when the fingertips of more than this share (%%) of "
                                   "a split's configurations are not found in their images")
    aux_weight: float = param(1.0, ge=0, le=1e6, help="pinch view: weight of the auxiliary "
                              "contact-point and normal losses where the dataset has the "
                              "simulator's contacts (0: labels only)")

    def __post_init__(self) -> None:
        super().__post_init__()
        # Messages name fields (other fields as {name}); the CLI puts its options in their place.
        if self.model.lower() not in list_models() and not _is_model(self.model):
            raise ConfigError("model", f"{self.model!r} is unknown; choose one of "
                              f"{', '.join(list_models())} (`vistac models`)")
        if self.select != "loss" and self.select not in selectable_metrics():
            raise ConfigError("select", f"{self.select!r} is not a metric; choose loss or one "
                              f"of {', '.join(selectable_metrics())}")
        if self.variant in CROP_VIEWS and self.rotations != "none":
            raise ConfigError("rotations", f"the {self.variant} view turns every crop to its "
                              "finger, so rotations change nothing; choose none")
        if self.freeze != "none" and self.init is None:
            raise ConfigError("freeze", "needs {init} RUN (weights to keep fixed)", ("init",))
        if self.train_split == self.val_split:
            raise ConfigError("val_split", f"must differ from {{train_split}} "
                              f"({self.train_split})", ("train_split",))
        if self.variant not in CROP_VIEWS and self.variant.endswith(("-index", "-thumb")):
            region = self.variant.rsplit("-", 1)[1]
            if self.finger not in (region,):
                raise ConfigError("finger", f"variant {self.variant} shows only the {region} "
                                  f"finger; choose {region}, not {self.finger}")

    @classmethod
    def from_protocol(cls, protocol: str, **changes) -> TrainCfg:
        """The defaults of a protocol (``default`` or ``study``, see `PROTOCOLS`), with
        `changes` (any field) on top."""
        return protocol_cfg(protocol, changes.pop("data", ""), changes.pop("out", ""),
                            **changes)

    def rotation_cfg(self) -> RotationCfg:
        """Rotations of training and validation samples."""
        return RotationCfg(self.rotations, self.n_rotations, self.rotation_step)

    def augment_cfg(self) -> AugmentCfg | None:
        """Training augmentation (None when nothing is switched on)."""
        j = self.jitter if self.variant in CROP_VIEWS else 0.0
        if not self.mirror and j == 0 and self.appearance == 0:
            return None
        d = AugmentCfg()
        return AugmentCfg(self.mirror, d.shift * j, d.turn * j, d.scale * j, self.appearance,
                          self.appearance_axes)


def _is_model(name: str) -> bool:
    """Whether `name` is a registered model under another spelling (e.g. the thesis's)."""
    from vistac_learn.models.registry import _resolve

    try:
        _resolve(name)
    except ValueError:
        return False
    return True


@functools.cache
def selectable_metrics() -> tuple[str, ...]:
    """The summary metrics `--select` may name (those of `cone_metrics`)."""
    from vistac_learn.metrics import cone_metrics

    one = np.array([[0.0, -1.0]])
    summary = cone_metrics(one, np.array([0]), [one])
    return tuple(k for k, v in summary.items() if isinstance(v, int | float))


STUDY = {"model": "schoeconv100-v3-fc160", "variant": "edge-index", "finger": "index",
         "epochs": 20, "batch_size": 5, "optimizer": "adam", "lr": 1e-4, "weight_decay": 1e-5,
         "schedule": "constant", "rotations": "fixed", "n_rotations": 20, "rotation_step": 18.0,
         "mirror": False, "jitter": 0.0, "appearance": 0.0, "select": "error_median_pct",
         "tta": False}
PROTOCOLS = {"default": {}, "study": STUDY}


def protocol_cfg(protocol: str, data: str, out: str, **changes) -> TrainCfg:
    """A `TrainCfg` of a protocol's defaults, with `changes` on top."""
    if protocol not in PROTOCOLS:
        raise UserError(f"protocol: must be one of {', '.join(PROTOCOLS)}, got {protocol!r}")
    base = {f.name: f.default for f in dataclasses.fields(TrainCfg)
            if f.default is not dataclasses.MISSING}
    return TrainCfg(**(base | PROTOCOLS[protocol] | {"data": data, "out": out} | changes))
