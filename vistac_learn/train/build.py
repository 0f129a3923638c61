"""What a training run's settings (`TrainCfg`) build: its device, view, model and samples, and
the checks of its paths and data made before any work.

The model is made in a seed scope (`build_model`): its weights are a function of the run's
seed, and torch's global random state is left as it was.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from vistac.dataset import DatasetTables, read_manifest
from vistac.dataset.files import check_out_dir
from vistac.errors import UserError
from vistac_learn.data.fingertip_table import FingertipTable
from vistac_learn.data.located_boxes import BoxTable, box_table, missing_boxes
from vistac_learn.data.samples import SampleSet, SampleSpec, fingers_of
from vistac_learn.data.tip_coverage import TipCoverage, tip_coverage
from vistac_learn.data.views import PINCH_VIEW, View, make_view
from vistac_learn.models import create_model
from vistac_learn.models.pinch import EMBED, PinchModel
from vistac_learn.models.tipnet import PerFinger
from vistac_learn.train.config import TrainCfg

SIDE_EMBED = 32  # per-finger features of a crop that side features join (`PerFinger`)
LABEL_DIMS = 2  # outputs per finger: the unit label (r_y, r_z)
DEFAULT_INPUT_SIZE = 227  # input side of a model that does not declare one (the study's)
SUBSET_STREAM = 7  # the seed stream of `train_fraction` subsets: ``[seed, SUBSET_STREAM]``


def resolve_device(name: str) -> torch.device:
    """``auto`` -> CUDA when available, else CPU."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise UserError("--device cuda: no CUDA device available")
    return torch.device(name)


def build_view(cfg: TrainCfg) -> View:
    """The run's view."""
    return make_view(cfg.variant, cfg.margin)


def build_model(cfg: TrainCfg) -> torch.nn.Module:
    """The run's model, freshly initialised from the seed (per finger for per-finger views).

    The weights are drawn in a seed scope: torch's global random state is seeded with
    ``cfg.seed`` for the initialisation only and then restored, so the same config gives the
    same weights whatever ran before, and building a model changes no other draw.
    """
    with torch.random.fork_rng(devices=[]):  # the weights are made on the CPU
        torch.manual_seed(cfg.seed)
        return _new_model(cfg)


def _new_model(cfg: TrainCfg) -> torch.nn.Module:
    view = build_view(cfg)
    n_fingers = len(fingers_of(cfg.finger))
    try:
        if view.name == PINCH_VIEW:
            return PinchModel(create_model(cfg.model, view.channels, EMBED),
                              fingers_of(cfg.finger), EMBED)
        if view.per_finger:
            embed = SIDE_EMBED if view.side_features else LABEL_DIMS
            return PerFinger(create_model(cfg.model, view.channels, embed), n_fingers,
                             view.side_features, embed)
        return create_model(cfg.model, in_channels=view.channels,
                            out_features=LABEL_DIMS * n_fingers)
    except (KeyError, ValueError) as exc:
        raise UserError(f"--model {cfg.model!r}: {exc}") from exc


def input_size(cfg: TrainCfg, model: torch.nn.Module) -> int:
    """Side of the rendered input: --size, else the model's own."""
    return int(cfg.size or getattr(model, "input_size", DEFAULT_INPUT_SIZE))


def subset_rows(rows: np.ndarray, fraction: float, seed: int) -> np.ndarray:
    """The first ceil(fraction * n) rows of a permutation drawn from `seed` (nested in the
    fraction: a smaller fraction is a subset of a larger one), in ascending order."""
    if fraction >= 1:
        return rows
    keep = max(1, int(np.ceil(fraction * len(rows))))
    rng = np.random.default_rng([seed, SUBSET_STREAM])
    return np.sort(rows[rng.permutation(len(rows))[:keep]])


