"""The segmenter's training (`vistac_learn.train.segmenter`, which writes the shipped weights
through `benchmarks/train_segmenter.py`): it learns, it is a function of its seed, its loss is
the weighted cross entropy it says."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from vistac_learn.train.segmenter import (
    SegmenterTrainCfg,
    class_iou,
    edge_weighted_loss,
    train_segmenter,
)

pytestmark = pytest.mark.usefixtures("one_torch_thread")  # tests/conftest.py


COLOURS = np.array([[200, 200, 200], [60, 60, 140], [230, 40, 40], [40, 200, 60]], np.uint8)


def _images(n: int, seed: int, side: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Images of four flat-coloured regions (a class each) with noise, and their labels."""
    rng = np.random.default_rng(seed)
    labs = np.zeros((n, side, side), np.uint8)
    for lab in labs:
        for c in (1, 2, 3):
            y, x = rng.integers(0, side * 3 // 4, 2)
            lab[y:y + side // 5, x:x + side // 5] = c
    noise = rng.normal(0, 8, (*labs.shape, 3))
    imgs = np.clip(COLOURS[labs] + noise, 0, 255).astype(np.uint8)
    return imgs, labs


def test_the_segmenter_learns_regions_from_their_colours():
    imgs, labs = _images(6, 0)
    cfg = SegmenterTrainCfg(steps=20, batch=4, crop=24, lr=3e-2, widths=(8,), seed=3)
    losses = []
    model = train_segmenter(imgs, labs, cfg, lambda step, loss: losses.append(loss))
    assert len(losses) == cfg.steps and np.mean(losses[-5:]) < 0.5 * np.mean(losses[:5])
    test_imgs, test_labs = _images(2, 1, side=227)  # the segmenter's native scale
    assert min(class_iou(model, test_imgs, test_labs)) > 0.8


def test_training_is_a_function_of_the_seed_alone():
    imgs, labs = _images(4, 0)
    cfg = SegmenterTrainCfg(steps=3, batch=2, crop=32, widths=(4, 8), seed=1)  # two levels
    torch.manual_seed(9)
    state = torch.get_rng_state()
    a = train_segmenter(imgs, labs, cfg).state_dict()
    assert torch.equal(torch.get_rng_state(), state)  # the caller's draws are untouched
    torch.rand(10)
    b = train_segmenter(imgs, labs, cfg).state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_the_loss_is_the_weighted_cross_entropy_with_boundaries_weighed_more():
    torch.manual_seed(0)
    logits = torch.randn(2, 4, 6, 6)
    y = torch.zeros(2, 6, 6, dtype=torch.long)
    y[:, 2:4, 2:4] = 2
    w = torch.tensor([1.0, 1.0, 2.0, 2.0])
    plain = torch.nn.functional.cross_entropy(logits, y, weight=w)
    torch.testing.assert_close(edge_weighted_loss(logits, y, w, 1.0), plain)
    ce = torch.nn.functional.cross_entropy(logits, y, weight=w, reduction="none")
    edge = torch.zeros_like(ce, dtype=torch.bool)
    edge[:, 1:5, 1:5] = True  # the 2 x 2 square and the ring round it: within one pixel of
    # a label boundary
    pix_w = w[y] * (1 + 2 * edge.float())
    expected = (ce * (1 + 2 * edge.float())).sum() / pix_w.sum()
    torch.testing.assert_close(edge_weighted_loss(logits, y, w, 3.0), expected)
