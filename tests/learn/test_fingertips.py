"""vistac_learn.data.fingertips: tips and axes found in the image agree with the simulator."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vistac.dataset import FINGERS, open_tables
from vistac_learn.data.finger_masks import colour_mask, finger_masks
from vistac_learn.data.fingertip_table import fingertip_table, located_in, simulator_tips
from vistac_learn.data.fingertips import Fingertip, LocatorCfg
from vistac_learn.data.locator import locate_fingertips
from vistac_learn.data.perturb import (
    PERTURBATIONS,
    Scene,
    map_direction,
    map_points,
    perturb,
    segment,
)
from vistac_learn.data.variants import read_rgb, rotation_matrix

TIP_PX, AXIS_DEG = 2.0, 3.0  # agreed tolerance: the crop is 54 px wide, a degree is a label error


def _truth(t, row: int, finger: str) -> tuple[np.ndarray, np.ndarray]:
    """Simulator's tip centre (pixels) and finger axis (image u, v) of a configuration."""
    return simulator_tips(t, row, read_rgb(t.image_path(row)).shape[0])[finger]


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))))


def test_located_tips_and_axes_match_the_simulator(small_dataset):
    t = open_tables(small_dataset)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    tip_err, axis_err = [], []
    for row in range(len(t.configs)):
        found = locate_fingertips(read_rgb(t.image_path(row)), colours)
        for f in FINGERS:
            assert found[f].ok, (row, f, found[f].reason)
            tip, axis = _truth(t, row, f)
            tip_err.append(np.hypot(*(found[f].tip - tip)))
            axis_err.append(_angle(found[f].axis, axis))
    assert max(tip_err) < TIP_PX and max(axis_err) < AXIS_DEG
    assert np.median(tip_err) < 1.2 and np.median(axis_err) < 0.5


def test_located_tips_are_unbiased(small_dataset):
    """The located tip and the simulator's agree on average to a fraction of a pixel: both in
    the same pixel coordinates (`PIXEL_CENTRE`; compared unconverted they were 0.5 px apart on
    each axis)."""
    t = open_tables(small_dataset)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    diff = []
    for row in range(len(t.configs)):
        found = locate_fingertips(read_rgb(t.image_path(row)), colours)
        diff += [found[f].tip - _truth(t, row, f)[0] for f in FINGERS]
    assert np.abs(np.mean(diff, axis=0)).max() < 0.2


@pytest.mark.parametrize("slant", [0.0, 25.0, 40.0])
def test_a_finger_cut_short_by_the_border_keeps_its_axis(slant):
    """A finger whose visible part is little more than its rounded end, cut off by the image
    border at a slant: its axis still follows the finger (the border is not its outline)."""
    size, r = 160, 14.0
    a = np.array([np.cos(np.radians(slant)), np.sin(np.radians(slant))])  # entering from the left
    tip = np.array([2.2 * r, 80.0])
    img = np.full((size, size, 3), 207, np.uint8)
    f = 16
    cv2.circle(img, tuple(int(round(c * f)) for c in tip), int(r * f), (0, 217, 0), -1,
               cv2.LINE_8, 4)
    back = tip - 200 * a
    n = np.array([-a[1], a[0]]) * r
    quad = np.array([tip + n, back + n, back - n, tip - n]) * f
    cv2.fillConvexPoly(img, np.round(quad).astype(np.int32), (0, 217, 0), cv2.LINE_8, 4)
    cv2.circle(img, (120, 80), 18, (60, 60, 140), -1)  # the object ahead
    found = locate_fingertips(img, {"index": (0.0, 0.85, 0.0)})["index"]
    assert found.ok, found.reason
    assert _angle(found.axis, a) < 1.5  # 2.5 and 3.3 deg at 25 and 40 with the border as outline
    assert np.hypot(*(found.tip - tip)) < 1.0