def build_boxes(cfg: TrainCfg, tables: DatasetTables, progress: bool = False
                ) -> BoxTable | None:
    """The finger boxes of a run whose view needs boxes the dataset lacks (``bbox_*`` NaN, as
    `vistac ingest` leaves them): located in the images (`vistac_learn.data.located_boxes`,
    cached in ``cfg.cache_dir``); None where the dataset's own serve."""
    if not missing_boxes(tables, build_view(cfg).needs_boxes):
        return None
    return box_table(tables, cache_dir=cfg.cache_dir, progress=progress)


def build_samples(cfg: TrainCfg, tables: DatasetTables, split: str, size: int,
                  tips: FingertipTable | None, train: bool = False,
                  mirror: bool = False, boxes: BoxTable | None = None) -> SampleSet:
    """The samples of one split: training ones with the run's augmentation (and only its
    `train_fraction`), others whole and without augmentation; `mirror` (not with `train`):
    every sample mirrored (test-time augmentation); `boxes`: located finger boxes
    (`build_boxes`)."""
    view = build_view(cfg)
    rows = tables.rows(split)
    if train:
        rows = subset_rows(rows, cfg.train_fraction, cfg.seed)
    spec = SampleSpec(view, size, fingers_of(cfg.finger), cfg.target if train else "mean",
                      cfg.seed, cfg.rotation_cfg(), cfg.augment_cfg() if train else None,
                      mirror)
    return SampleSet(tables, rows, spec, tips, boxes=boxes)


def run_coverage(cfg: TrainCfg, tables: DatasetTables, tips: FingertipTable | None,
                 boxes: BoxTable | None = None) -> list[TipCoverage]:
    """The fingertips (and located finger boxes, `build_boxes`) not found in the run's
    training rows and validation split (nothing for views that locate none), each split
    checked against ``cfg.max_missing_pct``.

    Raises:
        UserError: a split above the threshold (how many, an example image).
    """
    rows = {cfg.train_split: subset_rows(tables.rows(cfg.train_split), cfg.train_fraction,
                                         cfg.seed),
            cfg.val_split: tables.rows(cfg.val_split)}
    out = []
    if tips is not None:
        fingers = fingers_of(cfg.finger)
        out += [tip_coverage(tables, tips, r, fingers, split) for split, r in rows.items()]
    if boxes is not None:
        fingers = build_view(cfg).needs_boxes
        out += [tip_coverage(tables, boxes, r, fingers, split) for split, r in rows.items()]
    for c in out:
        c.check(cfg.max_missing_pct)
    return out


def check_paths(cfg: TrainCfg) -> None:
    """Before any work: the dataset is complete, --out and --cache-dir can be written, --init
    is a finished run.

    Raises:
        UserError: naming the option.
    """
    try:
        read_manifest(Path(cfg.data))
    except UserError as exc:
        raise UserError(f"--data {exc}") from None
    check_out_dir(cfg.out)
    if cfg.cache_dir is not None:
        check_out_dir(cfg.cache_dir, "--cache-dir")
    if cfg.init is not None and not (Path(cfg.init) / "checkpoints" / "best.pt").is_file():
        raise UserError(f"--init {cfg.init}: not a finished run (no checkpoints/best.pt)")


def check_data(cfg: TrainCfg, progress: bool = False) -> list[str]:
    """Before a tuning or an experiment: the run's dataset opens and its fingertips (located
    into the cache, for views that need them) and the finger boxes it lacks (located likewise,
    for views that need them) are found often enough; one line per split.

    Raises:
        UserError: a damaged dataset, a split above ``cfg.max_missing_pct``.
    """
    from vistac.dataset import open_tables
    from vistac_learn.data.fingertip_table import fingertip_table

    view = build_view(cfg)
    if not view.needs_tips and not view.needs_boxes:
        return []
    tables = open_tables(cfg.data)
    tips = fingertip_table(tables, cache_dir=cfg.cache_dir, progress=progress) \
        if view.needs_tips else None
    boxes = build_boxes(cfg, tables, progress)
    return [f"{cfg.data}: {c.line()}" for c in run_coverage(cfg, tables, tips, boxes)]
