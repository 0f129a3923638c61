"""vistac_learn.data.samples, loading and views: samples rendered per item, batches from a
`DataLoader`, targets, augmentation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from learn_fixtures import make_dataset

from vistac.dataset import open_tables
from vistac.errors import UserError
from vistac_learn.data.fingertip_table import fingertip_table
from vistac_learn.data.loading import EpochBatches, loader
from vistac_learn.data.samples import (
    AugmentCfg,
    RotationCfg,
    SampleSet,
    SampleSpec,
    collate,
    fingers_of,
)
from vistac_learn.data.views import SIDE_FEATURES, Aug, make_view, mirror_labels, tip_crop

SPEC_FIELDS = {f.name for f in dataclasses.fields(SampleSpec)}


@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    root = make_dataset(tmp_path_factory.mktemp("data") / "ds", n=8, repeats=3, size=128)
    t = open_tables(root)
    return t, fingertip_table(t, cache_dir=root.parent / "cache")


def _set(ds, view="tip", **kw):
    """The training rows' samples; `kw`: fields of their `SampleSpec`, or of the `SampleSet`."""
    t, tips = ds
    spec = dict(view=make_view(view), size=32, fingers=("index", "thumb"))
    spec |= {k: kw.pop(k) for k in [k for k in kw if k in SPEC_FIELDS]}
    return SampleSet(t, t.rows("train"), SampleSpec(**spec), **(dict(tips=tips) | kw))


def test_targets_and_items(ds):
    t, _ = ds
    rows = t.rows("train")
    mean = _set(ds, view="edge-crop", rotations=RotationCfg("fixed", 3, 18.0))
    assert len(mean) == len(rows) * 3
    b = mean.batch(np.arange(len(mean)))
    assert b["image"].shape == (len(mean), 1, 32, 32) and b["target"].shape == (len(mean), 4)
    np.testing.assert_allclose(b["target"][:, :2].numpy(),
                               t.mean_label("index")[b["row"].numpy()], rtol=1e-6)
    press = _set(ds, target="press", seed=1, fingers=("thumb",))
    e0, e1 = press.targets(np.arange(len(press)), 0), press.targets(np.arange(len(press)), 1)
    np.testing.assert_array_equal(e0, press.targets(np.arange(len(press)), 0))
    assert not np.array_equal(e0, e1)
    for tgt, r in zip(e1, press.item_row, strict=True):  # every target is one of the presses
        assert np.isclose(t.cones["thumb"][r], tgt, atol=1e-6).all(axis=1).any()
    every = _set(ds, target="all")
    assert len(every) == len(rows) * 3
    assert fingers_of("both") == ("index", "thumb")
    with pytest.raises(UserError):
        fingers_of("pinky")


def test_tip_view_gives_one_finger_aligned_crop_per_finger(ds):
    s = _set(ds)
    b = s.batch(np.arange(len(s)))
    assert b["image"].shape == (len(s), 2, 3, 32, 32) and b["found"].all()
    img = (b["image"][0, 0].numpy() * 255).astype(np.uint8)
    green = (img[1] > 150) & (img[0] < 100)
    # the finger points up: its pixels fill the lower half of the crop, not the upper
    assert green[20:].mean() > 0.3 and green[:8].mean() < 0.05


def test_augmentation_is_per_sample_deterministic_and_bounded(ds):
    aug = AugmentCfg()
    s = _set(ds, augment=aug, seed=4)
    a = [s.aug(i, 3) for i in range(len(s))]
    assert a == [s.aug(i, 3) for i in range(len(s))]  # replayable (resume)
    assert a != [s.aug(i, 4) for i in range(len(s))]  # drawn anew each epoch
    for x in a:
        assert abs(x.shift[0]) <= aug.shift and abs(x.turn) <= aug.turn
        assert abs(x.scale - 1) <= aug.scale
    flips = [_set(ds, augment=aug, seed=k).aug(0, 0).mirror for k in range(40)]
    assert 5 < sum(flips) < 35