def test_rotating_the_image_rotates_the_located_finger(small_dataset):
    t = open_tables(small_dataset)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    img = read_rgb(t.image_path(0))
    h, w = img.shape[:2]
    base = locate_fingertips(img, colours)
    bg = tuple(int(round(255 * c)) for c in t.table_rgb)
    for angle in (30.0, 90.0, 215.0):
        m = rotation_matrix(angle, w, h)
        rot = cv2.warpAffine(img, m, (w, h), flags=cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_CONSTANT, borderValue=bg)
        found = locate_fingertips(rot, colours)
        for f in FINGERS:
            if not found[f].ok:  # the finger may leave the image; then it must say so
                assert found[f].reason
                continue
            assert np.hypot(*(found[f].tip - (m[:, :2] @ base[f].tip + m[:, 2]))) < TIP_PX
            assert _angle(found[f].axis, m[:, :2] @ base[f].axis) < AXIS_DEG


def test_a_missing_finger_is_reported_not_guessed():
    img = np.full((96, 96, 3), 207, np.uint8)
    cv2.circle(img, (48, 48), 20, (60, 60, 140), -1)
    found = locate_fingertips(img, {"index": (0.0, 0.85, 0.0), "thumb": (0.9, 0.0, 0.0)})
    for f in FINGERS:
        assert not found[f].ok and "px of its colour" in found[f].reason
        assert np.isnan(found[f].tip).all()


def test_fingertip_table_is_cached_and_small(small_dataset, tmp_path):
    t = open_tables(small_dataset)
    a = fingertip_table(t, cache_dir=tmp_path)
    files = list(tmp_path.glob("fingertips-*.parquet"))
    assert len(files) == 1 and files[0].stat().st_size < 200 * len(t.configs) + 4096
    b = fingertip_table(t, cache_dir=tmp_path)  # read back, not recomputed
    for f in FINGERS:
        for row in range(len(t.configs)):
            x, y = a.get(row, f), b.get(row, f)
            assert isinstance(y, Fingertip) and y.ok
            np.testing.assert_allclose(x.tip, y.tip)
    other = fingertip_table(t, LocatorCfg(hue_tol_deg=20.0), cache_dir=tmp_path)
    assert other.frame.shape == a.frame.shape and len(list(tmp_path.glob("*.parquet"))) == 2


@pytest.mark.parametrize("preset", ["lab", "harsh"])
def test_fingers_are_found_under_image_effects(preset, tmp_path):
    """Shadows, textured tables, lighting and camera tilt do not hide the drawn fingers."""
    from vistac.cli import main

    out = tmp_path / preset
    assert main(["generate", "--n", "12", "--preset", preset, "--seed", "3", "--workers", "1",
                 "--no-progress", "--out", str(out)]) == 0
    t = open_tables(out)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    for row in range(len(t.configs)):
        found = locate_fingertips(read_rgb(t.image_path(row)), colours)
        assert all(found[f].ok for f in FINGERS), row


@pytest.mark.parametrize("name", ["table", "object", "overlay", "light", "tilt", "camera"])
def test_fingers_are_found_in_perturbed_images(small_dataset, name):
    """Photographic tables and objects, restyled overlays, light, tilt, noise/blur/JPEG: every
    finger of the first images still found within the agreed tolerance of the truth (moved by
    the perturbation's homography)."""
    t = open_tables(small_dataset)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    k = PERTURBATIONS.index(name)
    for row in range(8):
        rgb = read_rgb(t.image_path(row))
        scene = Scene(segment(rgb, colours, t.table_rgb), colours)
        p = perturb(name, rgb, scene, np.random.default_rng([0, row, k]))
        found = locate_fingertips(p.rgb, colours)
        for f in FINGERS:
            assert found[f].ok, (row, f, found[f].reason)
            tip, axis = _truth(t, row, f)
            assert np.hypot(*(found[f].tip - map_points(p.homography, tip[None])[0])) < TIP_PX
            assert _angle(found[f].axis, map_direction(p.homography, tip, axis)) < AXIS_DEG


