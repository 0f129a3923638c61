"""vistac_learn.data.variants: rotation, box rotation, crops, automatic Canny."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from learn_fixtures import make_dataset

from vistac.dataset import open_tables
from vistac.errors import UserError
from vistac_learn.data import variants as V
from vistac_learn.data.samples import SampleSet, SampleSpec
from vistac_learn.data.views import make_view


@pytest.fixture(scope="module")
def ds_dir(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("var") / "ds", n=4, repeats=2, size=96)


def test_rotate_box_matches_rotated_pixels():
    """The rotated box is the bounding box of the rotated filled box (1 px, interpolation)."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        img = np.zeros((101, 101), np.uint8)
        x, y = rng.integers(20, 50, size=2)
        w, h = rng.integers(5, 30, size=2)
        img[y:y + h, x:x + w] = 255
        ang = rng.uniform(0, 360)
        m = V.rotation_matrix(ang, 101, 101)
        rot = cv2.warpAffine(img, m, (101, 101), flags=cv2.INTER_NEAREST)
        vs, us = np.nonzero(rot)
        bx, by, bw, bh = V.rotate_box(np.array([x, y, w, h]), m)
        assert abs(us.min() - bx) <= 1.0 and abs(vs.min() - by) <= 1.0
        assert abs((us.max() + 1) - (bx + bw)) <= 1.0 and abs((vs.max() + 1) - (by + bh)) <= 1.0


def test_crop_against_slow_reference():
    """At angle 0 and without resizing, the crop equals a per-pixel reference."""
    rng = np.random.default_rng(1)
    img = rng.integers(0, 255, size=(40, 40, 3), dtype=np.uint8)
    boxes = {"index": np.array([5.0, 6.0, 10.0, 8.0]), "thumb": np.array([20.0, 15.0, 6.0, 12.0])}
    cfg = V.VariantCfg("color-crop", size=25, margin=2 / 40)
    out = V.render_variant(img, boxes, 0.0, cfg, table_rgb=(0.5, 0.5, 0.5))
    # reference: grown boxes [3, 17) x [4, 16) and [18, 28) x [13, 29); union [3, 28) x [4, 29)
    ref = np.full((25, 25, 3), 128, np.uint8)
    for v in range(4, 29):
        for u in range(3, 28):
            inside = (3 <= u < 17 and 4 <= v < 16) or (18 <= u < 28 and 13 <= v < 29)
            if inside:
                ref[v - 4, u - 3] = img[v, u]
    np.testing.assert_array_equal(out.transpose(1, 2, 0), ref)


def test_otsu_against_brute_force():
    rng = np.random.default_rng(2)
    vals = np.concatenate([rng.normal(10, 2, 500), rng.normal(60, 5, 200)])
    t = V.otsu_threshold(vals, bins=64)
    hist, edges = np.histogram(vals, bins=64)
    centres = 0.5 * (edges[1:] + edges[:-1])
    best, best_t = -1, None
    for k in range(1, 64):  # slow: between-class variance of every split
        w0, w1 = hist[:k].sum(), hist[k:].sum()
        m0 = (hist[:k] * centres[:k]).sum() / w0
        m1 = (hist[k:] * centres[k:]).sum() / w1
        var = w0 * w1 * (m0 - m1) ** 2
        if var > best:
            best, best_t = var, edges[k]
    np.testing.assert_array_equal(vals < t, vals < best_t)  # the same split of the values
    gap = (vals[vals < 35].max(), vals[vals > 35].min())
    assert gap[0] < t < gap[1]
    assert t == pytest.approx(np.mean(gap), abs=(gap[1] - gap[0]) / 4)


def test_auto_canny_finds_faint_object_and_nothing_on_flat():
    img = np.full((80, 80, 3), 207, np.uint8)
    assert V.auto_canny(img).max() == 0
    cv2.circle(img, (40, 40), 20, (190, 190, 190), -1)  # 17 grey levels below the table
    edges = V.auto_canny(img)
    vs, us = np.nonzero(edges)
    assert len(us) > 60
    r = np.hypot(us - 40, vs - 40)
    assert np.all(np.abs(r - 20) < 3)


@pytest.mark.parametrize("name", V.VARIANTS)
def test_every_variant_shape_and_background(ds_dir, name):
    t = open_tables(ds_dir)
    cfg = V.VariantCfg(name, size=48)
    img = V.read_rgb(t.image_path(0))
    boxes = {f: t.box(0, f) for f in ("index", "thumb")}
    out = V.render_variant(img, boxes, 45.0, cfg, t.table_rgb)
    assert out.shape == (cfg.channels, 48, 48) and out.dtype == np.uint8
    corner = out[:, 0, 0]
    expected = 207 if cfg.mode == "color" else 0
    assert (corner == expected).all()


def test_finger_stays_inside_rotated_box(ds_dir):
    t = open_tables(ds_dir)
    img = V.read_rgb(t.image_path(1))
    h, w = img.shape[:2]
    for ang in (18.0, 90.0, 234.0):
        m = V.rotation_matrix(ang, w, h)
        rot = cv2.warpAffine(img, m, (w, h), flags=cv2.INTER_NEAREST, borderValue=(207,) * 3)
        green = (rot[..., 1] > 180) & (rot[..., 0] < 60)
        vs, us = np.nonzero(green)
        bx, by, bw, bh = V.rotate_box(t.box(1, "index"), m)
        assert us.min() >= bx - 1 and us.max() <= bx + bw and vs.min() >= by - 1
        assert vs.max() <= by + bh


def test_box_variant_without_boxes_locates_them(ds_dir, tmp_path):
    import shutil

    import pandas as pd

    d = tmp_path / "nobox"
    shutil.copytree(ds_dir, d)
    c = pd.read_parquet(d / "configs.parquet")
    c.drop(columns=[k for k in c.columns if k.startswith("bbox_")]).to_parquet(
        d / "configs.parquet")
    t = open_tables(d)
    base = SampleSet(t, t.rows(None), SampleSpec(make_view("color-base"), 24, ("index",)))
    assert base.batch(np.arange(4))["image"].shape == (4, 3, 24, 24)
    # the boxes a view needs and the dataset lacks are located in the images
    # (vistac_learn.data.located_boxes), not refused
    located = SampleSet(t, t.rows(None), SampleSpec(make_view("edge-index"), 24, ("index",)))
    assert located.boxes is not None and located.batch(np.arange(4))["found"].all()
    with pytest.raises(UserError, match="name: must be one of"):
        V.VariantCfg("edge-pinky")