def test_mirror_flips_the_view_and_negates_r_y(ds):
    """A mirrored scene has mirrored forces: r_y changes sign, r_z does not (the simulator
    agrees: tests/sim/test_mirror_physics.py)."""
    t, tips = ds
    s = _set(ds, augment=AugmentCfg(mirror=True, shift=0, turn=0, scale=0), seed=2)
    items = np.arange(len(s))
    b = s.batch(items)
    plain = _set(ds).batch(items)
    for i in items:
        mirrored = s.aug(int(i), 0).mirror
        expect = plain["target"][i].numpy().copy()
        if mirrored:
            expect = mirror_labels(expect.reshape(2, 2)).ravel()
            np.testing.assert_array_equal(b["image"][i].numpy(),
                                          plain["image"][i].numpy()[..., ::-1])
        else:
            np.testing.assert_array_equal(b["image"][i].numpy(), plain["image"][i].numpy())
        np.testing.assert_allclose(b["target"][i].numpy(), expect, rtol=1e-6)


def test_rotating_the_top_view_leaves_labels_and_tip_crops_unchanged(ds):
    """Forces are in the fingertip frame, so a rotated top view keeps its labels; the tip view
    turns every crop to its finger, so the model even sees (nearly) the same pixels."""
    import cv2

    from vistac_learn.data.locator import locate_fingertips
    from vistac_learn.data.variants import read_rgb, rotation_matrix

    t, _ = ds
    rows = t.rows("train")
    study = _set(ds, view="color-crop", rotations=RotationCfg("fixed", 4, 90.0))
    tgt = study.targets(np.arange(len(study)))
    for k in range(4):
        np.testing.assert_array_equal(tgt[k::4], tgt[0::4])
    colours = {f: t.finger_rgb(f) for f in ("index", "thumb")}
    bg = tuple(int(round(255 * c)) for c in t.table_rgb)
    for row in rows[:3]:
        img = read_rgb(t.image_path(row))
        h, w = img.shape[:2]
        base = locate_fingertips(img, colours)
        rot = cv2.warpAffine(img, rotation_matrix(90.0, w, h), (w, h),
                             borderMode=cv2.BORDER_CONSTANT, borderValue=bg)
        turned = locate_fingertips(rot, colours)
        for f in ("index", "thumb"):
            a = tip_crop(img, base[f], 32).astype(float)
            b = tip_crop(rot, turned[f], 32).astype(float)
            assert np.abs(a - b).mean() < 12.0, (row, f)  # interpolation only


def test_identity_augmentation_changes_nothing_and_each_part_changes_the_crop(ds):
    """On a real image (the drawn finger, the object's edge): the default `Aug` is the identity,
    while a shift, a turn and a scale each move the crop and a mirror flips it exactly."""
    from vistac_learn.data.variants import read_rgb

    t, tips = ds
    row = int(t.rows("train")[0])
    img, tip = read_rgb(t.image_path(row)), tips.get(row, "index")
    plain = tip_crop(img, tip, 32)
    assert plain.std() > 10  # a crop with content, not a flat patch
    np.testing.assert_array_equal(plain, tip_crop(img, tip, 32, aug=Aug()))
    for aug in (Aug(shift=(0.5, 0.0)), Aug(shift=(0.0, 0.5)), Aug(turn=20.0), Aug(scale=1.3)):
        moved = tip_crop(img, tip, 32, aug=aug).astype(float)
        assert np.abs(moved - plain).mean() > 2.0, aug
    np.testing.assert_array_equal(tip_crop(img, tip, 32, mirror=True), plain[:, :, ::-1])


def test_side_features_say_where_the_other_finger_is(ds):
    """In the crop frame (finger pointing up) the other fingertip's direction is rotation-free;
    a mirror negates its x component, like the crop it goes with."""
    t, tips = ds
    s = _set(ds)
    plain = s.batch(np.arange(len(s)))["side"].numpy()
    assert plain.shape == (len(s), 2, SIDE_FEATURES)
    np.testing.assert_allclose(np.hypot(plain[..., 0], plain[..., 1]), 1.0, rtol=1e-5)
    np.testing.assert_allclose(np.hypot(plain[..., 3], plain[..., 4]), 1.0, rtol=1e-5)
    # the fingers face each other (the fixture presses opposite edges): the other tip lies
    # ahead of each finger (y > 0 in the crop frame), and the distances agree
    assert (plain[..., 1] > 0).all()
    np.testing.assert_allclose(plain[:, 0, 2] + np.log(tips.frame["index_radius"].to_numpy()[
        s.item_row]), plain[:, 1, 2] + np.log(tips.frame["thumb_radius"].to_numpy()[
            s.item_row]), rtol=1e-5)
    m = _set(ds, augment=AugmentCfg(mirror=True, shift=0, turn=0, scale=0), seed=2)
    side = m.batch(np.arange(len(m)))["side"].numpy()
    for i in range(len(m)):
        expect = plain[i].copy()
        if m.aug(i, 0).mirror:
            expect[:, [0, 3]] *= -1
        np.testing.assert_allclose(side[i], expect, atol=1e-6)