def test_a_background_of_the_fingers_colour_is_reported():
    img = np.zeros((96, 96, 3), np.uint8)
    img[:] = (200, 30, 30)  # a red table
    cv2.line(img, (0, 20), (50, 50), (0, 255, 0), 12)
    found = locate_fingertips(img, {"index": (0.0, 0.85, 0.0), "thumb": (0.9, 0.0, 0.0)})
    assert found["index"].ok
    assert not found["thumb"].ok and "% of the image" in found["thumb"].reason


def test_the_cache_key_follows_the_locator_version(small_dataset, tmp_path, monkeypatch):
    import vistac_learn.data.fingertip_table as tip_table
    import vistac_learn.data.fingertips as fingertips

    t = open_tables(small_dataset)
    before = tip_table.cache_path(t, LocatorCfg(), tmp_path)
    monkeypatch.setattr(fingertips, "LOCATOR_VERSION", fingertips.LOCATOR_VERSION + 1)
    assert tip_table.cache_path(t, LocatorCfg(), tmp_path) != before


def test_located_in_serves_given_images(small_dataset):
    t = open_tables(small_dataset)
    rows = np.array([1, 3])
    imgs = [read_rgb(t.image_path(r)) for r in rows]
    table = located_in(t, rows, imgs)
    assert len(table.frame) == len(t.configs)
    assert table.get(1, "index").ok and table.get(3, "thumb").ok
    assert not table.get(0, "index").ok and table.failures(np.array([0, 1, 2]), "thumb") == 2


def test_the_loose_colour_mask_covers_the_finger(small_dataset):
    t = open_tables(small_dataset)
    colours = {f: t.finger_rgb(f) for f in FINGERS}
    img = read_rgb(t.image_path(0))
    hsv = cv2.cvtColor(img, cv2.COLOR_RGB2HSV_FULL)
    masks = finger_masks(img, colours, LocatorCfg())
    for f in FINGERS:
        loose = colour_mask(hsv, colours[f], LocatorCfg())
        assert masks[f].any() and loose[masks[f]].mean() > 0.97  # (nearly) all of the finger
        assert loose.mean() < 0.2


def test_simulator_fingertips_follow_a_moved_overlay_and_a_tilted_camera(tmp_path):
    """`--preset harsh` draws the fingers off the real ones (overlay error) under a tilted,
    rolled, zoomed camera (camera jitter): the simulator's fingertips as drawn
    (`simulator_fingertips`, through `vistac.projection`) are where the locator finds them,
    radius included (before, the overlay and the tilt were ignored: tips 7 px off, median)."""
    from vistac.cli import main
    from vistac_learn.data.fingertip_table import simulator_fingertips

    out = tmp_path / "harsh"
    assert main(["generate", "--n", "6", "--preset", "harsh", "--seed", "7", "--workers", "1",
                 "--no-progress", "--out", str(out)]) == 0
    t = open_tables(out)
    assert (t.configs["overlay_index_dx"] != 0).all() and (t.configs["camera_tilt_deg"] > 0).all()
    # the rendered fingers keep their colours: the colour fit alone finds them (and fast)
    found = fingertip_table(t, LocatorCfg(segmenter="off"), cache_dir=tmp_path / "cache")
    truth = simulator_fingertips(t, 227)
    gaps = []
    for row in range(len(t.configs)):
        for f in FINGERS:
            got, want = found.get(row, f), truth.get(row, f)
            assert got.ok, (row, f, got.reason)
            gaps.append(np.hypot(*(got.tip - want.tip)))
            assert gaps[-1] < TIP_PX and _angle(got.axis, want.axis) < AXIS_DEG, (row, f)
            assert got.radius == pytest.approx(want.radius, abs=1.0), (row, f)
    assert np.median(gaps) < 0.5
