"""vistac_learn.data.segmenter: the learned front end of the fingertip locator."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch

from vistac.dataset import FINGERS, open_tables
from vistac.errors import UserError
from vistac_learn.data.fingertip_table import simulator_tips
from vistac_learn.data.fingertips import Fingertip, LocatorCfg, colour_fingertips
from vistac_learn.data.locator import (
    combine,
    flat_render,
    learned_fingertips,
    learned_fit,
    locate_fingertips,
    refined_fingertips,
)
from vistac_learn.data.perturb import (
    FINGER_LABEL,
    PERTURBATIONS,
    Scene,
    map_direction,
    map_points,
    perturb,
    segment,
)
from vistac_learn.data.segmenter import (
    FORMAT,
    TinyUNet,
    load_weights,
    palette_image,
    save_weights,
    segment_image,
)
from vistac_learn.data.variants import read_rgb

TIP_PX, AXIS_DEG = 2.0, 3.0  # the locator's agreed tolerance (test_fingertips.py)
COLOURS = {"index": (0.0, 0.85, 0.0), "thumb": (0.9, 0.0, 0.0)}


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))))


def _capsule_labels() -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """A hand-built label image: an object and two capsule fingers facing each other, with
    each finger's tip centre and axis."""
    lab = np.zeros((120, 120), np.uint8)
    cv2.circle(lab, (60, 60), 18, 1, -1)
    truth = {}
    for f, (back, tip) in {"index": ((5.0, 30.0), (45.0, 50.0)),
                           "thumb": ((115.0, 95.0), (76.0, 70.0))}.items():
        back, tip = np.array(back), np.array(tip)
        cv2.line(lab, tuple(int(v) for v in back), tuple(int(v) for v in tip),
                 2 if f == "index" else 3, 15)
        truth[f] = (tip, (tip - back) / np.linalg.norm(tip - back))
    return lab, truth


def test_the_palette_of_hand_built_labels_is_located_within_tolerance():
    lab, truth = _capsule_labels()
    found = colour_fingertips(palette_image(lab, COLOURS, (0.81, 0.81, 0.81)), COLOURS,
                              LocatorCfg())
    for f in FINGERS:
        assert found[f].ok, found[f].reason
        assert np.hypot(*(found[f].tip - truth[f][0])) < TIP_PX
        assert _angle(found[f].axis, truth[f][1]) < 1.0


def test_weights_round_trip(tmp_path):
    model = TinyUNet((4, 8)).eval()
    save_weights(model, tmp_path / "w.pt", {"note": "test"})
    back = load_weights(tmp_path / "w.pt")
    x = torch.rand(1, 3, 37, 41)
    with torch.inference_mode():
        assert model(x).shape == (1, 4, 37, 41)
        torch.testing.assert_close(model(x), back(x), atol=1e-4, rtol=1e-4)  # BN folded


def test_missing_or_corrupt_weights_are_one_line_errors(tmp_path):
    with pytest.raises(UserError, match="segmenter weights missing"):
        load_weights(tmp_path / "none.pt")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a weights file at all")
    with pytest.raises(UserError, match="unreadable segmenter weights"):
        load_weights(bad)
    other = tmp_path / "other.pt"
    torch.save({"format": "something else"}, other)
    with pytest.raises(UserError, match="not segmenter weights"):
        load_weights(other)
    wrong = tmp_path / "wrong.pt"
    torch.save({"format": FORMAT, "widths": [4, 8], "meta": {},
                "state": TinyUNet((8, 16)).state_dict()}, wrong)
    with pytest.raises(UserError, match="do not fit"):
        load_weights(wrong)


def _tip(t: float, ax: tuple = (1.0, 0.0), ok: bool = True) -> Fingertip:
    if not ok:
        return Fingertip.missing("gone")
    return Fingertip(np.array([t, 0.0]), np.array(ax, float), 7.0)