def test_training_subsets_are_nested_and_seeded():
    from vistac_learn.train.build import subset_rows

    rows = np.arange(10, 110)
    small, big = subset_rows(rows, 0.1, 3), subset_rows(rows, 0.33, 3)
    assert len(small) == 10 and len(big) == 33 and set(small) <= set(big)
    assert (np.diff(big) > 0).all() and set(big) <= set(rows)
    assert not np.array_equal(small, subset_rows(rows, 0.1, 4))
    np.testing.assert_array_equal(subset_rows(rows, 1.0, 3), rows)


def test_appearance_augmentation_perturbs_seeded_and_off_changes_nothing(ds):
    plain = _set(ds, augment=AugmentCfg(), seed=2)
    off = _set(ds, augment=AugmentCfg(appearance=0.0), seed=2)
    on = _set(ds, augment=AugmentCfg(appearance=1.0), seed=2)
    items = np.arange(len(on))
    # off: the same draws as before the option existed (no random number spent on it)
    assert [plain.aug(i, 1) for i in items] == [off.aug(i, 1) for i in items]
    assert all(off.aug(i, 1).appearance == -1 for i in items)
    assert all(on.aug(i, 1).appearance >= 0 for i in items)
    a, b = on.batch(items, 1), on.batch(items, 1)
    np.testing.assert_array_equal(a["image"].numpy(), b["image"].numpy())  # replayable
    c = off.batch(items, 1)
    assert not np.array_equal(a["image"].numpy(), c["image"].numpy())
    np.testing.assert_array_equal(a["target"].numpy(), c["target"].numpy())  # labels unchanged
    assert a["found"].all()


def test_train_config_switches_appearance_augmentation_on():
    from vistac_learn.train.config import protocol_cfg

    cfg = protocol_cfg("default", "d", "r", appearance=0.5)
    assert cfg.augment_cfg().appearance == 0.5
    assert protocol_cfg("default", "d", "r").augment_cfg().appearance == 0.5  # the recipe's
    assert protocol_cfg("study", "d", "r").augment_cfg() is None  # the study had none
    with pytest.raises(UserError):
        protocol_cfg("default", "d", "r", appearance=1.5)
    assert cfg.augment_cfg().appearance_axes == 0.5
    assert protocol_cfg("default", "d", "r", appearance=0.5,
                        appearance_axes=1.0).augment_cfg().appearance_axes == 1.0
    with pytest.raises(UserError, match="appearance_axes"):
        protocol_cfg("default", "d", "r", appearance_axes=0.0)


def test_the_axis_probability_decides_how_many_axes_a_perturbed_image_gets(ds, monkeypatch):
    """Every axis at probability 1, mostly one at a small probability (at least one always)."""
    from vistac_learn.data import perturb, samples

    drawn = []
    real = perturb.random_axes

    def spy(rng, p=0.5, flat=True):
        assert flat  # the dataset's renders are flat
        drawn.append(real(rng, p, flat))
        return drawn[-1]

    monkeypatch.setattr(samples, "random_axes", spy)
    items = np.arange(len(_set(ds)))
    _set(ds, augment=AugmentCfg(appearance=1.0, appearance_axes=1.0), seed=2).batch(items, 1)
    assert drawn and all(a == tuple(perturb.AXES) for a in drawn)
    drawn.clear()
    _set(ds, augment=AugmentCfg(appearance=1.0, appearance_axes=0.01), seed=2).batch(items, 1)
    assert drawn and all(len(a) == 1 for a in drawn)


