"""Training the fingertip locator's segmenter (`vistac_learn.data.segmenter.TinyUNet`).

The data: images with exact per-pixel labels (0 table, 1 object, 2 index, 3 thumb) from
datasets written with masks (`segmentation_samples`): each clean render as it is and perturbed
toward a photograph (`vistac_learn.data.perturb`, the labels moved with the perturbation's
homography), and the renders of ``photo``-preset datasets. The training (`train_segmenter`):
random crops with flips and quarter turns, AdamW with a one-cycle schedule for a fixed number
of steps from a fixed seed, a cross entropy that weighs pixels next to a label boundary more
(`edge_weighted_loss`); `class_iou` scores a model on held-out images.

`benchmarks/train_segmenter.py` makes the datasets, calls these and writes the weights the
package ships.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch

from vistac.config import Config, param
from vistac.dataset import FINGERS, DatasetTables, open_tables
from vistac_learn.data.perturb import AXES, Scene, perturb_axes, random_axes, segment
from vistac_learn.data.segmenter import CLASSES, DEFAULT_WIDTHS, TinyUNet, segment_image
from vistac_learn.data.variants import read_rgb


@dataclass(frozen=True)
class SegmenterTrainCfg(Config):
    """How the segmenter is trained (the shipped weights: these defaults)."""

    steps: int = param(10_000, ge=1, le=10_000_000, help="optimiser steps")
    batch: int = param(8, ge=1, le=4096, help="crops per step")
    crop: int = param(128, ge=8, le=4096, help="side of a training crop, pixels")
    lr: float = param(4e-3, gt=0, le=10, help="peak learning rate (one-cycle)")
    weight_decay: float = param(1e-4, ge=0, le=1, help="AdamW's weight decay")
    warmup: float = param(0.1, gt=0, lt=1, help="share of the steps rising to the peak lr")
    widths: tuple[int, ...] = param(DEFAULT_WIDTHS, ge=1, le=1024, help="channels per level")
    finger_weight: float = param(1.0, gt=0, le=100, help="loss weight of the finger classes "
                                 "(above 1 widens the predicted fingers: their tips move)")
    edge_weight: float = param(3.0, gt=0, le=100, help="loss weight of pixels next to a label "
                               "boundary")
    seed: int = param(0, ge=0, lt=2**32, help="seed of the weights and of the crops")


def labels_of(t: DatasetTables, row: int, rgb: np.ndarray) -> np.ndarray:
    """A render's labels: its mask when written, else `segment` of its flat colours."""
    path = t.mask_path(row)
    if path.is_file():
        return cv2.imread(str(path), cv2.IMREAD_UNCHANGED).astype(np.uint8)
    return segment(rgb, {f: t.finger_rgb(f) for f in FINGERS}, t.table_rgb)


def segmentation_samples(clean: Path, photos: list[Path], split: str, copies: int, seed: int
                         ) -> tuple[np.ndarray, np.ndarray]:
    """(N, H, W, 3) images and (N, H, W) labels of one split of every dataset.

    Each clean render comes with `copies` perturbed versions (the first with every axis, the
    others with a random set, drawn from ``[seed, row, k]``); photo renders come as they are.
    """
    imgs, labs = [], []
    t = open_tables(clean)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    for row in t.rows(split):
        rgb = read_rgb(t.image_path(int(row)))
        lab = labels_of(t, int(row), rgb)
        imgs.append(rgb)
        labs.append(lab)
        scene = Scene(lab, colours)
        for k in range(copies):
            rng = np.random.default_rng([seed, int(row), k])
            axes = tuple(AXES) if k == 0 else random_axes(rng)
            p = perturb_axes(axes, rgb, scene, rng)
            h, w = lab.shape
            imgs.append(p.rgb)
            labs.append(cv2.warpPerspective(lab, p.homography, (w, h), flags=cv2.INTER_NEAREST,
                                            borderMode=cv2.BORDER_REPLICATE))
    for photo in photos:
        t = open_tables(photo)
        for row in t.rows(split):
            rgb = read_rgb(t.image_path(int(row)))
            imgs.append(rgb)
            labs.append(labels_of(t, int(row), rgb))
    return np.stack(imgs), np.stack(labs)