def test_combine_keeps_the_colour_fit_where_both_agree_and_the_learned_one_elsewhere():
    colour = {"index": _tip(0.0), "thumb": _tip(50.0)}
    learned = {"index": _tip(1.0), "thumb": _tip(10.0)}
    check = combine(colour, learned, LocatorCfg(segmenter="check"))
    assert check["index"].tip[0] == 0.0 and check["thumb"].tip[0] == 10.0
    fallback = combine(colour, learned, LocatorCfg(segmenter="fallback"))
    assert fallback["thumb"].tip[0] == 50.0
    colour["index"] = _tip(0.0, ok=False)
    assert combine(colour, learned, LocatorCfg(segmenter="fallback"))["index"].tip[0] == 1.0
    gone = combine(colour, {**learned, "index": Fingertip.missing("segmenter: none")},
                   LocatorCfg(segmenter="check"))["index"]
    assert not gone.ok and "gone" in gone.reason and "segmenter: none" in gone.reason


def test_refine_keeps_the_refined_fit_where_it_agrees_and_the_learned_one_elsewhere():
    cfg = LocatorCfg(segmenter="refine")
    refined = {"index": _tip(0.5), "thumb": _tip(40.0)}
    learned = {"index": _tip(1.0), "thumb": _tip(10.0)}
    out = combine(None, learned, cfg, refined)
    assert out["index"].tip[0] == 0.5 and out["thumb"].tip[0] == 10.0
    turned = combine(None, learned, cfg, {**refined, "index": _tip(0.5, (0.0, 1.0))})
    assert turned["index"].tip[0] == 1.0  # axes 90 deg apart: the learned fit
    alone = combine(None, {**learned, "index": Fingertip.missing("segmenter: none")}, cfg,
                    refined)
    assert alone["index"].tip[0] == 0.5
    gone = combine(None, {**learned, "index": Fingertip.missing("segmenter: none")}, cfg,
                   {**refined, "index": _tip(0.0, ok=False)})["index"]
    assert not gone.ok and "gone" in gone.reason and "segmenter: none" in gone.reason
    with pytest.raises(ValueError, match="refine"):
        combine(None, learned, cfg)


def test_refined_fit_reads_the_colour_only_inside_the_segmenters_finger():
    """A larger red decoy (a table mark of the thumb's colour) draws the colour fit away from the
    thumb; inside the thumb's learned mask the colour fit finds the thumb, to the sub-pixel."""
    lab, truth = _capsule_labels()
    img = palette_image(lab, COLOURS, (0.81, 0.81, 0.81))
    cfg = LocatorCfg()
    plain = colour_fingertips(img, COLOURS, cfg)
    cv2.line(img, (10, 110), (10, 75), (230, 0, 0), 19)  # the decoy, wider than the thumb
    colour = colour_fingertips(img, COLOURS, cfg)["thumb"]
    assert not colour.ok or np.hypot(*(colour.tip - truth["thumb"][0])) > 20
    masks = {f: lab == FINGER_LABEL[f] for f in FINGERS}
    refined = refined_fingertips(img, COLOURS, cfg, masks)
    for f in FINGERS:
        assert refined[f].ok, refined[f].reason
        np.testing.assert_allclose(refined[f].tip, plain[f].tip, atol=1e-6)  # as without decoy
        assert np.hypot(*(refined[f].tip - truth[f][0])) < TIP_PX
    # an empty learned mask leaves that finger to the colour fit over the whole image
    masks["index"] = np.zeros_like(masks["index"])
    assert refined_fingertips(img, COLOURS, cfg, masks)["index"].ok


def test_the_default_locator_keeps_the_colour_fit_on_clean_renders(small_dataset):
    """On clean renders the refined fit is the colour fit, to the last bit: the segmenter only
    picks the blob."""
    t = open_tables(small_dataset)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    cfg = LocatorCfg()
    assert cfg.segmenter == "refine"
    for row in range(4):
        rgb = read_rgb(t.image_path(row))
        assert flat_render(rgb)  # so the locator skips the segmenter here ...
        learned, masks = learned_fit(rgb, colours, cfg)  # ... which would give the same
        refined = combine(None, learned, cfg, refined_fingertips(rgb, colours, cfg, masks))
        got, colour = locate_fingertips(rgb, colours), colour_fingertips(rgb, colours, cfg)
        for f in FINGERS:
            assert got[f].ok and colour[f].ok and refined[f].ok
            for a in (got[f], refined[f]):
                np.testing.assert_allclose(a.tip, colour[f].tip, atol=1e-9)
                np.testing.assert_allclose(a.axis, colour[f].axis, atol=1e-9)
    noisy = np.clip(rgb + np.random.default_rng(0).integers(-3, 4, rgb.shape), 0, 255)
    assert not flat_render(noisy.astype(np.uint8))  # camera noise: the segmenter runs