def _equal_batches(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        assert a[k].dtype == b[k].dtype, k
        np.testing.assert_array_equal(a[k].numpy(), b[k].numpy(), err_msg=k)


def test_an_item_depends_on_epoch_and_index_only_not_on_order(ds):
    """Augmentation and press draws come from (seed, epoch, index): a fresh dataset asked in
    another order, or after other epochs, serves the same samples."""
    kw = dict(augment=AugmentCfg(appearance=0.5), target="press", seed=5)
    first = _set(ds, **kw)
    n = len(first)
    forward = [first[3, i] for i in range(n)]
    other = _set(ds, **kw)
    for e in (0, 7):  # other epochs first: nothing of theirs may stay behind
        [other[e, i] for i in range(n)]
    backward = [other[3, i] for i in reversed(range(n))][::-1]
    for a, b in zip(forward, backward, strict=True):
        _equal_batches(collate([a]), collate([b]))
    assert any(not np.array_equal(a["image"], b["image"])
               for a, b in zip(forward, [first[4, i] for i in range(n)], strict=True))
    _equal_batches(collate([first[0]]), collate([first[0, 0]]))  # an index alone: epoch 0
    with pytest.raises(IndexError):
        first[0, n]


def test_loader_batches_equal_the_items_they_hold(ds):
    """A `DataLoader` batch is the collated items of its keys, in the order given, from the
    batch asked for; worker processes change nothing."""
    s = _set(ds, augment=AugmentCfg(appearance=0.5), seed=3)
    order = np.random.default_rng(0).permutation(len(s))
    got = list(loader(s, 2, epoch=2, order=order, start=1))
    sampler = EpochBatches(order, 2, epoch=2, start=1)
    assert len(got) == len(sampler) == sampler.total - 1
    for b, batch in enumerate(got, start=1):
        _equal_batches(batch, collate([s[2, int(i)] for i in order[2 * b:2 * b + 2]]))
        np.testing.assert_array_equal(batch["row"].numpy(),
                                      s.item_row[order[2 * b:2 * b + 2]])
    assert got[0]["image"].dtype == torch.float32 and float(got[0]["image"].max()) <= 1.0
    for a, b in zip(got, loader(s, 2, epoch=2, order=order, start=1, workers=2), strict=True):
        _equal_batches(a, b)


def test_mirror_is_an_explicit_setting_of_the_samples(ds):
    """Test-time mirroring: every sample flipped and its r_y negated; it cannot be mixed with
    drawn augmentation."""
    plain, mirrored = _set(ds), _set(ds, mirror=True)
    a, b = plain.batch(range(len(plain))), mirrored.batch(range(len(plain)))
    np.testing.assert_array_equal(b["image"].numpy(), a["image"].numpy()[..., ::-1])
    expect = a["target"].numpy().copy()
    expect[:, 0::2] *= -1
    np.testing.assert_array_equal(b["target"].numpy(), expect)
    with pytest.raises(ValueError, match="exclude"):
        _set(ds, mirror=True, augment=AugmentCfg())


def test_samples_no_epoch_changes_are_rendered_once(ds, monkeypatch):
    """The study's samples (fixed rotations, no augmentation) come from memory after their
    first rendering, identical to a fresh rendering; augmented or randomly turned samples are
    rendered anew at every epoch."""
    import vistac_learn.data.samples as samples

    fixed = _set(ds, view="edge-index", fingers=("index",),
                 rotations=RotationCfg("fixed", 3, 18.0))
    first = fixed[0, 4]
    calls = []
    monkeypatch.setattr(fixed, "_render", lambda *a: calls.append(a))
    again = fixed[5, 4]
    assert not calls  # epoch 5 read the sample rendered at epoch 0
    fresh = _set(ds, view="edge-index", fingers=("index",),
                 rotations=RotationCfg("fixed", 3, 18.0))[5, 4]
    for k in first:
        np.testing.assert_array_equal(again[k], fresh[k])
    assert not again["image"].flags.writeable
    for kw in ({"rotations": RotationCfg("random", 2, 18.0)}, {"augment": AugmentCfg()}):
        s = _set(ds, view="edge-index", fingers=("index",), **kw)
        s[0, 1]
        assert not s._cache
    monkeypatch.setattr(samples, "RENDER_CACHE_BYTES", 0)  # over the budget: rendered anew
    small = _set(ds, view="edge-index", fingers=("index",))
    small[0, 1]
    assert not small._cache