def crop_batch(imgs: np.ndarray, labs: np.ndarray, size: int, crop: int,
               rng: np.random.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """Random crops, flips and quarter turns of random samples: (B, 3, C, C) in [0, 1] and
    (B, C, C) labels."""
    idx = rng.integers(len(imgs), size=size)
    h, w = labs.shape[1:]
    xs, ys = [], []
    for i in idx:
        y0, x0 = int(rng.integers(0, h - crop + 1)), int(rng.integers(0, w - crop + 1))
        x, y = imgs[i, y0:y0 + crop, x0:x0 + crop], labs[i, y0:y0 + crop, x0:x0 + crop]
        k = int(rng.integers(4))
        x, y = np.rot90(x, k), np.rot90(y, k)
        if rng.random() < 0.5:
            x, y = x[:, ::-1], y[:, ::-1]
        xs.append(np.ascontiguousarray(x))
        ys.append(np.ascontiguousarray(y))
    x = torch.from_numpy(np.stack(xs)).permute(0, 3, 1, 2).float() / 255.0
    return x, torch.from_numpy(np.stack(ys)).long()


def edge_weighted_loss(logits: torch.Tensor, y: torch.Tensor, class_weight: torch.Tensor,
                       edge_weight: float) -> torch.Tensor:
    """Cross entropy, each pixel weighted by its class's weight and by `edge_weight` where a
    label boundary passes within one pixel (a 3 x 3 window of more than one label): the
    overlays' outlines, where the fingertip is read, count more than their insides."""
    ce = torch.nn.functional.cross_entropy(logits, y, weight=class_weight, reduction="none")
    yf = y[:, None].float()
    hi = torch.nn.functional.max_pool2d(yf, 3, 1, 1)
    lo = -torch.nn.functional.max_pool2d(-yf, 3, 1, 1)
    w = 1.0 + (edge_weight - 1.0) * (hi != lo)[:, 0].float()
    return (ce * w).sum() / (class_weight[y] * w).sum()


def train_segmenter(imgs: np.ndarray, labs: np.ndarray,
                    cfg: SegmenterTrainCfg = SegmenterTrainCfg(),
                    on_step: Callable[[int, float], None] | None = None) -> TinyUNet:
    """A segmenter trained on labelled images, in evaluation mode.

    The weights and the crops are functions of ``cfg.seed`` alone: torch's global random state
    is seeded inside a scope and left as it was.

    Args:
        imgs: (N, H, W, 3) uint8 RGB images, each at least ``cfg.crop`` on a side.
        labs: (N, H, W) labels (0 table, 1 object, 2 index, 3 thumb).
        cfg: The training settings.
        on_step: Called as ``on_step(step, loss)`` after every step (to report progress).
    """
    rng = np.random.default_rng(cfg.seed)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(cfg.seed)
        model = TinyUNet(tuple(cfg.widths))
        opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
        sched = torch.optim.lr_scheduler.OneCycleLR(opt, cfg.lr, total_steps=cfg.steps,
                                                    pct_start=cfg.warmup)
        weight = torch.tensor([1.0, 1.0, cfg.finger_weight, cfg.finger_weight])
        for step in range(cfg.steps):
            model.train()
            x, y = crop_batch(imgs, labs, cfg.batch, cfg.crop, rng)
            loss = edge_weighted_loss(model(x), y, weight, cfg.edge_weight)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            if on_step is not None:
                on_step(step, loss.item())
    return model.eval()


def class_iou(model: TinyUNet, imgs: np.ndarray, labs: np.ndarray) -> list[float]:
    """Per-class intersection over union of `model`'s labels on whole images."""
    inter, union = np.zeros(CLASSES), np.zeros(CLASSES)
    for x, y in zip(imgs, labs, strict=True):
        p = segment_image(x, model)
        for c in range(CLASSES):
            inter[c] += np.sum((p == c) & (y == c))
            union[c] += np.sum((p == c) | (y == c))
    return [float(v) for v in inter / np.maximum(union, 1)]