def test_segmenter_finds_the_fingers_of_a_clean_render_like_its_colours(small_dataset):
    t = open_tables(small_dataset)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    for row in range(3):
        rgb = read_rgb(t.image_path(row))
        truth, got = segment(rgb, colours, t.table_rgb), segment_image(rgb)
        for code in FINGER_LABEL.values():
            iou = ((got == code) & (truth == code)).sum() / ((got == code) | (truth == code)).sum()
            assert iou > 0.85, (row, code, iou)


def test_segmenter_reads_smaller_images_at_the_scale_it_learned(tmp_path):
    """96 px images (fingers 10 px wide, not the 30-40 px of training) are segmented at the
    net's native size and the labels brought back: the learned fit lands on the colour fit's
    fingers (at 96 px directly, two thumbs were taken 20 px away)."""
    from tests.learn_fixtures import make_dataset

    t = open_tables(make_dataset(tmp_path / "ds", n=12))
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    for row in range(len(t.configs)):
        rgb = read_rgb(t.image_path(row))
        assert rgb.shape == (96, 96, 3)
        colour = colour_fingertips(rgb, colours, LocatorCfg())
        learned = learned_fingertips(rgb, colours, LocatorCfg())
        for f in FINGERS:
            assert learned[f].ok, (row, f, learned[f].reason)
            assert np.hypot(*(learned[f].tip - colour[f].tip)) < TIP_PX, (row, f)


def test_learned_locator_finds_tips_in_images_perturbed_every_way_at_once(small_dataset):
    """Every axis of perturb.py at once (photo tables and objects, restyled overlays, light,
    tilt, noise/blur/JPEG) on the first 8 images: the learned fit alone places 15 of the 16
    fingers within tolerance (the colour fit 11; measured with the shipped weights)."""
    t = open_tables(small_dataset)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    k = PERTURBATIONS.index("all")
    good = 0
    for row in range(8):
        rgb = read_rgb(t.image_path(row))
        truth = simulator_tips(t, row, rgb.shape[0])
        p = perturb("all", rgb, Scene(segment(rgb, colours, t.table_rgb), colours),
                    np.random.default_rng([0, row, k]))
        learned = learned_fingertips(p.rgb, colours, LocatorCfg())
        for f in FINGERS:
            tip, axis = truth[f]
            got = learned[f]
            assert got.ok or got.reason.startswith("segmenter: ")
            good += got.ok and bool(
                np.hypot(*(got.tip - map_points(p.homography, tip[None])[0])) < TIP_PX
                and _angle(got.axis, map_direction(p.homography, tip, axis)) < AXIS_DEG)
    assert good >= 14, f"{good} of 16 within tolerance"


def test_fingers_are_found_in_photo_preset_images(tmp_path):
    """`--preset photo` (textures, light, a tilted perspective camera, drawn overlays, JPEG):
    every finger found and within tolerance of the simulator's tip projected by the camera
    (`simulator_tips` of a perspective view)."""
    from vistac.cli import main

    out = tmp_path / "photo"
    assert main(["generate", "--n", "10", "--preset", "photo", "--seed", "5", "--workers", "1",
                 "--no-progress", "--out", str(out)]) == 0
    t = open_tables(out)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    good = 0
    for row in range(len(t.configs)):
        rgb = read_rgb(t.image_path(row))
        found = locate_fingertips(rgb, colours)
        for f, (tip, axis) in simulator_tips(t, row, rgb.shape[0]).items():
            assert found[f].ok, (row, f, found[f].reason)
            good += bool(np.hypot(*(found[f].tip - tip)) < TIP_PX
                         and _angle(found[f].axis, axis) < AXIS_DEG)
    assert good == 20, f"{good} of 20 within tolerance"  # locator v3: 19 (a thumb 16 px off)
